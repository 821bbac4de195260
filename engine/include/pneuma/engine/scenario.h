#pragma once
// A breathing scenario: what to simulate and for how long (scenarios/*.yaml).
#include <filesystem>
#include <string>

#include "pneuma/engine/physiology_config.h"

namespace pneuma::engine {

struct Scenario {
  std::filesystem::path file;
  std::string name;
  std::string description;
  double duration_s = 0.0;
  PhysiologyConfig physiology;
};

// Reads and checks a scenario file; every problem is one line (file:line:col: key: what).
Scenario load_scenario(const std::filesystem::path& file,
                       const std::filesystem::path& config_dir = default_config_dir());

}  // namespace pneuma::engine
