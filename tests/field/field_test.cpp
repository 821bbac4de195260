// Force to displacement (METHOD.md 4) and regional stiffness (METHOD.md 5) against invariants
// and finite differences.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <numbers>

#include "field_fixture.h"
#include "pneuma/core/error.h"
#include "pneuma/field/field.h"
#include "pneuma/field/tissue.h"
#include "pneuma/scenario/tissue_config.h"
#include "test_support.h"

using namespace pneuma;
using namespace pneuma::field;
using pneuma::scenario::load_tissue;

namespace {

double max_relative_difference(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
                               double scale_b = 1.0) {
  double worst = 0.0, largest = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    worst = std::max(worst, (a[i] - scale_b * b[i]).norm());
    largest = std::max(largest, a[i].norm());
  }
  return worst / largest;
}

Tissue preset(const std::string& name) {
  return load_tissue(test::source_dir() / "configs" / "tissue" / (name + ".yaml"));
}

// Mean |u| over the vertices whose dependent position lies in [lo, hi].
double mean_displacement(const ElastostaticField& f, const std::vector<double>& position, double lo, double hi) {
  double sum = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < position.size(); ++i) {
    if (position[i] >= lo && position[i] <= hi) {
      sum += f.unit_displacement[i].norm();
      ++n;
    }
  }
  return sum / n;
}

}  // namespace

TEST(Field, NormalisationGivesOneAreaUnitToFirstOrder) {
  for (const auto& m : {mesh::make_icosphere(0.1, 4), test::ellipsoid(0.12, 0.08, 0.15, 4)}) {
    const ElastostaticField f = compute_field(m, test::graded_modulus(m, 0.6e3, 2.4e3));
    const auto g = mesh::area_gradient(m);
    double first_order = 0.0;
    for (std::size_t i = 0; i < g.size(); ++i) first_order += g[i].dot(f.unit_displacement[i]);
    EXPECT_NEAR(first_order, 1e-4, 1e-4 * 1e-12);
    // Central finite difference of the area of rest + s u: O(s^2) error.
    const double s = 1e-2;
    mesh::TriangleMesh plus = m, minus = m;
    for (std::size_t i = 0; i < m.vertices.size(); ++i) {
      plus.vertices[i] += s * f.unit_displacement[i];
      minus.vertices[i] -= s * f.unit_displacement[i];
    }
    const double rate = (mesh::surface_area(plus) - mesh::surface_area(minus)) / (2 * s);
    EXPECT_NEAR(rate, 1e-4, 1e-4 * 1e-6);
  }
}

TEST(Field, UniformSphereMovesLikeARadialInflation) {
  // Analytic oracle: a sphere grown by dr gains 8 pi r dr of area, so one cm^2 needs
  // dr = 1e-4 / (8 pi r). The icosphere's field is nearly uniform and radial.
  const double r = 0.1;
  const auto m = mesh::make_icosphere(r, 4);
  const ElastostaticField f = compute_field(m, std::vector<double>(m.vertex_count(), 3e3));
  double mean = 0.0;
  for (std::size_t i = 0; i < m.vertex_count(); ++i) {
    mean += f.unit_displacement[i].norm();
    EXPECT_GT(f.unit_displacement[i].dot(m.vertices[i]), 0.0) << "outward";
  }
  mean /= static_cast<double>(m.vertex_count());
  EXPECT_NEAR(mean, 1e-4 / (8 * std::numbers::pi * r), 0.02 * 1e-4 / (8 * std::numbers::pi * r));
}

TEST(Field, MultiplyingEveryModulusByAConstantChangesNothing) {
  const auto m = test::ellipsoid(0.12, 0.08, 0.15, 3);
  const auto mu = test::graded_modulus(m, 0.6e3, 2.4e3);
  // The exact fixed point (LU) is invariant to rounding; the iterative solvers to their
  // tolerance (a last-bit change of m may change where they stop).
  for (SolverKind solver : {SolverKind::direct, SolverKind::cg, SolverKind::shot}) {
    FieldOptions o;
    o.solver = solver;
    const double allowed = solver == SolverKind::direct ? 1e-12 : 1e-5;
    const ElastostaticField a = compute_field(m, mu, o);
    for (double c : {1e-3, 7.25, 1e6}) {
      std::vector<double> scaled = mu;
      for (double& v : scaled) v *= c;
      EXPECT_LT(max_relative_difference(a.unit_displacement, compute_field(m, scaled, o).unit_displacement), allowed)
          << c;
    }
  }
}

TEST(Field, SameMeshInMillimetresAndMetresGivesTheSameField) {
  const auto metres = test::ellipsoid(0.12, 0.08, 0.15, 3);
  mesh::TriangleMesh millimetres = metres;
  for (auto& v : millimetres.vertices) v *= 1000.0;
  const auto mu = test::graded_modulus(metres, 0.6e3, 2.4e3);
  FieldOptions in_mm;
  in_mm.area_unit = 100.0;  // 1 cm^2 in mm^2
  const ElastostaticField a = compute_field(metres, mu);
  const ElastostaticField b = compute_field(millimetres, mu, in_mm);
  EXPECT_LT(max_relative_difference(a.unit_displacement, b.unit_displacement, 1e-3), 1e-9);
  EXPECT_EQ(a.report.iterations, b.report.iterations);
}

TEST(Field, SofterTissueMovesMore) {
  // healthy-upright: stiff apex (top), soft base: the base moves more; the fibrotic preset
  // turns that around for its stiff lower band.
  const auto m = test::ellipsoid(0.08, 0.06, 0.12, 4);
  const Tissue upright = preset("healthy-upright");
  const auto position = dependent_position(upright, m);
  const ElastostaticField healthy = compute_field(m, shear_modulus_per_vertex(upright, m));
  EXPECT_GT(mean_displacement(healthy, position, 0.8, 1.0), 1.2 * mean_displacement(healthy, position, 0.0, 0.2));
  const ElastostaticField fibrotic = compute_field(m, shear_modulus_per_vertex(preset("fibrotic-lower-lobe"), m));
  EXPECT_LT(mean_displacement(fibrotic, position, 0.8, 1.0), 0.5 * mean_displacement(fibrotic, position, 0.0, 0.2));
}

TEST(Field, SolversGiveTheSameField) {
  const auto m = test::ellipsoid(0.12, 0.08, 0.15, 3);
  const auto mu = test::contrast_modulus(m);
  FieldOptions o;
  const ElastostaticField reference = compute_field(m, mu, o);
  for (SolverKind k : {SolverKind::shot, SolverKind::sweep, SolverKind::direct}) {
    o.solver = k;
    EXPECT_LT(max_relative_difference(reference.unit_displacement, compute_field(m, mu, o).unit_displacement), 2e-5)
        << solver_name(k);
  }
  o.solver = SolverKind::cg;
  o.clique_hops = 2;
  EXPECT_THROW(compute_field(m, mu, o), UnsupportedError);
}

TEST(Field, FlatSurfaceCannotBeNormalised) {
  const auto grid = test::regular_grid(4, 4, 1.0);
  EXPECT_THROW(compute_field(grid, std::vector<double>(grid.vertex_count(), 1.0)), UnsupportedError);
}

TEST(Tissue, PresetsFollowPosture) {
  const auto m = mesh::make_icosphere(0.1, 3);
  auto extreme = [&](const Eigen::Vector3d& d) {
    std::size_t best = 0;
    for (std::size_t i = 0; i < m.vertex_count(); ++i) {
      if (m.vertices[i].dot(d) > m.vertices[best].dot(d)) best = i;
    }
    return best;
  };
  // The healthy presets: a modulus per anatomical region times the posture's gravity factor.
  const auto upright = shear_modulus_per_vertex(preset("healthy-upright"), m);
  EXPECT_NEAR(upright[extreme({0, 0, 1})], 3000.0 * 1.5, 1e-9);   // apex, top
  EXPECT_NEAR(upright[extreme({0, 0, -1})], 500.0 * 0.75, 1e-9);  // diaphragmatic, bottom
  // Supine, 1.8 to 0.6 over 175 mm, the gradient per metre (Tissue.TheGravityGradientsArePerMetre...):
  // this sphere is 2 r deep front to back.
  const auto supine = shear_modulus_per_vertex(preset("healthy-supine"), m);
  const double span = (m.vertices[extreme({0, 1, 0})].y() - m.vertices[extreme({0, -1, 0})].y()) / 0.175;
  EXPECT_NEAR(supine[extreme({0, -1, 0})], 1500.0 * (1.2 + 0.6 * span), 1e-9);  // costal, anterior (LPS: -y)
  EXPECT_NEAR(supine[extreme({0, 1, 0})], 1500.0 * (1.2 - 0.6 * span), 1e-9);   // costal, posterior
  // Both healthy presets blur the force in space at 3 mm (docs/realism.md).
  EXPECT_DOUBLE_EQ(with_tissue({}, preset("healthy-upright"), m).magnitude_smoothing, 3e-3);
  EXPECT_DOUBLE_EQ(with_tissue({}, preset("healthy-supine"), m).magnitude_smoothing, 3e-3);
  EXPECT_DOUBLE_EQ(with_tissue({}, preset("fibrotic-lower-lobe"), m).magnitude_smoothing, 0.0);
  const auto fibrotic = shear_modulus_per_vertex(preset("fibrotic-lower-lobe"), m);
  EXPECT_DOUBLE_EQ(fibrotic[extreme({0, 0, -1})], 10e3);
  EXPECT_DOUBLE_EQ(fibrotic[extreme({0, 0, 1})], 2400.0);
}

TEST(Tissue, ExponentialProfileIsGeometricAndAxesAreConfigurable) {
  test::TempDir dir;
  const auto file = dir.write(
      "t.yaml", "posture: upright\ncoordinates: {up: -y, anterior: +z}\n"
                "stiffness: {model: gradient, profile: exponential, nondependent: 4 kPa, dependent: 1 kPa}\n");
  const Tissue t = load_tissue(file);
  EXPECT_EQ(t.name, "t");
  mesh::TriangleMesh m;
  m.vertices = {{0, -1, 0}, {0, 0, 0}, {0, 1, 0}};
  const auto mu = shear_modulus_per_vertex(t, m);
  EXPECT_DOUBLE_EQ(mu[0], 4000.0);  // up is -y: the top
  EXPECT_NEAR(mu[1], 2000.0, 1e-9);
  EXPECT_DOUBLE_EQ(mu[2], 1000.0);
}

TEST(Tissue, PerVertexAndRegionFiles) {
  test::TempDir dir;
  const auto m = test::single_triangle();
  dir.write("mu.txt", "1.5\n2 # comment\n3\n");
  const Tissue pv =
      load_tissue(dir.write("pv.yaml", "posture: supine\nstiffness: {model: per_vertex, values: mu.txt, unit: kPa}\n"));
  EXPECT_EQ(shear_modulus_per_vertex(pv, m), (std::vector<double>{1500.0, 2000.0, 3000.0}));
  dir.write("labels.txt", "upper\nlower lower\n");
  const Tissue rg = load_tissue(dir.write(
      "rg.yaml",
      "posture: upright\nstiffness:\n  model: regions\n  labels: labels.txt\n  moduli: {upper: 2 kPa, lower: 10 kPa}\n"));
  EXPECT_EQ(shear_modulus_per_vertex(rg, m), (std::vector<double>{2000.0, 10000.0, 10000.0}));
  dir.write("short.txt", "1\n2\n");
  const Tissue bad = load_tissue(
      dir.write("bad.yaml", "posture: supine\nstiffness: {model: per_vertex, values: short.txt, unit: kPa}\n"));
  try {
    shear_modulus_per_vertex(bad, m);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), (dir / "short.txt").string() + ": expected 3 values (one per mesh vertex), got 2");
  }
}

TEST(Tissue, DomeProfileIsReadWithItsUnits) {
  test::TempDir dir;
  const Tissue t = load_tissue(dir.write(
      "t.yaml",
      "posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3 kPa, dependent: 1 kPa}\n"
      "load: {apex: 0.1, costal: 0.1, diaphragmatic: 1, mediastinal: 0, dome: {radius: 6 cm, falloff: 20 mm, rim: 0.3}}\n"));
  EXPECT_DOUBLE_EQ(t.dome_load.radius_m, 0.06);
  EXPECT_DOUBLE_EQ(t.dome_load.falloff_m, 0.02);
  EXPECT_DOUBLE_EQ(t.dome_load.rim, 0.3);
  // Without `dome`: no profile.
  const Tissue plain = load_tissue(dir.write(
      "p.yaml",
      "posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3 kPa, dependent: 1 kPa}\n"
      "load: {apex: 0.1, costal: 0.1, diaphragmatic: 1, mediastinal: 0}\n"));
  EXPECT_EQ(plain.dome_load.radius_m, 0.0);
}

// The supine preset's gravity factors (on the load: dependent regions ventilate more; on the
// modulus: mu ~ 0.7 P_L) change by the same amount per metre on any lung (`gravity: {..., depth:
// 175 mm}`): the pleural pressure's gradient per cm of height does not depend on the lung's size,
// so a lung shallower than 175 mm spans a smaller front-to-back range, not the same ratio (#45:
// the phantom, 129-141 mm deep, had the CT lungs' 3:1 and its recesses' tips tore). Oracle: the
// line (a + b) / 2 + (b - a) (y - y_mid) / D through each sphere's vertices (y the dependent axis,
// posterior +y in LPS), written out here.
TEST(Tissue, TheGravityGradientsArePerMetreWhateverTheLungsDepth) {
  const Tissue supine = preset("healthy-supine");
  ASSERT_DOUBLE_EQ(supine.load_gravity_depth_m, 0.175);
  ASSERT_DOUBLE_EQ(supine.load_nondependent, 0.5);
  ASSERT_DOUBLE_EQ(supine.load_dependent, 1.5);
  const auto& stiffness = std::get<RegionStiffness>(supine.stiffness);
  ASSERT_DOUBLE_EQ(stiffness.gravity_depth_m, 0.175);
  for (const double radius : {0.0625, 0.0875, 0.1}) {  // 125, 175 and 200 mm deep
    const auto m = mesh::make_icosphere(radius, 3);
    const std::vector<double> load = load_gravity_factor(supine, m);
    const std::vector<double> mu = gravity_factor(supine, m, stiffness.gravity_nondependent,
                                                  stiffness.gravity_dependent, stiffness.gravity_depth_m);
    double lo = 1.0, hi = -1.0;
    for (const Eigen::Vector3d& v : m.vertices) {
      lo = std::min(lo, v.y());
      hi = std::max(hi, v.y());
    }
    for (std::size_t i = 0; i < m.vertex_count(); ++i) {
      const double along = (m.vertices[i].y() - 0.5 * (lo + hi)) / 0.175;  // metres from the middle, in depths
      EXPECT_NEAR(load[i], 1.0 + 1.0 * along, 1e-12) << radius << " m, vertex " << i;
      EXPECT_NEAR(mu[i], 1.2 - 1.2 * along, 1e-12) << radius << " m, vertex " << i;
    }
    // The ends: 0.5 and 1.5 (1.8 and 0.6) on a lung 175 mm deep, narrower on a shallower one.
    EXPECT_NEAR(*std::min_element(load.begin(), load.end()), 1.0 - radius / 0.175, 1e-12) << radius;
    EXPECT_NEAR(*std::max_element(load.begin(), load.end()), 1.0 + radius / 0.175, 1e-12) << radius;
    // The modulus per vertex is the regions' blend times that factor.
    Tissue flat = supine;
    std::get<RegionStiffness>(flat.stiffness).gravity_nondependent = 1.0;
    std::get<RegionStiffness>(flat.stiffness).gravity_dependent = 1.0;
    const std::vector<double> with = shear_modulus_per_vertex(supine, m), without = shear_modulus_per_vertex(flat, m);
    for (std::size_t i = 0; i < m.vertex_count(); ++i) EXPECT_NEAR(with[i], without[i] * mu[i], 1e-9 * with[i]) << i;
  }
  // Without `depth` the factors are a and b at the lung's own ends, whatever its depth (the rule
  // before; the upright preset keeps it for its modulus and has no load gravity).
  Tissue by_ends = supine;
  by_ends.load_gravity_depth_m = 0.0;
  for (const double radius : {0.0625, 0.1}) {
    const std::vector<double> factor = load_gravity_factor(by_ends, mesh::make_icosphere(radius, 3));
    EXPECT_NEAR(*std::min_element(factor.begin(), factor.end()), 0.5, 1e-12);
    EXPECT_NEAR(*std::max_element(factor.begin(), factor.end()), 1.5, 1e-12);
  }
  const std::vector<double> upright = load_gravity_factor(preset("healthy-upright"), mesh::make_icosphere(0.1, 3));
  EXPECT_EQ(*std::min_element(upright.begin(), upright.end()), 1.0);
  EXPECT_EQ(*std::max_element(upright.begin(), upright.end()), 1.0);
  // The load the field takes is the regional load times the load's factor.
  const auto m = mesh::make_icosphere(0.0625, 3);
  const FieldOptions with = with_tissue({}, supine, m), without = with_tissue({}, by_ends, m);
  const std::vector<double> factor = load_gravity_factor(supine, m), ends = load_gravity_factor(by_ends, m);
  for (std::size_t i = 0; i < m.vertex_count(); ++i) {
    EXPECT_NEAR(with.load[i] * ends[i], without.load[i] * factor[i], 1e-12 * (1.0 + without.load[i])) << i;
  }
  // A lung too deep for the modulus's factors (1.8 to 0.6 over 10 mm on a 200 mm sphere): one line.
  Tissue steep = supine;
  std::get<RegionStiffness>(steep.stiffness).gravity_depth_m = 0.01;
  EXPECT_THROW(shear_modulus_per_vertex(steep, mesh::make_icosphere(0.1, 3)), InputError);
}

TEST(Tissue, SlidingIsReadInUnitsOfTheDiaphragmsDescent) {
  const Tissue slide = preset("healthy-supine-slide");
  EXPECT_DOUBLE_EQ(slide.sliding.caudal, 1.2);
  EXPECT_DOUBLE_EQ(slide.sliding.exponent, 0.5);
  EXPECT_DOUBLE_EQ(slide.sliding.anterior, 0.0);  // #45: it squeezed the lingula's margin
  EXPECT_DOUBLE_EQ(slide.sliding.mediastinal, 0.0);
  EXPECT_TRUE(slide.sliding.active());
  EXPECT_FALSE(preset("healthy-upright").sliding.active());
  // One supine preset (#45): healthy-supine-slide is its former name.
  const Tissue supine = preset("healthy-supine");
  EXPECT_EQ(supine.name, "healthy-supine");
  EXPECT_EQ(slide.name, "healthy-supine");
  EXPECT_DOUBLE_EQ(supine.sliding.caudal, slide.sliding.caudal);
  // The heart descends with the diaphragm (#45): 0.6 of it, below half the lung's height.
  EXPECT_DOUBLE_EQ(supine.heart.descent, 0.6);
  EXPECT_DOUBLE_EQ(supine.heart.top, 0.5);
  EXPECT_TRUE(supine.heart.active());
  // In any posture (#45: the upright recesses of case008 and case009 stretched without it).
  const Tissue upright = preset("healthy-upright");
  EXPECT_DOUBLE_EQ(upright.heart.descent, 0.6);
  EXPECT_DOUBLE_EQ(upright.heart.top, 0.5);
}

// The lung's face on the heart takes the heart's descent where it looks down onto it (#45,
// field/heart.h). On a sphere of radius r that is all mediastinal face (regions made by hand),
// the smoothed normal is radial, so the oracle is analytic: at height h = (z + r) / 2r,
//   descent * g(h) * max(0, -z / r) * (-up),  g = 1 below top - 0.1, 0 above top + 0.1.
TEST(HeartDescent, TheFaceOnTheHeartDescendsAsFarAsItLooksDown) {
  const double r = 0.1;
  const auto m = mesh::make_icosphere(r, 4);
  mesh::SurfaceRegions regions;
  const std::size_t n = m.vertices.size();
  regions.label.assign(n, mesh::Region::mediastinal);
  regions.weight.assign(n, {0.0, 0.0, 0.0, 1.0});
  for (const Eigen::Vector3d& x : m.vertices) regions.height.push_back((x.z() + r) / (2.0 * r));
  const HeartDescent heart{.descent = 0.6, .top = 0.5};
  const auto moved = heart_descent_field(m, regions, heart, 0.01);
  double worst = 0.0, largest = 0.0;
  std::size_t below = 0, above = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double h = regions.height[i];
    const double g = h <= 0.4 ? 1.0 : h >= 0.6 ? 0.0 : -1.0;  // the smooth step's ends, exactly
    if (g < 0.0) continue;
    const double expected = heart.descent * g * std::max(0.0, -m.vertices[i].z() / r);
    worst = std::max(worst, (moved[i] - Eigen::Vector3d(0.0, 0.0, -expected)).norm());
    largest = std::max(largest, expected);
    (h < 0.4 ? below : above) += 1;
  }
  EXPECT_GT(below, 100u);
  EXPECT_GT(above, 100u);
  EXPECT_NEAR(largest, 0.6, 0.01);         // the lowest point descends with the heart
  EXPECT_LT(worst, 0.01 * heart.descent);  // the smoothed normal of a sphere: radial to 1 %
  // Linear in the descent; none at 0; the costal face (weights by hand) none either.
  const auto half = heart_descent_field(m, regions, {.descent = 0.3, .top = 0.5}, 0.01);
  for (std::size_t i = 0; i < n; ++i) EXPECT_NEAR((moved[i] - 2.0 * half[i]).norm(), 0.0, 1e-15);
  for (const auto& v : heart_descent_field(m, regions, {.descent = 0.0, .top = 0.5}, 0.01)) EXPECT_EQ(v.norm(), 0.0);
  mesh::SurfaceRegions costal = regions;
  costal.weight.assign(n, {0.0, 1.0, 0.0, 0.0});
  for (const auto& v : heart_descent_field(m, costal, heart, 0.01)) EXPECT_EQ(v.norm(), 0.0);
  EXPECT_THROW(heart_descent_field(m, regions, {.descent = 1.5, .top = 0.5}, 0.01), ValueError);
  EXPECT_THROW(heart_descent_field(mesh::make_icosphere(r, 2), regions, heart, 0.01), ValueError);
}

// A face below the dome's top that looks up lies under the diaphragm (case009's stretched
// recess, #45) and moves with the surface around it, as far as it looks up. On a sphere of radius
// r the smoothed normal is radial, so the oracle is analytic. All of it diaphragmatic by label (no
// normals given: the dome's top is then the highest diaphragmatic vertex, the sphere's top):
// below 0.95 of the height the weight is max(0, z / r). Diaphragmatic below the equator only
// (normals given, radial): the dome's top is the highest vertex whose normal lies within 30
// degrees of straight down (h = (1 - cos 30) / 2 = 0.067), and nothing below it looks up: no
// weight anywhere, and the field is left as it was, bit for bit. A uniform field is its own
// mean: unchanged.
TEST(HeartDescent, AFaceUnderTheDiaphragmMovesWithTheSurfaceAroundIt) {
  const double r = 0.1;
  const auto m = mesh::make_icosphere(r, 4);
  const std::size_t n = m.vertices.size();
  mesh::SurfaceRegions regions;
  regions.label.assign(n, mesh::Region::diaphragmatic);
  regions.weight.assign(n, {0.0, 0.0, 1.0, 0.0});
  for (const Eigen::Vector3d& x : m.vertices) regions.height.push_back((x.z() + r) / (2.0 * r));
  const std::vector<double> under = under_diaphragm(m, regions);
  double worst = 0.0, largest = 0.0;
  std::size_t checked = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (regions.height[i] > 0.95) continue;  // the band below the dome's top
    const double expected = std::max(0.0, m.vertices[i].z() / r);
    worst = std::max(worst, std::abs(under[i] - expected));
    largest = std::max(largest, under[i]);
    ++checked;
  }
  EXPECT_GT(checked, 2000u);
  EXPECT_GT(largest, 0.85);  // the face looking nearly straight up, at 0.95 of the height
  EXPECT_LT(worst, 0.01);    // the smoothed normal of a sphere: radial to 1 %
  std::vector<Eigen::Vector3d> uniform(n, Eigen::Vector3d(0.001, -0.002, -0.01));
  follow_the_diaphragm_over(m, regions, uniform);
  for (const Eigen::Vector3d& v : uniform) EXPECT_NEAR((v - Eigen::Vector3d(0.001, -0.002, -0.01)).norm(), 0.0, 1e-12);

  mesh::SurfaceRegions base = regions;
  for (std::size_t i = 0; i < n; ++i) {
    base.normal.push_back(m.vertices[i].normalized());
    if (m.vertices[i].z() > 0.0) {
      base.label[i] = mesh::Region::costal;
      base.weight[i] = {0.0, 1.0, 0.0, 0.0};
    }
  }
  for (const double w : under_diaphragm(m, base)) EXPECT_EQ(w, 0.0);
  std::vector<Eigen::Vector3d> radial(n);
  for (std::size_t i = 0; i < n; ++i) radial[i] = 0.01 * m.vertices[i];
  std::vector<Eigen::Vector3d> moved = radial;
  follow_the_diaphragm_over(m, base, moved);
  EXPECT_EQ(moved, radial);
  EXPECT_THROW(under_diaphragm(mesh::make_icosphere(r, 2), regions), ValueError);
}

// The costophrenic margin (case009's anterior recess upright, #45): where the costal and the
// diaphragmatic face meet below the dome's top in a thin edge, both move with the surface around
// them. The oracle is the rule's definition summed directly over the vertices (a Gaussian of
// sigma = 10 mm over vertex areas), against the function's blur on its grid: on a lens 12 mm
// thick and 200 mm wide (thin everywhere: its faces' normals cancel over 10 mm) whose costal
// weight is Phi(x / 5 mm), the lower face's weight is min(1, 4 c d) (1 - |N|), c, d and N the
// costal and diaphragmatic weights and the normals so averaged; its motion u + w (ubar - u). On
// a sphere of radius 100 mm (thick: |N| = 0.99) the same border moves by under 2 %.
TEST(HeartDescent, AThinCostophrenicMarginMovesWithTheSurfaceAroundIt) {
  const double sigma = 0.01, tau = 0.005;
  const auto phi = [](double t) { return 0.5 * std::erfc(-t / std::sqrt(2.0)); };
  const auto setup = [&](const mesh::TriangleMesh& m) {
    mesh::SurfaceRegions regions;
    double lo = 1e9, hi = -1e9;
    for (const Eigen::Vector3d& x : m.vertices) lo = std::min(lo, x.z()), hi = std::max(hi, x.z());
    for (const Eigen::Vector3d& x : m.vertices) {
      const double costal = phi(x.x() / tau);
      regions.label.push_back(costal >= 0.5 ? mesh::Region::costal : mesh::Region::diaphragmatic);
      regions.weight.push_back({0.0, costal, 1.0 - costal, 0.0});
      regions.height.push_back((x.z() - lo) / (hi - lo));
    }
    return regions;
  };
  // The direct Gaussian average over vertex areas of per-vertex vectors.
  const auto averaged = [&](const mesh::TriangleMesh& m, const std::vector<Eigen::Vector3d>& v) {
    std::vector<double> area(m.vertices.size(), 0.0);
    for (const auto& t : m.triangles) {
      const double a = 0.5 * (m.vertices[t[1]] - m.vertices[t[0]]).cross(m.vertices[t[2]] - m.vertices[t[0]]).norm();
      for (const auto k : t) area[k] += a / 3.0;
    }
    std::vector<Eigen::Vector3d> out(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      double total = 0.0;
      for (std::size_t j = 0; j < v.size(); ++j) {
        const double g = area[j] * std::exp(-0.5 * (m.vertices[i] - m.vertices[j]).squaredNorm() / (sigma * sigma));
        sum += g * v[j];
        total += g;
      }
      out[i] = sum / total;
    }
    return out;
  };

  mesh::TriangleMesh lens = mesh::make_icosphere(1.0, 4);
  for (Eigen::Vector3d& x : lens.vertices) x = Eigen::Vector3d(0.1 * x.x(), 0.1 * x.y(), 0.006 * x.z());
  const std::size_t n = lens.vertices.size();
  const mesh::SurfaceRegions regions = setup(lens);
  std::vector<Eigen::Vector3d> weights(n), u(n);
  for (std::size_t i = 0; i < n; ++i) {
    weights[i] = Eigen::Vector3d(regions.weight[i][1], regions.weight[i][2], 0.0);
    u[i] = Eigen::Vector3d(0.0, 0.0, -0.02 * regions.weight[i][2]);  // the diaphragmatic side descends 20 mm
  }
  const std::vector<Eigen::Vector3d> cd = averaged(lens, weights);
  const std::vector<Eigen::Vector3d> normal = averaged(lens, mesh::vertex_normals(lens));
  const std::vector<Eigen::Vector3d> ubar = averaged(lens, u);
  const std::vector<double> under = under_diaphragm(lens, regions);
  std::vector<Eigen::Vector3d> moved = u;
  follow_the_diaphragm_over(lens, regions, moved);
  double worst = 0.0, worst_moved = 0.0, on_border = 1.0;
  std::size_t checked = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (lens.vertices[i].z() > -0.003) continue;  // the lower face (looking down), off the rim
    const double expected = std::min(1.0, 4.0 * cd[i].x() * cd[i].y()) * (1.0 - normal[i].norm());
    worst = std::max(worst, std::abs(under[i] - expected));
    worst_moved = std::max(worst_moved, (moved[i] - (u[i] + under[i] * (ubar[i] - u[i]))).norm());
    if (std::abs(lens.vertices[i].x()) < 0.002) on_border = std::min(on_border, under[i]);
    ++checked;
  }
  std::cout << "thin margin: weight against the direct sum within " << worst << ", on the border >= " << on_border
            << ", motion within " << worst_moved * 1e3 << " mm\n";
  EXPECT_GT(checked, 500u);
  EXPECT_GT(on_border, 0.5);       // the thin edge's faces move most of the way together
  EXPECT_LT(worst, 0.12);          // the grid's blur (splat, blur, sample) against the direct sum: 0.10
  EXPECT_LT(worst_moved, 0.5e-3);  // of a 20 mm step

  // The same border on a thick lung: its faces' normals do not cancel, it keeps its motion.
  const auto ball = mesh::make_icosphere(0.1, 4);
  const std::vector<double> thick = under_diaphragm(ball, setup(ball));
  double largest = 0.0;
  for (std::size_t i = 0; i < ball.vertices.size(); ++i) {
    if (ball.vertices[i].z() < -0.02) largest = std::max(largest, thick[i]);
  }
  EXPECT_LT(largest, 0.02);

  // Margin::kept (a tissue that slides): the lower face looks down, so nothing moves.
  const std::vector<double> looking_up_only = under_diaphragm(lens, regions, Margin::kept);
  std::vector<Eigen::Vector3d> kept = u;
  follow_the_diaphragm_over(lens, regions, kept, Margin::kept);
  for (std::size_t i = 0; i < n; ++i) {
    if (lens.vertices[i].z() < -0.003) {
      EXPECT_EQ(looking_up_only[i], 0.0);
      EXPECT_EQ(kept[i], u[i]);
    }
  }
}

TEST(Tissue, BadFilesAreOneLine) {
  test::TempDir dir;
  struct Bad {
    const char* yaml;
    const char* message;
  };
  const Bad cases[] = {
      {"posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3 kg, dependent: 1 kPa}\n",
       "2:61: stiffness.nondependent: expected a shear modulus such as '3 kPa', got '3 kg'"},
      {"posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3, dependent: 1 kPa}\n",
       "2:61: stiffness.nondependent: expected a shear modulus such as '3 kPa', got '3'"},
      {"posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3 kPa, dependent: 1 kPa, band: []}\n",
       "2:86: stiffness.band: unknown key; expected one of: bands, dependent, model, nondependent, profile"},
      {"posture: sideways\nstiffness: {model: gradient}\n",
       "1:10: posture: expected one of: upright, supine, prone; got 'sideways'"},
      {"posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3 kPa, dependent: 1 kPa}\ndisplacement: {magnitude_smoothing: 3}\n",
       "3:37: displacement.magnitude_smoothing: expected a length such as '3 mm', got '3'"},
      {"posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3 kPa, dependent: 1 kPa}\ndisplacement: {magnitude_smoothing: -3 mm}\n",
       "3:37: displacement.magnitude_smoothing: expected a length >= 0 such as '3 mm'"},
      {"posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3 kPa, dependent: 1 kPa}\n"
       "load: {apex: 0, costal: 0, diaphragmatic: 1, mediastinal: 0, dome: {radius: 60, falloff: 2 cm, rim: 0.3}}\n",
       "3:77: load.dome.radius: expected a length such as '3 mm', got '60'"},
      {"posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3 kPa, dependent: 1 kPa}\n"
       "load: {apex: 0, costal: 0, diaphragmatic: 1, mediastinal: 0, dome: {radius: 6 cm, falloff: 2 cm, rim: 1.3}}\n",
       "3:103: load.dome.rim: expected a factor from 0 to 1"},
      {"posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3 kPa, dependent: 1 kPa}\n"
       "load: {apex: 0, costal: 0, diaphragmatic: 1, mediastinal: 0, dome: {radius: 6 cm, rim: 0.3}}\n",
       "3:68: load.dome: missing key 'falloff' (expected length such as '3 mm')"},
      {"posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3 kPa, dependent: 1 kPa}\n"
       "load: {apex: 0, costal: 0, diaphragmatic: 1, mediastinal: 0, dome: {radius: 6 cm, area: 150 cm^2, falloff: 2 "
       "cm, rim: 0.3}}\n",
       "3:68: load.dome: expected one of 'radius' and 'area'"},
      {"posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3 kPa, dependent: 1 kPa}\n"
       "load: {apex: 0, costal: 0, diaphragmatic: 1, mediastinal: 0, dome: {area: -1 cm^2, falloff: 2 cm, rim: 0.3}}\n",
       "3:75: load.dome.area: expected a positive area, got '-1 cm^2'"},
      {"posture: supine\nstiffness: {model: gradient, profile: linear, nondependent: 3 kPa, dependent: 1 kPa}\n"
       "load: {apex: 0, costal: 0, diaphragmatic: 1, mediastinal: 0, gravity: {nondependent: 0.5, dependent: 1.5, "
       "depth: 175}}\n",
       "3:114: load.gravity.depth: expected a length such as '3 mm', got '175'"},
      {"posture: supine\nstiffness: {model: regions, moduli: {apex: 3 kPa, costal: 1.5 kPa, diaphragmatic: 0.5 kPa, "
       "mediastinal: 20 kPa}, gravity: {nondependent: 1.8, dependent: 0.6, depth: -1 mm}}\n",
       "2:166: stiffness.gravity.depth: expected a positive length, got '-1 mm'"},
      {"alias: healthy-upright\nposture: upright\n", "2:1: posture: unknown key; expected one of: alias"},
      {"posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3 kPa, dependent: 1 kPa}\n"
       "sliding: {caudal: 7}\n",
       "3:19: sliding.caudal: expected a factor from 0 to 5 (of the diaphragm's descent)"},
      {"posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3 kPa, dependent: 1 kPa}\n"
       "sliding: {caudal: 1, exponent: 0}\n",
       "3:32: sliding.exponent: expected an exponent above 0 and at most 4"},
      {"posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3 kPa, dependent: 1 kPa}\n"
       "sliding: {caudal: 1, blur: 1 m}\n",
       "3:28: sliding.blur: expected a length from 0 to 200 mm"},
      {"posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3 kPa, dependent: 1 kPa}\n"
       "heart: {descent: 1.5}\n",
       "3:18: heart.descent: expected a factor from 0 to 1 (of the diaphragm's descent)"},
      {"posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3 kPa, dependent: 1 kPa}\n"
       "heart: {descent: 0.6, top: 1}\n",
       "3:28: heart.top: expected a height above 0.1 and below 0.9"},
      {"posture: upright\nstiffness: {model: gradient, profile: linear, nondependent: 3 kPa, dependent: 1 kPa}\n"
       "heart: {top: 0.5}\n",
       "3:8: heart: missing key 'descent' (expected fraction such as '0.5 or 50 %')"},
  };
  for (const Bad& c : cases) {
    const auto file = dir.write("t.yaml", c.yaml);
    try {
      load_tissue(file);
      ADD_FAILURE() << c.yaml;
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()), file.string() + ":" + c.message);
    }
  }
}

// with_tissue finds the surface's regions once, where the tissue needs them; the moduli and the
// anatomical direction then use those, and give bit for bit what finding them again gives.
TEST(Tissue, RegionsFoundOnceGiveWhatFindingThemAgainGives) {
  const auto m = mesh::make_icosphere(0.1, 3);
  const Tissue upright = preset("healthy-upright");
  const FieldOptions options = with_tissue({}, upright, m);
  ASSERT_TRUE(options.regions);
  mesh::RegionOptions region_options;
  region_options.axes = body_axes(upright);
  const mesh::SurfaceRegions direct = mesh::find_regions(m, region_options);
  EXPECT_EQ(options.regions->label, direct.label);
  EXPECT_EQ(options.regions->weight, direct.weight);
  EXPECT_EQ(shear_modulus_per_vertex(upright, m, options.regions.get()), shear_modulus_per_vertex(upright, m));
  FieldOptions finding_again = options;
  finding_again.regions = nullptr;
  ASSERT_EQ(options.direction, DirectionKind::anatomical);
  EXPECT_EQ(displacement_directions(m, options), displacement_directions(m, finding_again));
  // A tissue that needs no regions (a height gradient, normal directions, a uniform load) gets none.
  EXPECT_FALSE(with_tissue({}, preset("fibrotic-lower-lobe"), m).regions);
  // Regions of another surface are refused, not used.
  const auto other = mesh::make_icosphere(0.1, 2);
  EXPECT_THROW(displacement_directions(other, options), ValueError);
  EXPECT_THROW(shear_modulus_per_vertex(upright, other, options.regions.get()), ValueError);
  // And so are regions found in other body axes (a surface given with anterior up).
  Tissue turned = upright;
  turned.up = {0.0, -1.0, 0.0};
  turned.anterior = {0.0, 0.0, -1.0};
  EXPECT_THROW(shear_modulus_per_vertex(turned, m, options.regions.get()), ValueError);
  FieldOptions other_axes = options;
  other_axes.axes = body_axes(turned);
  EXPECT_THROW(displacement_directions(m, other_axes), ValueError);
}
