// mesh/volume: the inside of a closed surface as tetrahedra. Oracles: the enclosed volume of
// the input surface (divergence theorem), the sphere's radii, orientation and determinism.
#include <gtest/gtest.h>

#include <cmath>

#include "pneuma/core/error.h"
#include "pneuma/mesh/volume/tetrahedralize.h"

namespace pneuma::mesh {
namespace {

TEST(Tetrahedralize, FillsAnIcosphereWithPositiveTetsWhoseVolumesSumToTheEnclosedVolume) {
  const double radius = 0.05;
  const TriangleMesh sphere = make_icosphere(radius, 4);
  const VolumeMesh volume = tetrahedralize(sphere, {.edge_length_m = 8e-3});
  ASSERT_GT(volume.mesh.tet_count(), 200u);
  double sum = 0.0;
  for (const auto& t : volume.mesh.tets) {
    const auto& n = volume.mesh.nodes;
    const double v = tet_volume6(n[t[0]], n[t[1]], n[t[2]], n[t[3]]) / 6.0;
    ASSERT_GT(v, 0.0);
    sum += v;
  }
  EXPECT_NEAR(sum, volume.volume_m3, 1e-15);
  // Boundary facets approximate the polyhedron within facet_distance (edge / 10): a chord error
  // of order d * area / volume.
  const double enclosed = enclosed_volume(sphere);
  EXPECT_NEAR(volume.volume_m3 / enclosed, 1.0, 0.02);
  // Boundary nodes lie on the icosphere's triangles: between its inscribed radius and the sphere.
  const double inner = radius * std::cos(std::atan(1.0) * 4.0 / 5.0 / 16.0 * 3.0);  // generous
  ASSERT_FALSE(volume.boundary_nodes.empty());
  for (const auto b : volume.boundary_nodes) {
    const double r = volume.mesh.nodes[b].norm();
    EXPECT_LE(r, radius * (1.0 + 1e-9));
    EXPECT_GE(r, inner);
  }
  // Every other node is strictly inside.
  std::vector<char> boundary(volume.mesh.node_count(), 0);
  for (const auto b : volume.boundary_nodes) boundary[b] = 1;
  for (std::size_t i = 0; i < volume.mesh.node_count(); ++i) {
    if (!boundary[i]) {
      EXPECT_LT(volume.mesh.nodes[i].norm(), radius * (1.0 - 1e-9));
    }
  }
}

TEST(Tetrahedralize, GivesTheSameTetsTwice) {
  const TriangleMesh sphere = make_icosphere(0.04, 3);
  const VolumeMesh a = tetrahedralize(sphere, {.edge_length_m = 8e-3});
  const VolumeMesh b = tetrahedralize(sphere, {.edge_length_m = 8e-3});
  ASSERT_EQ(a.mesh.tets, b.mesh.tets);
  ASSERT_EQ(a.mesh.nodes, b.mesh.nodes);
  EXPECT_EQ(a.boundary_nodes, b.boundary_nodes);
}

TEST(Tetrahedralize, RefusesAnOpenSurfaceAndANonPositiveEdge) {
  TriangleMesh open = make_icosphere(0.04, 2);
  open.triangles.pop_back();
  EXPECT_THROW(tetrahedralize(open), ValueError);
  EXPECT_THROW(tetrahedralize(make_icosphere(0.04, 2), {.edge_length_m = 0.0}), ValueError);
  EXPECT_THROW(tetrahedralize(make_icosphere(0.04, 2), {.edge_length_m = -1e-3}), ValueError);
}

}  // namespace
}  // namespace pneuma::mesh
