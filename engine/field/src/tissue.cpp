#include "pneuma/engine/tissue.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <sstream>

#include "pneuma/core/error.h"
#include "pneuma/core/units.h"

namespace pneuma::engine {
namespace {

using config::Node;
namespace kind = units::kind;

const std::vector<std::string> kAxes{"+x", "-x", "+y", "-y", "+z", "-z"};

Eigen::Vector3d axis_vector(const std::string& name) {
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  v[name[1] - 'x'] = name[0] == '-' ? -1.0 : 1.0;
  return v;
}

// Whitespace-separated tokens of a text file, with the line of each (for messages).
struct Token {
  std::string text;
  int line;
};
std::vector<Token> read_tokens(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw IoError(file.string() + ": cannot open file");
  std::vector<Token> tokens;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    if (auto hash = line.find('#'); hash != std::string::npos) line.resize(hash);
    std::istringstream words(line);
    for (std::string w; words >> w;) tokens.push_back({w, number});
  }
  return tokens;
}

GradientStiffness read_gradient(const Node& s) {
  GradientStiffness g;
  g.profile = s.choice("profile", {"linear", "exponential"}) == "linear" ? GradientStiffness::Profile::linear
                                                                       : GradientStiffness::Profile::exponential;
  g.nondependent_pa = s.positive_quantity("nondependent", kind::shear_modulus);
  g.dependent_pa = s.positive_quantity("dependent", kind::shear_modulus);
  for (const Node& band : s.sequence("bands")) {
    StiffnessBand b;
    b.from = band.quantity("from", kind::fraction);
    b.to = band.quantity("to", kind::fraction);
    if (!(b.from >= 0.0 && b.from <= 1.0)) band.fail_at("from", "expected a position from 0 to 1");
    if (!(b.to > b.from && b.to <= 1.0)) band.fail_at("to", "expected a position after 'from' and at most 1");
    b.shear_modulus_pa = band.positive_quantity("shear_modulus", kind::shear_modulus);
    band.finish();
    g.bands.push_back(b);
  }
  return g;
}

PerVertexStiffness read_per_vertex(const Node& s) {
  PerVertexStiffness p;
  const std::string unit = s.string("unit");
  double factor = 0.0;
  try {
    factor = units::parse("1 " + unit, kind::shear_modulus);
  } catch (const units::UnitError&) {
    s.fail_at("unit", "expected a unit of shear modulus such as 'kPa', got '" + unit + "'");
  }
  const std::filesystem::path file = s.directory("values") / s.string("values");
  p.source = file.string();
  for (const Token& t : read_tokens(file)) {
    std::size_t used = 0;
    double v = 0.0;
    try {
      v = std::stod(t.text, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != t.text.size() || !(v > 0.0) || !std::isfinite(v))
      throw InputError(file.string() + ":" + std::to_string(t.line) + ": expected a positive number, got '" + t.text + "'");
    p.shear_modulus_pa.push_back(v * factor);
  }
  return p;
}

RegionStiffness read_regions(const Node& s) {
  RegionStiffness r;
  const Node moduli = s.map("moduli");
  for (const std::string& label : moduli.keys()) r.shear_modulus_pa[label] = moduli.positive_quantity(label, kind::shear_modulus);
  if (r.shear_modulus_pa.empty()) s.fail_at("moduli", "expected at least one label with its shear modulus");
  if (auto g = s.optional_map("gravity")) {
    r.gravity_nondependent = g->quantity("nondependent", kind::fraction);
    r.gravity_dependent = g->quantity("dependent", kind::fraction);
    if (!(r.gravity_nondependent > 0.0)) g->fail_at("nondependent", "expected a positive factor");
    if (!(r.gravity_dependent > 0.0)) g->fail_at("dependent", "expected a positive factor");
    g->finish();
  }
  if (!s.has("labels")) {
    // The anatomical regions found on the surface: every region needs a modulus, no other label.
    r.anatomical = true;
    r.source = moduli.file();
    for (const auto& [label, mu] : r.shear_modulus_pa) {
      if (!mesh::region_from_name(label))
        moduli.fail_at(label, "expected a region: apex, costal, diaphragmatic or mediastinal (or give 'labels')");
    }
    for (mesh::Region region : mesh::kRegions) {
      if (!r.shear_modulus_pa.count(std::string(mesh::region_name(region))))
        s.fail_at("moduli", "expected a modulus for every region: apex, costal, diaphragmatic, mediastinal");
    }
    return r;
  }
  const std::filesystem::path file = s.directory("labels") / s.string("labels");
  r.source = file.string();
  for (const Token& t : read_tokens(file)) {
    if (!r.shear_modulus_pa.count(t.text))
      throw InputError(file.string() + ":" + std::to_string(t.line) + ": label '" + t.text + "' has no modulus in " +
                       moduli.file() + " (" + moduli.path() + ")");
    r.labels.push_back(t.text);
  }
  return r;
}

// The surface's anatomical regions in the tissue's body axes (mesh::find_regions).
mesh::SurfaceRegions regions_of(const Tissue& tissue, const mesh::TriangleMesh& mesh) {
  mesh::RegionOptions options;
  options.frame = body_frame(tissue);
  return mesh::find_regions(mesh, options);
}

}  // namespace

Tissue read_tissue(const Node& root) {
  Tissue t;
  t.name = root.has("name") ? root.string("name") : std::filesystem::path(root.file()).stem().string();
  const std::string posture = root.choice("posture", {"upright", "supine", "prone"});
  t.posture = posture == "upright" ? Posture::upright : posture == "supine" ? Posture::supine : Posture::prone;
  if (auto c = root.optional_map("coordinates")) {
    if (c->has("up")) t.up = axis_vector(c->choice("up", kAxes));
    if (c->has("anterior")) t.anterior = axis_vector(c->choice("anterior", kAxes));
    if (std::abs(t.up.dot(t.anterior)) > 0.5) c->fail_at("anterior", "expected an axis at right angles to 'up'");
    c->finish();
  }
  const Node s = root.map("stiffness");
  const std::string model = s.choice("model", {"gradient", "per_vertex", "regions"});
  if (model == "gradient") {
    for (const char* key : {"profile", "nondependent", "dependent", "bands"}) s.has(key);
    t.stiffness = read_gradient(s);
  } else if (model == "per_vertex") {
    for (const char* key : {"values", "unit"}) s.has(key);
    t.stiffness = read_per_vertex(s);
  } else {
    for (const char* key : {"labels", "moduli", "gravity"}) s.has(key);
    t.stiffness = read_regions(s);
  }
  s.finish();
  if (auto l = root.optional_map("load")) {
    std::array<double, mesh::kRegionCount> load{};
    double total = 0.0;
    for (mesh::Region region : mesh::kRegions) {
      const std::string key(mesh::region_name(region));
      const double v = l->quantity(key, kind::fraction);
      if (!(v >= 0.0)) l->fail_at(key, "expected a load of 0 or more");
      load[static_cast<std::size_t>(region)] = v;
      total += v;
    }
    if (!(total > 0.0)) l->fail("expected a positive load in at least one region");
    if (auto g = l->optional_map("gravity")) {
      t.load_nondependent = g->quantity("nondependent", kind::fraction);
      t.load_dependent = g->quantity("dependent", kind::fraction);
      if (!(t.load_nondependent > 0.0)) g->fail_at("nondependent", "expected a positive factor");
      if (!(t.load_dependent > 0.0)) g->fail_at("dependent", "expected a positive factor");
      g->finish();
    }
    if (auto d = l->optional_map("dome")) {
      t.dome_load.radius_m = d->positive_quantity("radius", kind::length);
      t.dome_load.falloff_m = d->positive_quantity("falloff", kind::length);
      t.dome_load.rim = d->quantity("rim", kind::fraction);
      if (!(t.dome_load.rim >= 0.0 && t.dome_load.rim <= 1.0)) d->fail_at("rim", "expected a factor from 0 to 1");
      d->finish();
    }
    l->finish();
    t.regional_load = load;
  }
  if (auto d = root.optional_map("displacement")) {
    if (d->has("direction")) t.direction = parse_direction_kind(d->choice("direction", {"vertex_normal", "smoothed_normal", "anatomical"}));
    if (d->has("smoothing")) t.direction_smoothing_m = d->positive_quantity("smoothing", kind::length);
    if (d->has("magnitude_smoothing")) {
      t.magnitude_smoothing_m = d->quantity("magnitude_smoothing", kind::length);
      if (!(t.magnitude_smoothing_m >= 0.0)) d->fail_at("magnitude_smoothing", "expected a length >= 0 such as '3 mm'");
    }
    d->finish();
  }
  root.finish();
  return t;
}

Tissue load_tissue(const std::filesystem::path& path) { return read_tissue(Node::load_file(path)); }

std::filesystem::path tissue_file(const std::string& name_or_path, const std::filesystem::path& config_dir) {
  if (name_or_path.find('/') != std::string::npos || name_or_path.ends_with(".yaml")) return name_or_path;
  return config_dir / "tissue" / (name_or_path + ".yaml");
}

Eigen::Vector3d dependent_direction(const Tissue& tissue) {
  switch (tissue.posture) {
    case Posture::upright: return -tissue.up;
    case Posture::supine: return -tissue.anterior;
    case Posture::prone: return tissue.anterior;
  }
  return -tissue.up;
}

std::vector<double> dependent_position(const Tissue& tissue, const mesh::TriangleMesh& mesh) {
  const Eigen::Vector3d d = dependent_direction(tissue);
  std::vector<double> depth(mesh.vertices.size());
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (std::size_t i = 0; i < depth.size(); ++i) {
    depth[i] = d.dot(mesh.vertices[i]);
    lo = std::min(lo, depth[i]);
    hi = std::max(hi, depth[i]);
  }
  for (double& v : depth) v = hi > lo ? (v - lo) / (hi - lo) : 0.0;
  return depth;
}

std::vector<double> shear_modulus_per_vertex(const Tissue& tissue, const mesh::TriangleMesh& mesh,
                                             const mesh::SurfaceRegions* known_regions) {
  const std::size_t n = mesh.vertices.size();
  auto check_count = [n](std::size_t got, const std::string& source, const char* what) {
    if (got != n)
      throw InputError(source + ": expected " + std::to_string(n) + " " + what + " (one per mesh vertex), got " +
                       std::to_string(got));
  };
  if (const auto* g = std::get_if<GradientStiffness>(&tissue.stiffness)) {
    const std::vector<double> position = dependent_position(tissue, mesh);
    std::vector<double> mu(n);
    for (std::size_t i = 0; i < n; ++i) {
      const double x = position[i];
      mu[i] = g->profile == GradientStiffness::Profile::linear
                  ? g->nondependent_pa + x * (g->dependent_pa - g->nondependent_pa)
                  : g->nondependent_pa * std::pow(g->dependent_pa / g->nondependent_pa, x);
      for (const StiffnessBand& b : g->bands) {
        if (x >= b.from && x <= b.to) mu[i] = b.shear_modulus_pa;
      }
    }
    return mu;
  }
  if (const auto* p = std::get_if<PerVertexStiffness>(&tissue.stiffness)) {
    check_count(p->shear_modulus_pa.size(), p->source, "values");
    return p->shear_modulus_pa;
  }
  const auto& r = std::get<RegionStiffness>(tissue.stiffness);
  std::vector<double> mu(n);
  if (r.anatomical) {
    std::optional<mesh::SurfaceRegions> found;  // only where none were given: no copy of given ones
    if (known_regions) mesh::require_regions_of(*known_regions, mesh, body_frame(tissue), "shear_modulus_per_vertex");
    const mesh::SurfaceRegions& regions = known_regions ? *known_regions : found.emplace(regions_of(tissue, mesh));
    std::array<double, mesh::kRegionCount> log_mu{};
    for (mesh::Region region : mesh::kRegions)
      log_mu[static_cast<std::size_t>(region)] = std::log(r.shear_modulus_pa.at(std::string(mesh::region_name(region))));
    for (std::size_t i = 0; i < n; ++i) {
      double sum = 0.0;
      for (std::size_t k = 0; k < mesh::kRegionCount; ++k) sum += regions.weight[i][k] * log_mu[k];
      mu[i] = std::exp(sum);
    }
  } else {
    check_count(r.labels.size(), r.source, "labels");
    for (std::size_t i = 0; i < n; ++i) mu[i] = r.shear_modulus_pa.at(r.labels[i]);
  }
  if (r.gravity_nondependent != 1.0 || r.gravity_dependent != 1.0) {
    const std::vector<double> position = dependent_position(tissue, mesh);
    for (std::size_t i = 0; i < n; ++i)
      mu[i] *= r.gravity_nondependent + position[i] * (r.gravity_dependent - r.gravity_nondependent);
  }
  return mu;
}

mesh::BodyFrame body_frame(const Tissue& tissue) {
  mesh::BodyFrame frame;
  frame.up = tissue.up;
  frame.anterior = tissue.anterior;
  return frame;
}

FieldOptions with_tissue(FieldOptions options, const Tissue& tissue, const mesh::TriangleMesh& mesh) {
  options.direction = tissue.direction;
  options.direction_smoothing = tissue.direction_smoothing_m;
  options.magnitude_smoothing = tissue.magnitude_smoothing_m;
  options.frame = body_frame(tissue);
  const auto* stiffness = std::get_if<RegionStiffness>(&tissue.stiffness);
  const bool needs_regions = tissue.regional_load || (stiffness && stiffness->anatomical) ||
                             tissue.direction == DirectionKind::anatomical;
  options.regions = needs_regions ? std::make_shared<const mesh::SurfaceRegions>(regions_of(tissue, mesh)) : nullptr;
  if (tissue.regional_load) {
    options.load = mesh::regional_load(mesh, *options.regions, *tissue.regional_load, tissue.dome_load);
    const std::vector<double> position = dependent_position(tissue, mesh);
    for (std::size_t i = 0; i < options.load.size(); ++i)
      options.load[i] *= tissue.load_nondependent + position[i] * (tissue.load_dependent - tissue.load_nondependent);
  }
  return options;
}

}  // namespace pneuma::engine
