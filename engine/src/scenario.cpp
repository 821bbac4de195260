#include "pneuma/engine/scenario.h"

#include "pneuma/engine/config.h"

namespace pneuma::engine {

Scenario load_scenario(const std::filesystem::path& file, const std::filesystem::path& config_dir) {
  const config::Node root = config::Node::load_file(file);
  Scenario s;
  s.file = file;
  s.name = root.optional_string("name").value_or(file.stem().string());
  s.description = root.optional_string("description").value_or("");
  s.duration_s = root.positive_quantity("duration", units::kind::duration);
  s.physiology = read_physiology(root.map("physiology"), s.duration_s, config_dir);
  root.finish();
  return s;
}

}  // namespace pneuma::engine
