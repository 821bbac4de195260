// The lung phantom: a valid surface, lung-sized, with the predicted number of triangles,
// deterministic, and remeshable without losing volume.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/mesh/geometry/validate.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "pneuma/mesh/repair/remesh.h"
#include "test_support.h"

using namespace pneuma::mesh;
using pneuma::test::run_pneuma;
using pneuma::test::TempDir;

TEST(Phantom, EachLungIsAValidLungSizedSurface) {
  for (Lung lung : {Lung::right, Lung::left}) {
    const TriangleMesh m = make_lung_phantom({.lung = lung, .edge_length_m = 0.008});
    const ValidationReport r = validate(m);  // closed, manifold, oriented, no self-intersection
    EXPECT_TRUE(r.valid()) << r.summary();
    EXPECT_EQ(r.component_count, 1u);
    EXPECT_EQ(r.genus, 0);
    EXPECT_EQ(r.self_intersection_count, 0u);
    EXPECT_GT(r.volume_m3, 1.1e-3);  // near FRC: 1.1 to 1.45 L per lung
    EXPECT_LT(r.volume_m3, 1.45e-3);
    EXPECT_NEAR(cgal_enclosed_volume(m), r.volume_m3, 1e-12);
    const auto box = bounding_box(m.vertices);
    EXPECT_NEAR(box[1].z() - box[0].z(), 0.25, 0.01);  // adult height, apex at the top
    EXPECT_NEAR(box[0].z(), 0.0, 0.003);
    // LPS: the right lung at x < 0, the left at x > 0, either side of a mediastinum.
    const double medial_x = lung == Lung::right ? -box[1].x() : box[0].x();
    EXPECT_GT(medial_x, 0.015);
    // The lowest point is at the back (posterior costophrenic recess, +y).
    const auto lowest = std::min_element(m.vertices.begin(), m.vertices.end(),
                                         [](const auto& a, const auto& b) { return a.z() < b.z(); });
    EXPECT_GT(lowest->y(), 0.0);
  }
}

TEST(Phantom, LeftLungIsSmallerAndBothAreTwoComponents) {
  const double right = enclosed_volume(make_lung_phantom({.lung = Lung::right, .edge_length_m = 0.01}));
  const double left = enclosed_volume(make_lung_phantom({.lung = Lung::left, .edge_length_m = 0.01}));
  EXPECT_LT(left, right);  // the heart takes room on the left
  const TriangleMesh both = make_lung_phantom({.lung = kBothLungs, .edge_length_m = 0.01});
  const ValidationReport r = validate(both);
  EXPECT_TRUE(r.valid()) << r.summary();
  EXPECT_EQ(r.component_count, 2u);
  EXPECT_NEAR(r.volume_m3, left + right, 1e-12);
}

TEST(Phantom, TriangleCountFollowsTheEdgeLength) {
  // Prediction: the generated surface's own area A over the area of an equilateral triangle of
  // edge h, 4 A / (sqrt(3) h^2), per lung. The generator rounds the geodesic frequency, so
  // within 10% once n >= 10.
  for (double h : {0.008, 0.004, 0.002}) {
    for (Lung lung : {Lung::right, Lung::left}) {
      const TriangleMesh m = make_lung_phantom({.lung = lung, .edge_length_m = h});
      const double predicted = 4 * surface_area(m) / (std::sqrt(3.0) * h * h);
      EXPECT_NEAR(static_cast<double>(m.triangle_count()), predicted, 0.1 * predicted) << h;
      const int n = phantom_frequency(lung, h);
      EXPECT_EQ(m.triangle_count(), 20u * static_cast<unsigned>(n * n));
      EXPECT_NEAR(measure_quality(m).mean_edge_m, h, 0.15 * h) << h;
    }
  }
  // Two million triangles are within reach: the prediction at 0.25 mm for one lung.
  EXPECT_GT(predicted_phantom_triangles(Lung::right, 0.00025), 2e6);
}

TEST(Phantom, EveryTriangleFacesAwayFromTheCentre) {
  // The star-shaped construction's invariant at a finer resolution (cheaper than CGAL's
  // self-intersection test and enough for an embedded surface: a triangulated sphere whose
  // triangles all project positively onto the sphere around c is a graph over that sphere).
  for (Lung lung : {Lung::right, Lung::left}) {
    const TriangleMesh m = make_lung_phantom({.lung = lung, .edge_length_m = 0.002});
    const Eigen::Vector3d c = phantom_centre(lung);
    std::size_t negative = 0;
    for (const Triangle& t : m.triangles) {
      const Eigen::Vector3d a = m.vertices[t[0]] - c, b = m.vertices[t[1]] - c, d = m.vertices[t[2]] - c;
      negative += a.dot(b.cross(d)) <= 0.0;
    }
    EXPECT_EQ(negative, 0u);
  }
}

TEST(Phantom, SameParametersSameBytes) {
  TempDir dir;
  for (const char* name : {"a.ply", "b.ply"}) {
    const auto r = run_pneuma({"phantom", "--lung", "left", "--edge", "6mm", "-o", (dir / name).string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  const std::string a = pneuma::test::read_text(dir / "a.ply");
  EXPECT_GT(a.size(), 10000u);
  EXPECT_EQ(a, pneuma::test::read_text(dir / "b.ply"));
  const auto r = run_pneuma({"phantom", "--lung", "left", "--edge", "5mm", "-o", (dir / "c.ply").string()});
  EXPECT_NE(a, pneuma::test::read_text(dir / "c.ply"));
}

TEST(Phantom, RemeshingKeepsVolumeAndReachesTheTargetEdge) {
  const TriangleMesh m = make_lung_phantom({.lung = Lung::right, .edge_length_m = 0.006});
  const double target = 0.005;
  const RemeshResult r = remesh_isotropic(m, {.target_edge_length_m = target});
  const ValidationReport v = validate(r.mesh);
  EXPECT_TRUE(v.valid()) << v.summary();
  EXPECT_NEAR(v.volume_m3, enclosed_volume(m), 0.01 * enclosed_volume(m));
  EXPECT_NEAR(r.after.mean_edge_m, target, 0.2 * target);
  // CGAL splits edges over 4/3 of the target and collapses those under 4/5 of it.
  std::size_t within = 0;
  const auto edges = unique_edges(r.mesh.triangles);
  for (const auto& e : edges) {
    const double len = (r.mesh.vertices[e[0]] - r.mesh.vertices[e[1]]).norm();
    within += std::abs(len - target) <= 0.2 * target;
  }
  EXPECT_GT(static_cast<double>(within), 0.75 * static_cast<double>(edges.size()));
  // Vertices lie on the input; triangle centroids stray by about the input's own sagitta.
  EXPECT_LT(r.max_deviation_m, 0.3 * target);
  EXPECT_GT(r.after.mean_min_angle_deg, r.before.mean_min_angle_deg - 5.0);
}
