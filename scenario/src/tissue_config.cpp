// Tissue files (configs/tissue/*.yaml) read into field::Tissue: the YAML side of the tissue,
// kept out of the field module so that it knows no YAML.
#include "pneuma/scenario/tissue_config.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <sstream>

#include "pneuma/core/error.h"
#include "pneuma/core/paths.h"
#include "pneuma/core/text.h"
#include "pneuma/core/units.h"

namespace pneuma::scenario {
namespace {

using scenario::Node;
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
  std::istringstream in(read_file_bytes(file, 1u << 30u));  // a device or a pipe is refused there
  std::vector<Token> tokens;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    if (auto hash = line.find('#'); hash != std::string::npos) line.resize(hash);
    std::istringstream words(line);
    for (std::string w; words >> w;) tokens.push_back({w, number});
  }
  return tokens;
}

// The shear moduli the field takes (docs/tissue.md): lung tissue is 0.1 to tens of kPa; far past
// 1 GPa sums overflow and the field fails away from the key that caused it.
constexpr double kMinShearModulusPa = 1.0;
constexpr double kMaxShearModulusPa = 1e9;
constexpr const char* kShearModulusRange = "a shear modulus from 1 Pa to 1 GPa";

double shear_modulus(const scenario::Node& n, const std::string& key) {
  const double pa = n.positive_quantity(key, kind::shear_modulus);
  if (!(pa >= kMinShearModulusPa && pa <= kMaxShearModulusPa))
    n.fail_at(key, std::string("expected ") + kShearModulusRange + ", got " + quote_input(n.string(key)));
  return pa;
}

field::GradientStiffness read_gradient(const scenario::Node& s) {
  field::GradientStiffness g;
  g.profile = s.choice("profile", {"linear", "exponential"}) == "linear"
                  ? field::GradientStiffness::Profile::linear
                  : field::GradientStiffness::Profile::exponential;
  g.nondependent_pa = shear_modulus(s, "nondependent");
  g.dependent_pa = shear_modulus(s, "dependent");
  for (const scenario::Node& band : s.sequence("bands")) {
    field::StiffnessBand b;
    b.from = band.quantity("from", kind::fraction);
    b.to = band.quantity("to", kind::fraction);
    if (!(b.from >= 0.0 && b.from <= 1.0)) band.fail_at("from", "expected a position from 0 to 1");
    if (!(b.to > b.from && b.to <= 1.0)) band.fail_at("to", "expected a position after 'from' and at most 1");
    b.shear_modulus_pa = shear_modulus(band, "shear_modulus");
    band.finish();
    g.bands.push_back(b);
  }
  return g;
}

field::PerVertexStiffness read_per_vertex(const scenario::Node& s) {
  field::PerVertexStiffness p;
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
      throw InputError(file.string() + ":" + std::to_string(t.line) + ": expected a positive number, got '" + t.text +
                       "'");
    if (!(v * factor >= kMinShearModulusPa && v * factor <= kMaxShearModulusPa))
      throw InputError(file.string() + ":" + std::to_string(t.line) + ": expected " + kShearModulusRange + ", got '" +
                       t.text + " " + unit + "'");
    p.shear_modulus_pa.push_back(v * factor);
  }
  return p;
}

field::RegionStiffness read_regions(const scenario::Node& s) {
  field::RegionStiffness r;
  const scenario::Node moduli = s.map("moduli");
  for (const std::string& label : moduli.keys()) r.shear_modulus_pa[label] = shear_modulus(moduli, label);
  if (r.shear_modulus_pa.empty()) s.fail_at("moduli", "expected at least one label with its shear modulus");
  if (auto g = s.optional_map("gravity")) {
    r.gravity_nondependent = g->quantity("nondependent", kind::fraction);
    r.gravity_dependent = g->quantity("dependent", kind::fraction);
    if (!(r.gravity_nondependent > 0.0)) g->fail_at("nondependent", "expected a positive factor");
    if (!(r.gravity_dependent > 0.0)) g->fail_at("dependent", "expected a positive factor");
    if (g->has("depth")) r.gravity_depth_m = g->positive_quantity("depth", kind::length);
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

}  // namespace

field::Tissue read_tissue(const scenario::Node& root) {
  field::Tissue t;
  t.name = root.has("name") ? root.string("name") : std::filesystem::path(root.file()).stem().string();
  const std::string posture = root.choice("posture", {"upright", "supine", "prone"});
  t.posture = posture == "upright"  ? field::Posture::upright
              : posture == "supine" ? field::Posture::supine
                                    : field::Posture::prone;
  if (auto c = root.optional_map("coordinates")) {
    if (c->has("up")) t.up = axis_vector(c->choice("up", kAxes));
    if (c->has("anterior")) t.anterior = axis_vector(c->choice("anterior", kAxes));
    if (std::abs(t.up.dot(t.anterior)) > 0.5) c->fail_at("anterior", "expected an axis at right angles to 'up'");
    c->finish();
  }
  const scenario::Node s = root.map("stiffness");
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
      if (g->has("depth")) t.load_gravity_depth_m = g->positive_quantity("depth", kind::length);
      g->finish();
    }
    if (auto d = l->optional_map("dome")) {
      // Either a fixed radius or the lung's own, from the area that moves with the dome.
      if (d->has("radius") == d->has("area")) d->fail("expected one of 'radius' and 'area'");
      if (d->has("radius")) t.dome_load.radius_m = d->positive_quantity("radius", kind::length);
      else t.dome_load.area_m2 = d->positive_quantity("area", kind::area);
      t.dome_load.falloff_m = d->positive_quantity("falloff", kind::length);
      t.dome_load.rim = d->quantity("rim", kind::fraction);
      if (!(t.dome_load.rim >= 0.0 && t.dome_load.rim <= 1.0)) d->fail_at("rim", "expected a factor from 0 to 1");
      d->finish();
    }
    l->finish();
    t.regional_load = load;
  }
  if (auto d = root.optional_map("displacement")) {
    if (d->has("direction"))
      t.direction =
          field::parse_direction_kind(d->choice("direction", {"vertex_normal", "smoothed_normal", "anatomical"}));
    if (d->has("smoothing")) t.direction_smoothing_m = d->positive_quantity("smoothing", kind::length);
    if (d->has("magnitude_smoothing")) {
      t.magnitude_smoothing_m = d->quantity("magnitude_smoothing", kind::length);
      if (!(t.magnitude_smoothing_m >= 0.0)) d->fail_at("magnitude_smoothing", "expected a length >= 0 such as '3 mm'");
    }
    d->finish();
  }
  if (auto sl = root.optional_map("sliding")) {
    auto amplitude = [&](const char* key) {
      const double v = sl->optional_quantity(key, kind::fraction).value_or(0.0);
      if (!(v >= 0.0 && v <= 5.0)) sl->fail_at(key, "expected a factor from 0 to 5 (of the diaphragm's descent)");
      return v;
    };
    t.sliding.caudal = amplitude("caudal");
    t.sliding.anterior = amplitude("anterior");
    t.sliding.mediastinal = amplitude("mediastinal");
    if (sl->has("blur")) {
      t.sliding.blur_m = sl->quantity("blur", kind::length);
      if (!(t.sliding.blur_m >= 0.0 && t.sliding.blur_m <= 0.2))
        sl->fail_at("blur", "expected a length from 0 to 200 mm");
    }
    if (sl->has("exponent")) {
      t.sliding.exponent = sl->quantity("exponent", kind::fraction);
      if (!(t.sliding.exponent > 0.0 && t.sliding.exponent <= 4.0))
        sl->fail_at("exponent", "expected an exponent above 0 and at most 4");
    }
    if (sl->has("base")) {
      t.sliding.base = sl->quantity("base", kind::fraction);
      if (!(t.sliding.base >= 0.0 && t.sliding.base < 1.0))
        sl->fail_at("base", "expected a fraction from 0 to below 1");
    }
    sl->finish();
  }
  if (auto hd = root.optional_map("heart")) {
    t.heart.descent = hd->quantity("descent", kind::fraction);
    if (!(t.heart.descent >= 0.0 && t.heart.descent <= 1.0))
      hd->fail_at("descent", "expected a factor from 0 to 1 (of the diaphragm's descent)");
    if (hd->has("top")) {
      t.heart.top = hd->quantity("top", kind::fraction);
      if (!(t.heart.top > 0.1 && t.heart.top < 0.9)) hd->fail_at("top", "expected a height above 0.1 and below 0.9");
    }
    hd->finish();
  }
  root.finish();
  return t;
}

field::Tissue load_tissue(const std::filesystem::path& path) {
  const scenario::Node root = scenario::Node::load_file(path);
  // `alias: NAME`: another preset beside this file under a former name (healthy-upright-ct).
  if (const auto alias = root.optional_string("alias")) {
    root.finish();
    const std::filesystem::path target = path.parent_path() / (*alias + ".yaml");
    if (alias->empty() || alias->find('/') != std::string::npos || !path_exists(target))
      root.fail_at("alias", "expected the name of a tissue preset beside this file (no " + target.string() + ")");
    const scenario::Node aliased = scenario::Node::load_file(target);
    if (aliased.has("alias")) aliased.fail_at("alias", "expected a tissue preset, not another alias");
    return read_tissue(aliased);
  }
  return read_tissue(root);
}

std::filesystem::path tissue_file(const std::string& name_or_path, const std::filesystem::path& config_dir) {
  if (name_or_path.find('/') != std::string::npos || name_or_path.ends_with(".yaml")) return name_or_path;
  return config_dir / "tissue" / (name_or_path + ".yaml");
}

}  // namespace pneuma::scenario
