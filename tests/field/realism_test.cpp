// The shipped healthy presets on the phantom against the human figures of docs/realism.md, and
// the anatomical direction against folding: a deep breath animates without self-intersection.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>

#include "field_fixture.h"
#include "pneuma/field/tissue.h"
#include "pneuma/mesh/anatomy/motion_summary.h"
#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/mesh/anatomy/sliding.h"
#include "pneuma/mesh/geometry/surface_queries.h"
#include "pneuma/mesh/labels/labels.h"
#include "pneuma/mesh/repair/remesh.h"
#include "pneuma/model/field_cache.h"
#include "pneuma/model/volume_scale.h"
#include "pneuma/scenario/physiology_config.h"
#include "pneuma/scenario/tissue_config.h"
#include "test_support.h"

namespace pneuma::field {
using model::field_key;
using model::VolumeScaleMap;
using scenario::default_config_dir;
using scenario::load_tissue;
using scenario::tissue_file;
namespace {

struct Breath {
  mesh::TriangleMesh rest;
  model::FieldRecord field;
  mesh::SurfaceRegions regions;
  double scale = 0.0;
};

Breath breathe(mesh::Lung lung, const std::string& tissue_name, double volume_m3, double edge_m = 4e-3) {
  mesh::PhantomOptions p;
  p.lung = lung;
  p.edge_length_m = edge_m;
  Breath b;
  b.rest = mesh::make_lung_phantom(p);
  const Tissue tissue = load_tissue(tissue_file(tissue_name, default_config_dir()));
  b.field = model::compute_field_record(b.rest, tissue, default_field_options);
  mesh::RegionOptions o;
  o.axes = body_axes(tissue);
  b.regions = mesh::find_regions(b.rest, o);
  const VolumeScaleMap map(b.rest.vertices, b.field.unit_displacement, b.rest.triangles);
  b.scale = map.scale_for(map.volume(0.0) + volume_m3);
  return b;
}

const mesh::RegionMotion& of(const mesh::MotionSummary& s, mesh::Region r) {
  return s.region[static_cast<std::size_t>(r)];
}

// A CT lung's quiet breath against the human figures of docs/realism.md (upright, quiet): the
// diaphragm descends at least 8 mm and carries 60-78 % of the volume, the apex and the mediastinal
// face nearly still, the dome's top 13-21 mm.
void expect_human_quiet_breath(const mesh::MotionSummary& s) {
  EXPECT_GE(of(s, mesh::Region::diaphragmatic).caudal_mean_m, 8e-3);
  EXPECT_GE(of(s, mesh::Region::diaphragmatic).volume_share, 0.60);
  EXPECT_LE(of(s, mesh::Region::diaphragmatic).volume_share, 0.78);
  EXPECT_LE(of(s, mesh::Region::apex).magnitude_mean_m, 3e-3);
  EXPECT_LE(of(s, mesh::Region::mediastinal).magnitude_mean_m, 1e-3);
  EXPECT_GE(s.dome_top_caudal_m, 13e-3);
  EXPECT_LE(s.dome_top_caudal_m, 21e-3);
}

TEST(Realism, QuietBreathingUprightMatchesHumanFigures) {
  // 500 mL, 55 % to the right lung (issue #16 targets).
  const Breath b = breathe(mesh::Lung::right, "healthy-upright", 0.55 * 500e-6);
  const mesh::MotionSummary s = mesh::summarize_motion(b.rest, b.field.unit_displacement, b.scale, b.regions);
  EXPECT_NEAR(s.volume_change_m3, 0.55 * 500e-6, 1e-9);
  EXPECT_GE(of(s, mesh::Region::diaphragmatic).caudal_mean_m, 8e-3);
  EXPECT_GE(s.dome_top_caudal_m, 15e-3);
  EXPECT_LE(s.dome_top_caudal_m, 21e-3);
  EXPECT_LE(of(s, mesh::Region::apex).magnitude_mean_m, 3e-3);
  EXPECT_LE(of(s, mesh::Region::mediastinal).magnitude_mean_m, 1e-3);
  EXPECT_GE(of(s, mesh::Region::diaphragmatic).volume_share, 0.60);
}

// healthy-upright-ct, the former CT preset, is now a name for healthy-upright: the same tissue.
TEST(Realism, TheFormerCtPresetIsHealthyUpright) {
  const Tissue ct = load_tissue(tissue_file("healthy-upright-ct", default_config_dir()));
  const Tissue upright = load_tissue(tissue_file("healthy-upright", default_config_dir()));
  EXPECT_EQ(ct.name, "healthy-upright");
  EXPECT_EQ(ct.regional_load, upright.regional_load);
  EXPECT_DOUBLE_EQ(ct.dome_load.area_m2, 150e-4);
  EXPECT_EQ(ct.dome_load.area_m2, upright.dome_load.area_m2);
  EXPECT_EQ(ct.dome_load.rim, upright.dome_load.rim);
  EXPECT_EQ(ct.dome_load.falloff_m, upright.dome_load.falloff_m);
}

TEST(Realism, SupineShiftsTheDiaphragmsMotionPosteriorly) {
  auto posterior_share = [](const Breath& b) {
    // The diaphragm's caudal motion behind its mid-coronal plane over the whole diaphragm's.
    double mid = 0.0, n = 0.0, back = 0.0, all = 0.0;
    for (std::size_t i = 0; i < b.rest.vertices.size(); ++i) {
      if (b.regions.label[i] != mesh::Region::diaphragmatic) continue;
      mid += b.rest.vertices[i].y();
      n += 1.0;
    }
    mid /= n;
    for (std::size_t i = 0; i < b.rest.vertices.size(); ++i) {
      if (b.regions.label[i] != mesh::Region::diaphragmatic) continue;
      const double caudal = -b.scale * b.field.unit_displacement[i].z();
      all += caudal;
      if (b.rest.vertices[i].y() > mid) back += caudal;  // LPS: +y is posterior
    }
    return back / all;
  };
  const double upright = posterior_share(breathe(mesh::Lung::right, "healthy-upright", 275e-6, 6e-3));
  const double supine = posterior_share(breathe(mesh::Lung::right, "healthy-supine", 275e-6, 6e-3));
  EXPECT_GT(supine, upright + 0.05);
}

TEST(Realism, DeepBreathDoesNotFoldTheSurface) {
  // 1.5 L above FRC, each lung its share; the check the runner makes at its largest frame.
  for (auto [lung, share] : {std::pair{mesh::Lung::right, 0.55}, std::pair{mesh::Lung::left, 0.45}}) {
    const Breath b = breathe(lung, "healthy-upright", share * 1.5e-3);
    mesh::TriangleMesh deformed = b.rest;
    for (std::size_t i = 0; i < deformed.vertices.size(); ++i)
      deformed.vertices[i] += b.scale * b.field.unit_displacement[i];
    EXPECT_FALSE(mesh::self_intersects(deformed));
  }
}

TEST(Realism, DirectionEntersTheCacheKey) {
  mesh::PhantomOptions p;
  p.edge_length_m = 8e-3;
  p.lung = mesh::Lung::right;
  const mesh::TriangleMesh m = mesh::make_lung_phantom(p);
  const std::vector<double> mu(m.vertices.size(), 1e3);
  FieldOptions a, b;
  b.direction = DirectionKind::smoothed_normal;
  EXPECT_NE(field_key(m, mu, "t", a), field_key(m, mu, "t", b));
  FieldOptions c = b;
  c.direction_smoothing = 0.03;
  EXPECT_NE(field_key(m, mu, "t", b), field_key(m, mu, "t", c));
  FieldOptions d = a;
  d.load.assign(m.vertices.size(), 2.0);
  EXPECT_NE(field_key(m, mu, "t", a), field_key(m, mu, "t", d));
  FieldOptions e = a;
  e.magnitude_smoothing = 0.003;
  EXPECT_NE(field_key(m, mu, "t", a), field_key(m, mu, "t", e));
}

TEST(Realism, SlidingEntersTheCacheKey) {
  mesh::PhantomOptions p;
  p.edge_length_m = 8e-3;
  const mesh::TriangleMesh m = mesh::make_lung_phantom(p);
  const std::vector<double> mu(m.vertices.size(), 1e3);
  FieldOptions a, b;
  b.sliding.caudal = 1.0;
  EXPECT_NE(field_key(m, mu, "t", a), field_key(m, mu, "t", b));
  FieldOptions c = b;
  c.sliding.exponent = 0.5;
  EXPECT_NE(field_key(m, mu, "t", b), field_key(m, mu, "t", c));
}

TEST(Realism, TheHeartsDescentEntersTheCacheKey) {
  mesh::PhantomOptions p;
  p.edge_length_m = 8e-3;
  const mesh::TriangleMesh m = mesh::make_lung_phantom(p);
  const std::vector<double> mu(m.vertices.size(), 1e3);
  FieldOptions a, b;
  b.heart.descent = 0.6;
  EXPECT_NE(field_key(m, mu, "t", a), field_key(m, mu, "t", b));
  FieldOptions c = b;
  c.heart.top = 0.4;
  EXPECT_NE(field_key(m, mu, "t", b), field_key(m, mu, "t", c));
}

TEST(Realism, TheSlideLiesAcrossTheSmoothedNormalAndFollowsTheDiaphragm) {
  // Oracles: the slide is orthogonal to the smoothed normal (a tangential field), it is the
  // field's own diaphragm descent times mesh::sliding_field, and the whole still adds one area unit.
  mesh::PhantomOptions p;
  p.edge_length_m = 8e-3;
  const mesh::TriangleMesh m = mesh::make_lung_phantom(p);
  const std::vector<double> mu = test::graded_modulus(m, 1e3, 3e3);
  mesh::RegionOptions ro;
  const auto regions = std::make_shared<const mesh::SurfaceRegions>(mesh::find_regions(m, ro));
  FieldOptions plain;
  plain.direction = DirectionKind::anatomical;
  plain.regions = regions;
  FieldOptions sliding = plain;
  sliding.sliding = {.caudal = 1.2, .anterior = 0.5, .mediastinal = 0.0, .exponent = 0.5};
  const std::vector<Eigen::Vector3d> slide = mesh::sliding_field(m, *regions, sliding.sliding, 0.02);
  const std::vector<Eigen::Vector3d> normal = mesh::smoothed_normals(m, 0.02);
  double largest = 0.0;
  for (std::size_t i = 0; i < slide.size(); ++i) {
    EXPECT_NEAR(slide[i].dot(normal[i]), 0.0, 1e-12);
    largest = std::max(largest, slide[i].norm());
  }
  EXPECT_GT(largest, 0.5);
  const ElastostaticField a = compute_field(m, mu, plain), b = compute_field(m, mu, sliding);
  const double descent = mesh::diaphragm_descent(m, *regions, a.unit_displacement);
  EXPECT_GT(descent, 0.0);
  const double k = b.normalisation / a.normalisation;  // the same force, scaled once more
  EXPECT_NEAR(k, 1.0, 0.2);
  for (std::size_t i = 0; i < slide.size(); ++i)
    EXPECT_LT((b.unit_displacement[i] - k * (a.unit_displacement[i] + descent * slide[i])).norm(), 1e-12);
  const auto g = mesh::area_gradient(m);
  double rate = 0.0;
  for (std::size_t i = 0; i < g.size(); ++i) rate += g[i].dot(b.unit_displacement[i]);
  EXPECT_NEAR(rate, sliding.area_unit, 1e-12 * sliding.area_unit);
}

TEST(Realism, TheBlurredSlideIsTheCostalShareAveragedInSpaceAndKeptOffTheMediastinum) {
  // Oracle: the same tangential vector per vertex, scaled by B[w_costal] (1 - w_mediastinal)
  // instead of w_costal, with B mesh::blurred_in_space (an independent function).
  mesh::PhantomOptions p;
  p.edge_length_m = 8e-3;
  const mesh::TriangleMesh m = mesh::make_lung_phantom(p);
  const mesh::SurfaceRegions regions = mesh::find_regions(m, mesh::RegionOptions{});
  mesh::Sliding plain{.caudal = 1.2, .anterior = 0.5, .mediastinal = 0.0, .exponent = 0.5};
  mesh::Sliding blurred = plain;
  blurred.blur_m = 0.015;
  const auto a = mesh::sliding_field(m, regions, plain, 0.02), b = mesh::sliding_field(m, regions, blurred, 0.02);
  std::vector<double> costal(m.vertices.size());
  for (std::size_t i = 0; i < costal.size(); ++i) costal[i] = regions.weight[i][1];
  const std::vector<double> averaged = mesh::blurred_in_space(m, costal, 0.015);
  std::size_t moved_by_blur = 0;
  for (std::size_t i = 0; i < costal.size(); ++i) {
    const double share = averaged[i] * (1.0 - regions.weight[i][3]);
    EXPECT_LT((b[i] * costal[i] - a[i] * share).norm(), 1e-12) << "vertex " << i;
    if (regions.weight[i][3] == 1.0) {
      EXPECT_EQ(b[i].norm(), 0.0) << "vertex " << i;
    }
    moved_by_blur += std::abs(share - costal[i]) > 0.05;
  }
  EXPECT_GT(moved_by_blur, 10u);  // the blur changes the share somewhere
}

TEST(Realism, MagnitudeSmoothingBlursTheForceAndKeepsOneAreaUnit) {
  // The force with smoothing is the blur of the force without (mesh::blurred_in_space, an
  // independent function), and the field still adds one area unit.
  mesh::PhantomOptions p;
  p.edge_length_m = 8e-3;
  const mesh::TriangleMesh m = mesh::make_lung_phantom(p);
  const std::vector<double> mu = test::graded_modulus(m, 1e3, 3e3);
  FieldOptions plain;
  plain.direction = DirectionKind::anatomical;
  FieldOptions smooth = plain;
  smooth.magnitude_smoothing = 0.01;
  const ElastostaticField a = compute_field(m, mu, plain), b = compute_field(m, mu, smooth);
  const std::vector<double> oracle = mesh::blurred_in_space(m, a.force, 0.01);
  EXPECT_LT(test::max_abs_difference(b.force, oracle, oracle.size()),
            1e-12 * *std::max_element(oracle.begin(), oracle.end()));
  EXPECT_GT(test::max_abs_difference(b.force, a.force, a.force.size()),
            0.01 * *std::max_element(a.force.begin(), a.force.end()));
  const auto g = mesh::area_gradient(m);
  double rate = 0.0;
  for (std::size_t i = 0; i < g.size(); ++i) rate += g[i].dot(b.unit_displacement[i]);
  EXPECT_NEAR(rate, smooth.area_unit, 1e-12 * smooth.area_unit);
  smooth.magnitude_smoothing = -1.0;
  EXPECT_THROW(compute_field(m, mu, smooth), ValueError);
}

TEST(Realism, FieldAlongGivenDirectionsIsNormalisedToOneAreaUnit) {
  mesh::PhantomOptions p;
  p.edge_length_m = 8e-3;
  p.lung = mesh::Lung::left;
  const mesh::TriangleMesh m = mesh::make_lung_phantom(p);
  const std::vector<double> mu(m.vertices.size(), 1e3);
  for (DirectionKind kind : {DirectionKind::vertex_normal, DirectionKind::smoothed_normal, DirectionKind::anatomical}) {
    FieldOptions o;
    o.direction = kind;
    const ElastostaticField f = compute_field(m, mu, o);
    const auto g = mesh::area_gradient(m);
    double rate = 0.0;
    for (std::size_t i = 0; i < g.size(); ++i) rate += g[i].dot(f.unit_displacement[i]);
    EXPECT_NEAR(rate, o.area_unit, 1e-12 * o.area_unit) << direction_name(kind);
  }
}

// The six real CT lungs (../shared/data/ct-lobes, both lungs) with the one shipped upright preset
// (healthy-upright, which also moves the phantom: its dome profile is sized by each lung's own
// diaphragm) at 4 and 2 mm edges: a 1.5 L breath above FRC (each lung its share: 55 % right,
// 45 % left) animates without self-intersection (CGAL, as the runner checks its largest frame),
// and quiet breathing (500 mL) meets the human figures of docs/realism.md: diaphragm mean caudal
// >= 8 mm and 60-78 % of the volume change, apex <= 3 mm, mediastinum <= 1 mm, and the dome top
// within one standard deviation of the mean of either sex (Boussuges et al. 2009, quiet
// breathing: men 18 +/- 3 mm, women 16 +/- 3 mm, so 13-21 mm).
class CtLungRealism : public ::testing::TestWithParam<const char*> {};

TEST_P(CtLungRealism, DeepBreathDoesNotFoldAndQuietBreathIsHuman) {
  const auto file = test::ct_lobes_dir() / (std::string(GetParam()) + "_lobes.nii.gz");
  if (!std::filesystem::exists(file)) {
    GTEST_SKIP() << "no CT lobe maps at " << file.parent_path()
                 << " (set PNEUMA_CT_LOBES to the folder of case00N_lobes.nii.gz)";
  }
  const image::LabelMap map = image::read_label_map(file);
  const std::vector<std::pair<std::string, Tissue>> presets{
      {"healthy-upright", load_tissue(tissue_file("healthy-upright", default_config_dir()))}};
  for (const auto& [labels, share] :
       {std::pair{std::vector<int>{3, 4, 5}, 0.55}, std::pair{std::vector<int>{1, 2}, 0.45}}) {
    for (double edge : {4e-3, 2e-3}) {
      // As a run makes it: meshed at extraction_edge_m(edge) (4 mm at a 4 mm edge), remeshed to edge.
      const mesh::TriangleMesh extracted =
          mesh::surface_from_labels(map, file.string(), labels, {.edge_length_m = mesh::extraction_edge_m(edge)}).mesh;
      const mesh::TriangleMesh rest =
          mesh::remesh_isotropic(extracted, {.target_edge_length_m = edge, .measure_deviation = false}).mesh;
      for (const auto& [preset, tissue] : presets) {
        const std::string what = std::string(GetParam()) + (share > 0.5 ? " right" : " left") + " at " +
                                 std::to_string(edge * 1e3) + " mm, " + preset;
        SCOPED_TRACE(what);
        const model::FieldRecord field = model::compute_field_record(rest, tissue, default_field_options);
        mesh::RegionOptions o;
        o.axes = body_axes(tissue);
        const mesh::SurfaceRegions regions = mesh::find_regions(rest, o);
        const VolumeScaleMap map_v(rest.vertices, field.unit_displacement, rest.triangles);
        mesh::TriangleMesh deep = rest;
        const double deep_scale = map_v.scale_for(map_v.volume(0.0) + share * 1.5e-3);
        for (std::size_t i = 0; i < deep.vertices.size(); ++i)
          deep.vertices[i] += deep_scale * field.unit_displacement[i];
        EXPECT_FALSE(mesh::self_intersects(deep));
        const double quiet_scale = map_v.scale_for(map_v.volume(0.0) + share * 500e-6);
        const mesh::MotionSummary s = mesh::summarize_motion(rest, field.unit_displacement, quiet_scale, regions);
        expect_human_quiet_breath(s);
        std::cout << what << ": diaphragm " << of(s, mesh::Region::diaphragmatic).caudal_mean_m * 1e3 << " mm ("
                  << of(s, mesh::Region::diaphragmatic).volume_share * 100 << " %), dome top "
                  << s.dome_top_caudal_m * 1e3 << " mm, apex " << of(s, mesh::Region::apex).magnitude_mean_m * 1e3
                  << " mm, mediastinum " << of(s, mesh::Region::mediastinal).magnitude_mean_m * 1e3 << " mm\n";
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(RealAnatomy, CtLungRealism,
                         ::testing::Values("case004", "case005", "case006", "case007", "case008", "case009"));

// The same lungs at 1 mm edges (120k-180k vertices a lung), where the tissue's inputs are read
// through the surface's proxy (mesh/geometry/surface_proxy.h, #50): the same human figures, and
// beside them the field read from every vertex (its proxy the mesh itself), the largest
// difference of the unit field and whether a 1.5 L breath folds each. Minutes a lung (Mesh_3
// at 1 mm): run only with PNEUMA_REALISM_1MM set (BENCHMARKS.md, #50).
class CtLungRealismAt1mm : public ::testing::TestWithParam<const char*> {};

TEST_P(CtLungRealismAt1mm, QuietBreathThroughTheProxyIsHuman) {
  const auto file = test::ct_lobes_dir() / (std::string(GetParam()) + "_lobes.nii.gz");
  if (!std::getenv("PNEUMA_REALISM_1MM")) GTEST_SKIP() << "set PNEUMA_REALISM_1MM to run (minutes a lung)";
  if (!std::filesystem::exists(file)) GTEST_SKIP() << "no CT lobe maps at " << file.parent_path();
  const image::LabelMap map = image::read_label_map(file);
  const Tissue tissue = load_tissue(tissue_file("healthy-upright", default_config_dir()));
  for (const auto& [labels, share] :
       {std::pair{std::vector<int>{3, 4, 5}, 0.55}, std::pair{std::vector<int>{1, 2}, 0.45}}) {
    constexpr double kEdge = 1e-3;
    const mesh::TriangleMesh extracted =
        mesh::surface_from_labels(map, file.string(), labels, {.edge_length_m = mesh::extraction_edge_m(kEdge)}).mesh;
    const mesh::TriangleMesh rest =
        mesh::remesh_isotropic(extracted, {.target_edge_length_m = kEdge, .measure_deviation = false}).mesh;
    const std::string what = std::string(GetParam()) + (share > 0.5 ? " right" : " left") + " at 1 mm";
    SCOPED_TRACE(what);
    ASSERT_LT(mesh::mean_edge_length(rest), mesh::kProxyBelowEdgeM);
    const TissueFieldInputs inputs = tissue_field_inputs(rest, tissue);
    ASSERT_TRUE(inputs.options.proxy);
    // Read from every vertex: the regions, load and moduli of the mesh itself, its proxy itself.
    TissueFieldInputs every = inputs;
    mesh::RegionOptions o;
    o.axes = body_axes(tissue);
    every.options.regions = std::make_shared<const mesh::SurfaceRegions>(mesh::find_regions(rest, o));
    every.options.load = mesh::regional_load(rest, *every.options.regions, *tissue.regional_load, tissue.dome_load);
    const std::vector<double> factor = load_gravity_factor(tissue, rest);
    for (std::size_t i = 0; i < factor.size(); ++i) every.options.load[i] *= factor[i];
    every.shear_modulus_pa = shear_modulus_per_vertex(tissue, rest, every.options.regions.get());
    auto itself = std::make_shared<mesh::SurfaceProxy>();
    itself->mesh = rest;
    itself->fine_vertex.resize(rest.vertices.size());
    for (std::size_t i = 0; i < rest.vertices.size(); ++i) itself->fine_vertex[i] = static_cast<std::uint32_t>(i);
    itself->group = itself->fine_vertex;
    itself->cell_m = 1e-9;
    every.options.proxy = itself;
    const mesh::SurfaceRegions regions = mesh::find_regions(rest, o);
    double worst = 0.0, largest = 0.0;
    std::vector<std::vector<Eigen::Vector3d>> fields;
    fields.push_back(compute_field(rest, every).unit_displacement);
    fields.push_back(compute_field(rest, inputs).unit_displacement);
    for (std::size_t i = 0; i < rest.vertices.size(); ++i) {
      worst = std::max(worst, (fields[1][i] - fields[0][i]).norm());
      largest = std::max(largest, fields[0][i].norm());
    }
    std::cout << what << " (" << rest.vertices.size() << " vertices, proxy "
              << inputs.options.proxy->mesh.vertices.size() << "): largest |u - u_every| / max |u_every| "
              << worst / largest << "\n";
    for (std::size_t k = 0; k < 2; ++k) {
      const std::vector<Eigen::Vector3d>& u = fields[k];
      const VolumeScaleMap map_v(rest.vertices, u, rest.triangles);
      const double quiet_scale = map_v.scale_for(map_v.volume(0.0) + share * 500e-6);
      const mesh::MotionSummary s = mesh::summarize_motion(rest, u, quiet_scale, regions);
      std::cout << "  " << (k == 0 ? "every vertex" : "proxy       ") << ": diaphragm "
                << of(s, mesh::Region::diaphragmatic).caudal_mean_m * 1e3 << " mm ("
                << of(s, mesh::Region::diaphragmatic).volume_share * 100 << " %), dome top "
                << s.dome_top_caudal_m * 1e3 << " mm, apex " << of(s, mesh::Region::apex).magnitude_mean_m * 1e3
                << " mm, mediastinum " << of(s, mesh::Region::mediastinal).magnitude_mean_m * 1e3 << " mm\n";
      mesh::TriangleMesh deep = rest;
      const double deep_scale = map_v.scale_for(map_v.volume(0.0) + share * 1.5e-3);
      for (std::size_t i = 0; i < deep.vertices.size(); ++i) deep.vertices[i] += deep_scale * u[i];
      // Reported, not checked: at 1 mm a 1.5 L breath folds 9 of the 12 lungs read from every
      // vertex and 6 read through the proxy (BENCHMARKS.md, #50); the 2 and 4 mm lungs are checked.
      std::cout << "    a 1.5 L breath " << (mesh::self_intersects(deep) ? "folds" : "does not fold") << "\n";
      if (k == 0) continue;
      expect_human_quiet_breath(s);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(RealAnatomy, CtLungRealismAt1mm,
                         ::testing::Values("case004", "case005", "case006", "case007", "case008", "case009"));

}  // namespace
}  // namespace pneuma::field
