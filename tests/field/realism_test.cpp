// The shipped healthy presets on the phantom against the human figures of docs/realism.md, and
// the anatomical direction against folding: a deep breath animates without self-intersection.
#include <gtest/gtest.h>

#include "pneuma/engine/field_cache.h"
#include "pneuma/engine/physiology_config.h"
#include "pneuma/engine/tissue.h"
#include "pneuma/engine/volume_scale.h"
#include "pneuma/mesh/motion_summary.h"
#include "pneuma/mesh/phantom.h"
#include "pneuma/mesh/surface_queries.h"

namespace pneuma::engine {
namespace {

struct Breath {
  mesh::TriangleMesh rest;
  FieldModel field;
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
  b.field = compute_field_model(b.rest, tissue, default_field_options);
  mesh::RegionOptions o;
  o.frame = body_frame(tissue);
  b.regions = mesh::find_regions(b.rest, o);
  const VolumeScaleMap map(b.rest.vertices, b.field.unit_displacement, b.rest.triangles);
  b.scale = map.scale_for(map.volume(0.0) + volume_m3);
  return b;
}

const mesh::RegionMotion& of(const mesh::MotionSummary& s, mesh::Region r) {
  return s.region[static_cast<std::size_t>(r)];
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

}  // namespace
}  // namespace pneuma::engine
