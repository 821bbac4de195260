// CGAL-backed queries against independent oracles.
#include "pneuma/mesh/geometry/surface_queries.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

using namespace pneuma::mesh;

namespace {

// A flat n x n grid of squares (two triangles each) on z = 0 covering [0, 1]^2, facing +z.
TriangleMesh flat_grid(int n) {
  TriangleMesh m;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) m.vertices.emplace_back(double(i) / n, double(j) / n, 0.0);
  auto id = [n](int i, int j) { return static_cast<std::uint32_t>(j * (n + 1) + i); };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      m.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      m.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  return m;
}

}  // namespace

TEST(SurfaceQueries, TransferReproducesALinearFieldAtTheFootOfEachPoint) {
  // Barycentric interpolation is exact for a linear field; a point above the plane takes the
  // value at its orthogonal foot (x, y, 0).
  const TriangleMesh grid = flat_grid(7);
  const Eigen::Matrix3d a{{1.0, 2.0, -1.0}, {0.5, -3.0, 2.0}, {4.0, 0.0, 1.0}};
  std::vector<Eigen::Vector3d> field;
  for (const auto& v : grid.vertices) field.push_back(a * v);
  const std::vector<Eigen::Vector3d> targets{{0.13, 0.71, 0.05}, {0.5, 0.5, -0.2}, {0.99, 0.02, 0.3}, {0.0, 1.0, 0.0}};
  const auto moved = transfer_vertex_field(grid, field, targets);
  for (std::size_t i = 0; i < targets.size(); ++i) {
    const Eigen::Vector3d foot(targets[i].x(), targets[i].y(), 0.0);
    EXPECT_LT((moved[i] - a * foot).norm(), 1e-12) << i;
  }
}

TEST(SurfaceQueries, AreaMeterEqualsThePlainSumAsVerticesMove) {
  const TriangleMesh sphere = make_icosphere(0.1, 3);
  AreaMeter meter(sphere);
  EXPECT_NEAR(meter.area(sphere.vertices), surface_area(sphere), 1e-15);
  std::vector<Eigen::Vector3d> moved = sphere.vertices;
  for (auto& p : moved) p = Eigen::Vector3d(1.5 * p.x(), p.y(), 0.7 * p.z() + 0.01 * p.y());
  EXPECT_NEAR(meter.area(moved), surface_area(moved, sphere.triangles), 1e-14);
}

TEST(SurfaceQueries, SelfIntersectionIsFound) {
  TriangleMesh sphere = make_icosphere(0.1, 2);
  EXPECT_FALSE(self_intersects(sphere));
  sphere.vertices[0] = -1.5 * sphere.vertices[0];  // pushed through to the far side
  EXPECT_TRUE(self_intersects(sphere));
}

TEST(SurfaceQueries, ParallelSelfIntersectionGivesTheSerialAnswer) {
  // Large enough (> 2000 faces) for CGAL to split the boxes into parallel subtrees.
  TriangleMesh sphere = make_icosphere(0.1, 5);
  EXPECT_FALSE(self_intersects(sphere, Concurrency::serial));
  EXPECT_FALSE(self_intersects(sphere, Concurrency::parallel));
  for (std::size_t v : {0u, 5000u, 10000u}) {
    TriangleMesh dented = sphere;
    dented.vertices[v] = -1.5 * dented.vertices[v];  // pushed through the far side
    EXPECT_TRUE(self_intersects(dented, Concurrency::serial)) << v;
    EXPECT_TRUE(self_intersects(dented, Concurrency::parallel)) << v;
  }
  // Pushed outwards: no intersection, however far.
  TriangleMesh bumped = sphere;
  bumped.vertices[77] *= 3.0;
  EXPECT_FALSE(self_intersects(bumped, Concurrency::serial));
  EXPECT_FALSE(self_intersects(bumped, Concurrency::parallel));
}

TEST(SurfaceQueries, ParallelSelfIntersectionFindsIntersectionsBetweenComponentsAndAtSlabBorders) {
  // Two spheres side by side along x (the slabs' axis): apart, touching nothing; then moved so
  // that they overlap, wherever the overlap falls among the slabs.
  const TriangleMesh one = make_icosphere(0.1, 4);
  for (double gap : {0.25, 0.15, 0.05, -0.1}) {
    TriangleMesh two = one;
    const auto offset = static_cast<std::uint32_t>(one.vertex_count());
    for (const auto& v : one.vertices) two.vertices.push_back(v + Eigen::Vector3d(0.2 + gap, 0.01, 0.0));
    for (const auto& t : one.triangles) two.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
    const bool expected = gap < 0.0;
    EXPECT_EQ(self_intersects(two, Concurrency::serial), expected) << gap;
    EXPECT_EQ(self_intersects(two, Concurrency::parallel), expected) << gap;
  }
}

// Two surfaces tested against each other give the answer of the two as one mesh's
// self-intersection test (CGAL's own, over every face: the oracle), for spheres apart, with
// overlapping boxes but apart, crossing, one inside the other (no face meets a face), coincident,
// and touching at one shared point.
TEST(SurfaceQueries, TwoSurfacesIntersectWhenTheirUnionSelfIntersects) {
  const TriangleMesh one = make_icosphere(0.1, 3);
  const auto union_of = [](const TriangleMesh& a, const TriangleMesh& b) {
    TriangleMesh both = a;
    const auto offset = static_cast<std::uint32_t>(a.vertex_count());
    both.vertices.insert(both.vertices.end(), b.vertices.begin(), b.vertices.end());
    for (const auto& t : b.triangles) both.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
    return both;
  };
  const auto moved = [](TriangleMesh m, const Eigen::Vector3d& by, double scale) {
    for (auto& v : m.vertices) v = scale * v + by;
    return m;
  };
  struct Case {
    const char* what;
    TriangleMesh other;
    bool expected;
  };
  // The vertex of `one` farthest along +x, and the same point as another sphere's farthest along -x.
  const Eigen::Vector3d tip = *std::max_element(one.vertices.begin(), one.vertices.end(),
                                                [](const auto& p, const auto& q) { return p.x() < q.x(); });
  const TriangleMesh mirrored = [&] {
    TriangleMesh m = one;
    for (auto& v : m.vertices) v.x() = -v.x();
    return moved(m, 2.0 * tip.x() * Eigen::Vector3d::UnitX(), 1.0);
  }();
  const std::vector<Case> cases{
      {"apart", moved(one, {0.5, 0.0, 0.0}, 1.0), false},
      {"boxes overlap, surfaces apart", moved(one, {0.15, 0.15, 0.15}, 1.0), false},
      {"crossing", moved(one, {0.15, 0.01, 0.0}, 1.0), true},
      {"inside", moved(one, {0.01, 0.0, 0.0}, 0.5), false},
      {"coincident", one, true},
      {"touching at a point", mirrored, true},
  };
  for (const Case& c : cases) {
    EXPECT_EQ(self_intersects(union_of(one, c.other), Concurrency::serial), c.expected) << c.what;
    EXPECT_EQ(surfaces_intersect(one, c.other), c.expected) << c.what;
    EXPECT_EQ(surfaces_intersect(c.other, one), c.expected) << c.what;
  }
}
