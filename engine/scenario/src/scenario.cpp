#include "pneuma/scenario/scenario.h"

#include <fmt/format.h>

#include <cctype>

#include "pneuma/config/config.h"
#include "pneuma/core/error.h"
#include "pneuma/core/paths.h"
#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/scenario/tissue_config.h"

namespace pneuma::scenario {
namespace {

namespace kind = units::kind;
using config::Node;

// Share of the total lung volume change by side: the right lung has three lobes and about
// 55 % of the volume (Yamaguchi et al., Radiology 1997; textbook 55:45).
double default_share(const std::optional<mesh::Lung>& lung) {
  if (lung == mesh::Lung::right) return 0.55;
  if (lung == mesh::Lung::left) return 0.45;
  return 1.0;
}

MeshSpec read_mesh_spec(const config::Node& n) {
  MeshSpec m;
  if (int(n.has("phantom")) + int(n.has("file")) + int(n.has("labels")) > 1) {
    n.fail_at(n.has("labels") ? "labels" : "file", "give one of phantom, file or labels");
  }
  if (n.has("labels")) {
    m.phantom.reset();
    m.labels_file = n.directory("labels") / n.string("labels");
    if (!path_exists(m.labels_file)) n.fail_at("labels", "no such file: " + m.labels_file.string());
    for (const config::Node& item : n.sequence("values")) {
      m.label_values.push_back(static_cast<int>(item.as_integer(1, 1'000'000)));
    }
    if (m.label_values.empty()) n.fail_at("values", "expected a list of label values such as [3, 4, 5]");
    m.edge_m = 4e-3;
    m.repair = n.boolean("repair", true);
  } else if (n.has("file")) {
    m.phantom.reset();
    m.file = n.directory("file") / n.string("file");
    if (!path_exists(m.file)) n.fail_at("file", "no such file: " + m.file.string());
    if (n.has("unit")) {
      m.unit_given = true;
      // A unit name ("mm") or a length ("0.5 mm"): the length of one file unit.
      const std::string text = n.string("unit");
      const bool bare = !text.empty() && std::isalpha(static_cast<unsigned char>(text.front()));
      try {
        m.metres_per_unit = units::parse(bare ? "1 " + text : text, kind::length);
      } catch (const units::UnitError&) {
        m.metres_per_unit = 0.0;
      }
      if (!(m.metres_per_unit > 0.0))
        n.fail_at("unit", "expected a length unit such as 'mm' or '0.5 mm', got '" + text + "'");
    }
    m.export_original = n.has("export") && n.choice("export", {"original", "remeshed"}) == "original";
    m.repair = n.boolean("repair", true);
  } else {
    if (n.has("phantom"))
      m.phantom = n.choice("phantom", {"left", "right"}) == "left" ? mesh::Lung::left : mesh::Lung::right;
    m.edge_m = 4e-3;
  }
  if (n.has("edge")) m.edge_m = n.positive_quantity("edge", kind::length);
  if (m.export_original && m.edge_m == 0.0)
    n.fail_at("export", "exporting the original mesh needs an 'edge' to remesh to");
  m.share = default_share(m.phantom);
  if (auto share = n.optional_quantity("share", kind::fraction)) {
    if (!(*share > 0.0 && *share <= 1.0)) n.fail_at("share", "expected a share in (0, 1], such as '0.55' or '55 %'");
    m.share = *share;
  }
  if (n.has("reference_volume")) m.reference_volume_m3 = n.quantity("reference_volume", kind::volume);
  n.finish();
  return m;
}

FieldSpec read_field(const config::Node& n, const std::filesystem::path& config_dir) {
  FieldSpec f;
  if (n.has("tissue")) f.tissue_name = n.string("tissue");
  const bool is_path = f.tissue_name.find('/') != std::string::npos || f.tissue_name.ends_with(".yaml");
  f.tissue_file = is_path ? n.directory("tissue") / f.tissue_name : config_dir / "tissue" / (f.tissue_name + ".yaml");
  if (!path_exists(f.tissue_file)) {
    n.fail_at("tissue", "no tissue '" + f.tissue_name + "' (looked for " + f.tissue_file.string() +
                            "; shipped presets: " + join_names(file_stems(config_dir / "tissue", ".yaml")) + ")");
  }
  f.tissue = load_tissue(f.tissue_file);
  field::FieldOptions& o = f.options;
  if (n.has("solver")) o.solver = field::parse_solver_kind(n.choice("solver", field::solver_names()));
  if (n.has("tolerance")) o.tolerance = n.positive_quantity("tolerance", kind::number);
  o.clique_hops = static_cast<int>(n.integer("clique", o.clique_hops, 1, field::kMaxCliqueHops));
  if (!field::solver_takes_clique(o.solver, o.clique_hops)) {
    n.fail_at("clique",
              fmt::format("the {} solver{} takes clique 1 only; add 'solver: shot' (or sweep, direct) "
                          "for a clique of {} hops",
                          field::solver_name(o.solver), n.has("solver") ? "" : " (the default)", o.clique_hops));
  }
  if (n.has("cache")) {
    const std::string cache = n.string("cache");
    if (cache == "off") {
      f.cache = FieldCache::off;
    } else if (cache != "auto") {
      f.cache = FieldCache::file;
      f.cache_file = n.directory("cache") / cache;
    }
  }
  n.finish();
  return f;
}

// An output's section: `name: true|false` or `name: {options}`. Returns the options node when on.
std::optional<config::Node> sink_section(const config::Node& outputs, const std::string& key, bool default_on,
                                         bool& on) {
  on = default_on;
  if (!outputs.has(key)) return std::nullopt;
  if (!outputs.is_map(key)) {
    on = outputs.boolean(key, default_on);
    return std::nullopt;
  }
  if (auto options = outputs.optional_map(key)) {
    on = options->boolean("enabled", true);
    return options;
  }
  on = outputs.boolean(key, default_on);
  return std::nullopt;
}

// The outputs on, each with the settings its key read. A section's options are read (and
// checked) whenever they are given, also for an output they turn off.
std::vector<OutputRequest> read_outputs(const std::optional<Node>& n, std::span<const OutputKey> keys) {
  std::vector<OutputRequest> requests;
  for (const OutputKey& output : keys) {
    bool on = output.on_by_default;
    const std::optional<Node> options = n ? sink_section(*n, output.key, output.on_by_default, on) : std::nullopt;
    if (on || options) {
      std::any settings = output.read(options ? &*options : nullptr);
      if (on) requests.push_back({output.key, std::move(settings)});
    }
    if (options) options->finish();
  }
  if (n) n->finish();
  return requests;
}

}  // namespace

const OutputRequest* Scenario::output(std::string_view key) const {
  for (const OutputRequest& request : outputs) {
    if (request.key == key) return &request;
  }
  return nullptr;
}

Scenario load_scenario(const std::filesystem::path& file, std::span<const OutputKey> outputs,
                       const std::filesystem::path& config_dir) {
  return read_scenario(config::Node::load_file(file), file, outputs, config_dir);
}

Scenario read_scenario(const config::Node& root, const std::filesystem::path& file, std::span<const OutputKey> outputs,
                       const std::filesystem::path& config_dir) {
  Scenario s;
  s.file = file;
  s.name = root.optional_string("name").value_or(file.stem().string());
  s.description = root.optional_string("description").value_or("");
  s.duration_s = root.positive_quantity("duration", kind::duration);
  if (auto frames = root.optional_map("frames")) {
    if (frames->has("rate")) s.frame_rate_hz = frames->positive_quantity("rate", kind::rate);
    frames->finish();
  }
  if (auto mesh = root.optional_map("mesh")) {
    s.mesh = read_mesh_spec(*mesh);
  } else {
    // The default phantom, as `mesh: {phantom: right}`: its default resolution and share.
    s.mesh.edge_m = mesh::kDefaultPhantom.edge_length_m;
    s.mesh.share = default_share(s.mesh.phantom);
  }
  if (auto field = root.optional_map("field")) {
    s.field = read_field(*field, config_dir);
  } else {
    s.field.tissue_file = config_dir / "tissue" / (s.field.tissue_name + ".yaml");
    s.field.tissue = load_tissue(s.field.tissue_file);
  }
  s.physiology = read_physiology(root.map("physiology"), s.duration_s, config_dir);
  s.outputs = read_outputs(root.optional_map("outputs"), outputs);
  root.finish();
  return s;
}

physiology::SimulationResult simulate_physiology(const Scenario& s, std::optional<double> output_rate_hz) {
  physiology::SimulationOptions options = s.physiology.options;
  if (output_rate_hz) options.output_rate_hz = *output_rate_hz;
  try {
    if (s.physiology.trace)
      return physiology::trace_result(*s.physiology.trace, options.duration_s, options.output_rate_hz);
    return physiology::simulate(s.physiology.protocol, options);
  } catch (const ValueError& e) {
    throw InputError(s.file.string() + ": physiology: " + e.what());
  }
}

}  // namespace pneuma::scenario
