#include "pneuma/engine/scenario.h"

#include <fmt/format.h>

#include <cctype>

#include "pneuma/core/error.h"
#include "pneuma/core/paths.h"
#include "pneuma/engine/config.h"
#include "pneuma/render/camera.h"

namespace pneuma::engine {
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

MeshSpec read_mesh_spec(const Node& n) {
  MeshSpec m;
  if (int(n.has("phantom")) + int(n.has("file")) + int(n.has("labels")) > 1) {
    n.fail_at(n.has("labels") ? "labels" : "file", "give one of phantom, file or labels");
  }
  if (n.has("labels")) {
    m.phantom.reset();
    m.labels_file = n.directory("labels") / n.string("labels");
    if (!path_exists(m.labels_file)) n.fail_at("labels", "no such file: " + m.labels_file.string());
    for (const Node& item : n.sequence("values")) {
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
      if (!(m.metres_per_unit > 0.0)) n.fail_at("unit", "expected a length unit such as 'mm' or '0.5 mm', got '" + text + "'");
    }
    m.export_original = n.has("export") && n.choice("export", {"original", "remeshed"}) == "original";
    m.repair = n.boolean("repair", true);
  } else {
    if (n.has("phantom")) m.phantom = n.choice("phantom", {"left", "right"}) == "left" ? mesh::Lung::left : mesh::Lung::right;
    m.edge_m = 4e-3;
  }
  if (n.has("edge")) m.edge_m = n.positive_quantity("edge", kind::length);
  if (m.export_original && m.edge_m == 0.0) n.fail_at("export", "exporting the original mesh needs an 'edge' to remesh to");
  m.share = default_share(m.phantom);
  if (auto share = n.optional_quantity("share", kind::fraction)) {
    if (!(*share > 0.0 && *share <= 1.0)) n.fail_at("share", "expected a share in (0, 1], such as '0.55' or '55 %'");
    m.share = *share;
  }
  if (n.has("reference_volume")) m.reference_volume_m3 = n.quantity("reference_volume", kind::volume);
  n.finish();
  return m;
}

FieldSpec read_field(const Node& n, const std::filesystem::path& config_dir) {
  FieldSpec f;
  if (n.has("tissue")) f.tissue = n.string("tissue");
  const bool is_path = f.tissue.find('/') != std::string::npos || f.tissue.ends_with(".yaml");
  f.tissue_file = is_path ? n.directory("tissue") / f.tissue : config_dir / "tissue" / (f.tissue + ".yaml");
  if (!path_exists(f.tissue_file)) {
    n.fail_at("tissue", "no tissue '" + f.tissue + "' (looked for " + f.tissue_file.string() +
                            "; shipped presets: " + join_names(file_stems(config_dir / "tissue", ".yaml")) + ")");
  }
  FieldOptions& o = f.options;
  if (n.has("solver")) o.solver = parse_solver_kind(n.choice("solver", solver_names()));
  if (n.has("tolerance")) o.tolerance = n.positive_quantity("tolerance", kind::number);
  o.clique_hops = static_cast<int>(n.integer("clique", o.clique_hops, 1, kMaxCliqueHops));
  if (!solver_takes_clique(o.solver, o.clique_hops)) {
    n.fail_at("clique", fmt::format("the {} solver{} takes clique 1 only; add 'solver: shot' (or sweep, direct) "
                                    "for a clique of {} hops",
                                    solver_name(o.solver), n.has("solver") ? "" : " (the default)", o.clique_hops));
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

// A sink's section: `name: true|false` or `name: {options}`. Returns the options node when on.
std::optional<Node> sink_section(const Node& outputs, const std::string& key, bool default_on, bool& on) {
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

OutputsSpec read_outputs(const std::optional<Node>& n) {
  OutputsSpec o;
  if (!n) return o;
  bool on = false;
  if (auto s = sink_section(*n, "physiology_csv", true, on)) s->finish();
  o.physiology_csv = on;
  if (auto s = sink_section(*n, "gltf", true, on)) s->finish();
  o.gltf = on;
  if (auto s = sink_section(*n, "motion_csv", true, on)) s->finish();
  o.motion_csv = on;
  if (auto s = sink_section(*n, "report", true, on)) s->finish();
  o.report = on;
  if (auto s = sink_section(*n, "hdf5", true, on)) {
    if (s->has("positions")) {
      const std::string value = s->string("positions");
      if (value == "true" || value == "false")
        s->fail_at("positions", "expected float32 or float64 (the stored type; series.h5 now always stores every "
                                "frame's positions, the plain geometry ParaView and meshio read), got '" + value + "'");
      o.hdf5_positions = s->choice("positions", {"float32", "float64"}) == "float64" ? PositionPrecision::float64
                                                                                     : PositionPrecision::float32;
    }
    s->finish();
  }
  o.hdf5 = on;
  auto sequence = sink_section(*n, "mesh_sequence", false, on);
  if (on) {
    MeshSequenceSpec spec;
    if (sequence) {
      if (sequence->has("format")) spec.format = sequence->choice("format", {"ply", "obj", "stl"});
      spec.ascii = sequence->boolean("ascii", false);
      spec.every = static_cast<std::size_t>(sequence->integer("every", 1, 1, 1000000));
    }
    o.mesh_sequence = spec;
  }
  if (sequence) sequence->finish();
  auto png = sink_section(*n, "png", false, on);
  if (on) {
    render::PngSinkOptions spec;
    if (png) {
      render::RenderOptions& r = spec.render;
      r.width = static_cast<int>(png->integer("width", r.width, 16, 8192));
      r.height = static_cast<int>(png->integer("height", r.height, 16, 8192));
      if (png->has("camera")) {
        const std::string camera = png->choice("camera", {"anterior", "posterior", "left", "right", "oblique"});
        render::parse_camera_preset(camera, r.camera);
      }
      spec.every = static_cast<std::size_t>(png->integer("every", 1, 1, 1000000));
      r.overlay_magnitude = png->boolean("overlay", false);
      if (png->has("gl")) render::parse_gl_backend(png->choice("gl", {"auto", "egl", "osmesa"}), r.gl);
    }
    o.png = spec;
  }
  if (png) png->finish();
  n->finish();
  return o;
}

}  // namespace

Scenario load_scenario(const std::filesystem::path& file, const std::filesystem::path& config_dir) {
  return read_scenario(Node::load_file(file), file, config_dir);
}

Scenario read_scenario(const Node& root, const std::filesystem::path& file, const std::filesystem::path& config_dir) {
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
    s.field.tissue_file = config_dir / "tissue" / (s.field.tissue + ".yaml");
  }
  s.physiology = read_physiology(root.map("physiology"), s.duration_s, config_dir);
  s.outputs = read_outputs(root.optional_map("outputs"));
  root.finish();
  return s;
}

physiology::SimulationResult simulate_physiology(const Scenario& s, std::optional<double> output_rate_hz) {
  physiology::SimulationOptions options = s.physiology.options;
  if (output_rate_hz) options.output_rate_hz = *output_rate_hz;
  try {
    return physiology::simulate(s.physiology.protocol, options);
  } catch (const ValueError& e) {
    throw InputError(s.file.string() + ": physiology: " + e.what());
  }
}

}  // namespace pneuma::engine
