// Plain Eigen area and volume against analytic shapes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"
#include "pneuma/mesh/geometry/vertex_neighbours.h"

using namespace pneuma::mesh;

TEST(Geometry, IcosphereConvergesToTheSphereAtTheKnownRate) {
  // An inscribed polyhedron: area and volume approach 4 pi r^2 and 4/3 pi r^3 from below, and
  // the error falls by about 4x per subdivision (it is O(h^2)).
  const double r = 0.1;
  double previous_error = 1.0;
  for (int k = 2; k <= 5; ++k) {
    const TriangleMesh s = make_icosphere(r, k);
    EXPECT_EQ(s.triangle_count(), 20u << (2 * k));
    const double area_error = 1.0 - surface_area(s) / (4 * std::numbers::pi * r * r);
    const double volume_error = 1.0 - enclosed_volume(s) / (4.0 / 3.0 * std::numbers::pi * r * r * r);
    EXPECT_GT(area_error, 0.0);
    EXPECT_GT(volume_error, 0.0);
    if (k > 2) {
      EXPECT_NEAR(previous_error / volume_error, 4.0, 0.3) << "k = " << k;
    }
    previous_error = volume_error;
  }
  EXPECT_LT(previous_error, 1e-3);
}

TEST(Geometry, AreaGradientPredictsTheAreaChangeOfANormalDisplacement) {
  // Moving every vertex by eps along its unit normal changes the area by eps * sum(gA . n)
  // and the volume by eps * sum(gV . n) to first order: a finite-difference oracle.
  const TriangleMesh s = make_icosphere(1.0, 3);
  const auto ga = area_gradient(s);
  const auto gv = volume_gradient(s);
  const auto n = vertex_normals(s);
  const double eps = 1e-6;
  TriangleMesh moved = s;
  double area_change = 0.0, volume_change = 0.0;
  for (std::size_t i = 0; i < s.vertices.size(); ++i) {
    moved.vertices[i] += eps * n[i];
    area_change += eps * ga[i].dot(n[i]);
    volume_change += eps * gv[i].dot(n[i]);
  }
  // Second-order terms are O(eps^2 * area) = 1e-11; the first-order change is ~1e-5.
  EXPECT_NEAR(surface_area(moved) - surface_area(s), area_change, 1e-4 * area_change);
  EXPECT_NEAR(enclosed_volume(moved) - enclosed_volume(s), volume_change, 1e-4 * volume_change);
}

TEST(Geometry, VertexNeighboursOfTwoTrianglesAreTheirEdges) {
  // Two faces on the edge (1, 2): by hand, each row ascending.
  const VertexNeighbours around(4, {{0, 1, 2}, {2, 1, 3}});
  const std::vector<std::vector<std::uint32_t>> expected{{1, 2}, {0, 2, 3}, {0, 1, 3}, {1, 2}};
  ASSERT_EQ(around.vertex_count(), 4u);
  for (std::size_t v = 0; v < 4; ++v) {
    const auto row = around(v);
    EXPECT_EQ(std::vector<std::uint32_t>(row.begin(), row.end()), expected[v]) << "vertex " << v;
  }
  EXPECT_THROW(VertexNeighbours(3, {{0, 1, 3}}), pneuma::ValueError);
}

TEST(Geometry, VertexNeighboursAreUniqueEdgesAdjacencyInItsOrder) {
  // The adjacency walked from the sorted unique edges (the umbrella average's order before
  // VertexNeighbours), whatever order the faces come in; every row of a closed icosphere holds
  // 5 (the 12 corners) or 6 vertices and the rows hold each edge twice.
  TriangleMesh sphere = make_icosphere(1.0, 3);
  std::reverse(sphere.triangles.begin(), sphere.triangles.end());
  std::rotate(sphere.triangles[7].begin(), sphere.triangles[7].begin() + 1, sphere.triangles[7].end());
  const auto edges = unique_edges(sphere.triangles);
  std::vector<std::vector<std::uint32_t>> expected(sphere.vertex_count());
  for (const auto& e : edges) {
    expected[e[0]].push_back(e[1]);
    expected[e[1]].push_back(e[0]);
  }
  const VertexNeighbours around(sphere);
  ASSERT_EQ(around.vertex_count(), sphere.vertex_count());
  EXPECT_EQ(around.list().size(), 2 * edges.size());
  std::size_t fives = 0;
  for (std::size_t v = 0; v < sphere.vertex_count(); ++v) {
    const auto row = around(v);
    EXPECT_EQ(std::vector<std::uint32_t>(row.begin(), row.end()), expected[v]) << "vertex " << v;
    EXPECT_TRUE(row.size() == 5 || row.size() == 6) << "vertex " << v;
    fives += row.size() == 5 ? 1 : 0;
  }
  EXPECT_EQ(fives, 12u);
}
