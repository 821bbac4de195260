#include "pneuma/scenario/scenario.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>

#include "pneuma/core/error.h"
#include "pneuma/core/parameters.h"
#include "pneuma/core/paths.h"
#include "pneuma/core/units.h"
#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/scenario/config.h"
#include "pneuma/scenario/tissue_config.h"

namespace pneuma::scenario {
namespace {

namespace kind = units::kind;
using scenario::Node;

// The longest run pneuma starts (docs/scenarios.md, limits): every sample of the drive and every
// frame is held in memory, and a run past these would take hours before its first output.
constexpr double kMaxDurationS = 86400.0;      // one day of breathing
constexpr double kMaxFrames = 1e6;             // duration x frames.rate
constexpr double kMaxPhysiologySamples = 1e7;  // duration x physiology.output_rate

// Refuses a run with too many frames or samples, at the key that makes it so (the rate where the scenario
// gives one, else the duration), with the numbers.
void check_run_size(const Node& root, const Scenario& s) {
  const auto too_many = [&](const std::optional<Node>& section, const std::string& key, double rate_hz, double most,
                            const char* what) {
    const double count = s.duration_s * rate_hz;
    if (!(count > most)) return;
    const std::string message =
        fmt::format("{:.4g} {} ({:.6g} s at {:.6g} Hz); expected at most {:.0f}: lower {} or the duration", count, what,
                    s.duration_s, rate_hz, most, key);
    if (section && section->has(key.substr(key.find('.') + 1)))
      section->fail_at(key.substr(key.find('.') + 1), message);
    root.fail_at("duration", message);
  };
  too_many(root.optional_map("frames"), "frames.rate", s.frame_rate_hz, kMaxFrames, "frames");
  too_many(root.optional_map("physiology"), "physiology.output_rate", s.physiology.options.output_rate_hz,
           kMaxPhysiologySamples, "physiology samples");
}

static_assert(parameters::kCliqueHops.max == field::kMaxCliqueHops, "the table's clique sizes are the field's");

// The value of a table parameter at its key (`name`), refused there in the table's words.
double parameter(const Node& n, const parameters::Parameter& p) {
  const double value = n.quantity(p.name, *p.kind);
  if (const auto why = p.check(value, n.string(p.name))) n.fail_at(p.name, *why);
  return value;
}

// Share of the total lung volume change by side: the right lung has three lobes and about
// 55 % of the volume (Yamaguchi et al., Radiology 1997; textbook 55:45).
double default_share(const std::optional<mesh::Lung>& lung) {
  if (lung == mesh::Lung::right) return 0.55;
  if (lung == mesh::Lung::left) return 0.45;
  return 1.0;
}

// `unit`: a unit name ("mm") or a length ("0.5 mm"): the length of one file unit.
double read_unit(const scenario::Node& n) {
  const std::string text = n.string("unit");
  const bool bare = !text.empty() && std::isalpha(static_cast<unsigned char>(text.front()));
  double metres = 0.0;
  try {
    metres = units::parse(bare ? "1 " + text : text, kind::length);
  } catch (const units::UnitError&) {
    metres = 0.0;
  }
  if (!(metres > 0.0)) n.fail_at("unit", "expected a length unit such as 'mm' or '0.5 mm', got '" + text + "'");
  if (metres < units::kMinFileUnitM || metres > units::kMaxFileUnitM)
    n.fail_at("unit", "expected a length unit from 1 nm to 1 km, got '" + text + "'");
  return metres;
}

// A label selection: label values (`[3, 4, 5]`) or segment names of the label map
// (`[lung_upper_lobe_left, lung_lower_lobe_left]`, resolved when the scenario is compiled).
struct LabelSelection {
  std::vector<int> values;
  std::vector<std::string> names;
};

LabelSelection read_label_values(const scenario::Node& n, const std::string& key) {
  LabelSelection selection;
  for (const scenario::Node& item : n.sequence(key)) {
    const std::string text = item.as_scalar("expected a label value such as 3 or a segment name");
    const bool number = text.find_first_not_of("0123456789+-") == std::string::npos;
    if (number) {
      selection.values.push_back(static_cast<int>(item.as_integer(1, 1'000'000)));
    } else {
      selection.names.push_back(text);
    }
  }
  if (selection.values.empty() && selection.names.empty())
    n.fail_at(key, "expected a list of label values such as [3, 4, 5] or segment names");
  return selection;
}

// `lungs: {right: ..., left: ...}`: with `labels`, each side's label values (`[3, 4, 5]`, or a
// map with `values`); without, each side's `file`. Either form may give `share` and `compartment`.
std::vector<LungSpec> read_lungs(const scenario::Node& n, bool labels) {
  const scenario::Node lungs = n.map("lungs");
  const std::vector<std::string> sides = lungs.keys();
  for (const std::string& side : sides) {
    if (side != "right" && side != "left") lungs.fail_at(side, "expected the lungs 'right' and 'left'");
  }
  std::vector<LungSpec> specs;
  for (const mesh::Lung side : {mesh::Lung::right, mesh::Lung::left}) {
    const std::string name = lung_name(side);
    if (!lungs.has(name)) lungs.fail("missing key '" + name + "' (two lungs: give both 'right' and 'left')");
    LungSpec spec;
    spec.side = side;
    spec.share = default_share(side);
    if (labels && !lungs.is_map(name)) {
      LabelSelection selection = read_label_values(lungs, name);
      spec.label_values = std::move(selection.values);
      spec.label_names = std::move(selection.names);
      specs.push_back(std::move(spec));
      continue;
    }
    const scenario::Node lung = lungs.map(name);
    if (labels) {
      LabelSelection selection = read_label_values(lung, "values");
      spec.label_values = std::move(selection.values);
      spec.label_names = std::move(selection.names);
    } else {
      if (lung.has("values")) lung.fail_at("values", "label values need a label map: add 'labels: FILE' to mesh");
      spec.file = lung.directory("file") / lung.string("file");
      if (const std::string why = missing_reason(spec.file); !why.empty())
        lung.fail_at("file", why + ": " + spec.file.string());
    }
    if (auto share = lung.optional_quantity("share", kind::fraction)) {
      if (!(*share > 0.0 && *share <= 1.0))
        lung.fail_at("share", "expected a share in (0, 1], such as '0.55' or '55 %'");
      spec.share = *share;
    }
    if (auto compartment = lung.optional_string("compartment")) {
      spec.compartment_name = *compartment;
      if (!lung.has("share")) spec.share = 1.0;  // the whole of its compartment's volume change
    }
    lung.finish();
    specs.push_back(std::move(spec));
  }
  if (specs[0].compartment_name.empty() && specs[1].compartment_name.empty() &&
      specs[0].share + specs[1].share > 1.0 + 1e-12) {
    lungs.fail(fmt::format("the lungs' shares add up to {:g} %, more than the whole breath",
                           (specs[0].share + specs[1].share) * 100.0));
  }
  // A label in both lungs would give two overlapping surfaces.
  if (const auto value = label_in_both_lungs(specs[0], specs[1]))
    lungs.fail_at("left", fmt::format("label {} is in both lungs", *value));
  for (const std::string& name : specs[0].label_names) {
    if (std::find(specs[1].label_names.begin(), specs[1].label_names.end(), name) != specs[1].label_names.end())
      lungs.fail_at("left", fmt::format("segment '{}' is in both lungs", name));
  }
  lungs.finish();
  return specs;
}

// `breath: end_inspiration | end_expiration | <volume above FRC>` (or its older name
// `reference_volume: <volume>`): where the scan lies on the breath.
void read_breath(const scenario::Node& n, MeshSpec& m) {
  if (n.has("breath") && n.has("reference_volume"))
    n.fail_at("reference_volume", "give either 'breath' or its older name 'reference_volume', not both");
  const std::string key = n.has("breath") ? "breath" : "reference_volume";
  if (!n.has(key)) return;
  const char* expected = key == "breath" ? "expected end_inspiration, end_expiration or a volume above FRC with its "
                                           "unit from 0 to 10 L, such as '500 mL'"
                                         : "expected a volume above FRC with its unit from 0 to 10 L, such as '500 mL'";
  if (n.is_map(key)) n.fail_at(key, expected);
  std::string text;
  try {
    text = n.string(key);
  } catch (const InputError&) {
    n.fail_at(key, expected);  // a list
  }
  if (key == "breath" && (text == "end_inspiration" || text == "end_expiration")) {
    m.breath_at_end_inspiration = text == "end_inspiration";
    return;
  }
  double v = 0.0;
  try {
    v = n.quantity(key, kind::volume);
  } catch (const InputError&) {
    n.fail_at(key, expected);
  }
  constexpr double kMostAboveFrc_m3 = 10e-3;  // more than any lung's inspiratory capacity
  if (!(v >= 0.0 && v <= kMostAboveFrc_m3)) n.fail_at(key, expected);
  m.reference_volume_m3 = v;
}

MeshSpec read_mesh_spec(const scenario::Node& n) {
  MeshSpec m;
  if (int(n.has("phantom")) + int(n.has("file")) + int(n.has("labels")) > 1) {
    n.fail_at(n.has("labels") ? "labels" : "file", "give one of phantom, file or labels");
  }
  if (n.has("lungs")) {
    if (n.has("phantom")) n.fail_at("lungs", "give either phantom or lungs ('phantom: both' is both phantoms)");
    if (n.has("file")) n.fail_at("lungs", "give either file or lungs (each lung's file under lungs.<side>.file)");
    if (n.has("values")) n.fail_at("lungs", "give either values or lungs (each lung's values under lungs.<side>)");
  }
  if (n.has("labels")) {
    m.phantom.reset();
    m.labels_file = n.directory("labels") / n.string("labels");
    if (const std::string why = missing_reason(m.labels_file); !why.empty())
      n.fail_at("labels", why + ": " + m.labels_file.string());
    if (n.has("lungs")) {
      m.lungs = read_lungs(n, true);
    } else {
      LabelSelection selection = read_label_values(n, "values");
      m.label_values = std::move(selection.values);
      m.label_names = std::move(selection.names);
    }
    m.edge_m = parameters::kEdge.default_si;
    m.repair = n.boolean("repair", true);
  } else if (n.has("file")) {
    m.phantom.reset();
    m.file = n.directory("file") / n.string("file");
    if (const std::string why = missing_reason(m.file); !why.empty()) n.fail_at("file", why + ": " + m.file.string());
    if (n.has("unit")) {
      m.unit_given = true;
      m.metres_per_unit = read_unit(n);
    }
    m.export_original = n.has("export") && n.choice("export", {"original", "remeshed"}) == "original";
    m.repair = n.boolean("repair", true);
  } else if (n.has("lungs")) {
    m.phantom.reset();
    m.lungs = read_lungs(n, false);
    m.unit_given = n.has("unit");
    if (m.unit_given) m.metres_per_unit = read_unit(n);
    m.repair = n.boolean("repair", true);
  } else {
    const std::string phantom = n.has("phantom") ? n.choice("phantom", {"left", "right", "both"}) : "right";
    m.phantom = phantom == "left" ? mesh::Lung::left : mesh::Lung::right;
    if (phantom == "both") {
      m.phantom.reset();
      for (const mesh::Lung side : {mesh::Lung::right, mesh::Lung::left})
        m.lungs.push_back({side, true, {}, {}, {}, default_share(side), -1, {}});
    }
    m.edge_m = parameters::kEdge.default_si;
  }
  if (n.has("edge")) m.edge_m = parameter(n, parameters::kEdge);
  if (m.export_original && m.edge_m == 0.0)
    n.fail_at("export", "exporting the original mesh needs an 'edge' to remesh to");
  m.share = default_share(m.phantom);
  if (!m.lungs.empty()) {
    if (n.has("share"))
      n.fail_at("share", "two lungs: give each lung's share under lungs.<side>.share (default 55 %, 45 %)");
    if (m.export_original) n.fail_at("export", "two lungs export their remeshed surfaces only");
    m.share = m.lungs[0].share + m.lungs[1].share;
  }
  if (auto share = n.optional_quantity("share", kind::fraction)) {
    if (!(*share > 0.0 && *share <= 1.0)) n.fail_at("share", "expected a share in (0, 1], such as '0.55' or '55 %'");
    m.share = *share;
  }
  read_breath(n, m);
  n.finish();
  return m;
}

FieldSpec read_field(const scenario::Node& n, const std::filesystem::path& config_dir) {
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
  if (n.has("tolerance")) o.tolerance = parameter(n, parameters::kFieldTolerance);
  if (n.has("clique")) o.clique_hops = static_cast<int>(parameter(n, parameters::kCliqueHops));
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
  if (auto interior = n.optional_map("interior")) {
    const scenario::Node& i = *interior;
    if (i.has("edge")) {
      f.interior_edge_m = i.positive_quantity("edge", kind::length);
      if (f.interior_edge_m < 0.5e-3 || f.interior_edge_m > 50e-3) {
        i.fail_at("edge", "expected a tetrahedron size between 0.5 mm and 50 mm, such as '3 mm'");
      }
    }
    if (i.has("mesher")) {
      f.interior_mesher = i.choice("mesher", {"delaunay", "lattice"}) == "lattice" ? mesh::TetMesher::lattice
                                                                                   : mesh::TetMesher::delaunay;
    }
    if (i.has("model")) {
      f.interior.model = i.choice("model", {"elastic", "harmonic"}) == "elastic" ? field::InteriorModel::elastic
                                                                                 : field::InteriorModel::harmonic;
    }
    if (i.has("poisson_ratio")) {
      f.interior.poisson_ratio = i.quantity("poisson_ratio", kind::number);
      if (!(f.interior.poisson_ratio >= 0.0 && f.interior.poisson_ratio <= 0.49)) {
        i.fail_at("poisson_ratio", "expected a Poisson ratio between 0 and 0.49, such as '0.4'");
      }
    }
    if (i.has("unfold")) {
      f.interior.unfold_volume_m3 = i.quantity("unfold", kind::volume);
      if (!(f.interior.unfold_volume_m3 >= 0.0 && f.interior.unfold_volume_m3 <= 5e-3)) {
        i.fail_at("unfold", "expected a volume from 0 L to 5 L above rest, such as '1 L'");
      }
    }
    i.finish();
  }
  n.finish();
  return f;
}

// An output's section: `name: true|false` or `name: {options}`. Returns the options node when on.
std::optional<scenario::Node> sink_section(const scenario::Node& outputs, const std::string& key, bool default_on,
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
std::vector<OutputRequest> read_outputs(const std::optional<Node>& n, std::span<const OutputKey> keys,
                                        const Scenario& run) {
  std::vector<OutputRequest> requests;
  for (const OutputKey& output : keys) {
    bool on = output.on_by_default;
    const std::optional<Node> options = n ? sink_section(*n, output.key, output.on_by_default, on) : std::nullopt;
    if (on || options) {
      std::any settings = output.read(options ? &*options : nullptr, run);
      if (on) requests.push_back({output.key, std::move(settings)});
    }
    if (options) options->finish();
  }
  if (n) n->finish();
  return requests;
}

// A lung that follows a compartment (`lungs.<side>.compartment`) names one of the physiology
// model's compartments (two_compartment: upper, lower).
void resolve_compartments(const scenario::Node& root, Scenario& s) {
  for (LungSpec& lung : s.mesh.lungs) {
    if (lung.compartment_name.empty()) continue;
    std::vector<std::string> names;
    if (!s.physiology.trace && !s.physiology.protocol.settings.empty()) {
      for (const auto& c : s.physiology.protocol.settings.front().mechanics.compartments) names.push_back(c.name);
    }
    const auto found = std::find(names.begin(), names.end(), lung.compartment_name);
    if (names.size() < 2 || found == names.end()) {
      root.map("mesh")
          .map("lungs")
          .map(lung_name(lung.side))
          .fail_at("compartment", names.size() < 2
                                      ? "a lung follows a compartment of a two_compartment physiology model only"
                                      : "expected a compartment of the physiology model (" + join_names(names) +
                                            "), got '" + lung.compartment_name + "'");
    }
    lung.compartment = static_cast<int>(found - names.begin());
  }
}

}  // namespace

const char* lung_name(const std::optional<mesh::Lung>& side) {
  if (!side) return "lung";
  return *side == mesh::Lung::right ? "right" : "left";
}

std::optional<int> label_in_both_lungs(const LungSpec& right, const LungSpec& left) {
  for (const int value : right.label_values) {
    if (std::find(left.label_values.begin(), left.label_values.end(), value) != left.label_values.end()) return value;
  }
  return std::nullopt;
}

std::vector<LungSpec> lung_specs(const MeshSpec& mesh) {
  if (!mesh.lungs.empty()) return mesh.lungs;
  LungSpec one;
  one.side = mesh.phantom;
  one.phantom = mesh.phantom.has_value();
  one.file = mesh.file;
  one.label_values = mesh.label_values;
  one.label_names = mesh.label_names;
  one.share = mesh.share;
  return {one};
}

const OutputRequest* Scenario::output(std::string_view key) const {
  for (const OutputRequest& request : outputs) {
    if (request.key == key) return &request;
  }
  return nullptr;
}

Scenario load_scenario(const std::filesystem::path& file, std::span<const OutputKey> outputs,
                       const std::filesystem::path& config_dir) {
  return read_scenario(scenario::Node::load_file(file), file, outputs, config_dir);
}

Scenario read_scenario(const scenario::Node& root, const std::filesystem::path& file,
                       std::span<const OutputKey> outputs, const std::filesystem::path& config_dir) {
  Scenario s;
  s.file = file;
  s.name = root.optional_string("name").value_or(file.stem().string());
  s.description = root.optional_string("description").value_or("");
  s.duration_s = root.positive_quantity("duration", kind::duration);
  if (s.duration_s > kMaxDurationS) {
    root.fail_at("duration",
                 fmt::format("expected at most {:.0f} s (one day), got {:.6g} s", kMaxDurationS, s.duration_s));
  }
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
  check_run_size(root, s);
  resolve_compartments(root, s);
  s.outputs = read_outputs(root.optional_map("outputs"), outputs, s);
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
