// CGAL-backed queries against independent oracles.
#include "pneuma/mesh/geometry/surface_queries.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "pneuma/mesh/geometry/surface_hits.h"

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

namespace {

// The nearest crossing of every face but those around vertex i, found by trying them all
// (Moller-Trumbore in doubles): the oracle of first_hits_from_vertices.
struct BruteHit {
  bool found = false;
  double distance = 0.0;
  std::size_t face = 0;
};
BruteHit nearest_crossing(const TriangleMesh& mesh, std::size_t i, const Eigen::Vector3d& d, double reach) {
  const Eigen::Vector3d& o = mesh.vertices[i];
  double best = std::numeric_limits<double>::infinity();
  std::size_t best_face = 0;
  for (std::size_t f = 0; f < mesh.triangle_count(); ++f) {
    const auto& t = mesh.triangles[f];
    if (t[0] == i || t[1] == i || t[2] == i) continue;
    const Eigen::Vector3d a = mesh.vertices[t[0]], e1 = mesh.vertices[t[1]] - a, e2 = mesh.vertices[t[2]] - a;
    const Eigen::Vector3d p = d.cross(e2);
    const double det = e1.dot(p);
    if (std::abs(det) < 1e-300) continue;
    const Eigen::Vector3d s = o - a, q = s.cross(e1);
    const double u = s.dot(p) / det, v = d.dot(q) / det, along = e2.dot(q) / det;
    if (u < 0.0 || v < 0.0 || u + v > 1.0 || along <= 0.0) continue;
    if (along < best) {
      best = along;
      best_face = f;
    }
  }
  if (!std::isfinite(best) || best * d.norm() > reach) return {};
  const auto& t = mesh.triangles[best_face];
  const Eigen::Vector3d area_normal =
      (mesh.vertices[t[1]] - mesh.vertices[t[0]]).cross(mesh.vertices[t[2]] - mesh.vertices[t[0]]);
  if (!(area_normal.dot(d) > 0.0)) return {};  // entering: the ray started outside
  return {true, best * d.norm(), best_face};
}

// A closed, lumpy surface with thin and thick parts: a sphere squashed along z and dented.
TriangleMesh lumpy_lens() {
  TriangleMesh m = make_icosphere(0.05, 3);
  for (Eigen::Vector3d& v : m.vertices) {
    v.z() *= 0.2;
    v.x() *= 1.0 + 0.3 * std::sin(40.0 * v.y());
  }
  return m;
}

}  // namespace

// Inward from every vertex of a lens 20 mm thick at its centre, along its own inward normal and
// tilted: each vertex's hit (found or not, and the distance) is the nearest crossing over every
// face, within the reach, and the same at one thread as at all.
TEST(SurfaceQueries, FirstHitsFromVerticesAreTheNearestCrossingOverEveryFace) {
  const TriangleMesh lens = lumpy_lens();
  const std::vector<Eigen::Vector3d> normal = vertex_normals(lens);
  for (const double tilt : {0.0, 0.4}) {
    std::vector<Eigen::Vector3d> inward(lens.vertex_count());
    for (std::size_t i = 0; i < inward.size(); ++i)
      inward[i] = (-normal[i] + tilt * Eigen::Vector3d(0.3, -0.5, 0.1).cross(normal[i])).normalized();
    for (const double reach : {0.006, 0.015, 0.2}) {
      const std::vector<SurfaceHit> hits = first_hits_from_vertices(lens, inward, reach);
      std::size_t found = 0;
      for (std::size_t i = 0; i < hits.size(); ++i) {
        const BruteHit expected = nearest_crossing(lens, i, inward[i], reach);
        ASSERT_EQ(hits[i].found, expected.found) << i << " tilt " << tilt << " reach " << reach;
        if (!expected.found) continue;
        ++found;
        EXPECT_NEAR(hits[i].distance, expected.distance, 1e-12) << i;
        const auto& t = lens.triangles[hits[i].face];
        Eigen::Vector3d at = Eigen::Vector3d::Zero();
        for (std::size_t k = 0; k < 3; ++k) at += hits[i].weights[k] * lens.vertices[t[k]];
        EXPECT_NEAR((at - lens.vertices[i] - hits[i].distance * inward[i]).norm(), 0.0, 1e-12) << i;
      }
      // The lens is 20 mm thick at most: 15 mm finds some faces across, 200 mm nearly all.
      if (reach > 0.01) {
        EXPECT_GT(found, reach > 0.1 ? hits.size() * 9 / 10 : 0) << reach;
      }
      const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
      const std::vector<SurfaceHit> serial = first_hits_from_vertices(lens, inward, reach);
      for (std::size_t i = 0; i < hits.size(); ++i) {
        EXPECT_EQ(serial[i].found, hits[i].found);
        EXPECT_EQ(serial[i].distance, hits[i].distance);
        EXPECT_EQ(serial[i].face, hits[i].face);
      }
    }
  }
}

// A random closed surface (an icosphere of 2,562 vertices, each moved along its radius by up to
// a fifth, so faces face every way and the surface folds), rays from every vertex in random
// directions (half of them outward): each hit is the nearest crossing over every face, the same
// face and distance, found or not as that scan says, within short and long reaches.
TEST(SurfaceQueries, FirstHitsFromVerticesMatchABruteForceScanOnARandomClosedSurface) {
  TriangleMesh lump = make_icosphere(0.05, 4);
  std::mt19937 random(20261128);
  std::uniform_real_distribution<double> radial(0.8, 1.2), coordinate(-1.0, 1.0);
  for (Eigen::Vector3d& v : lump.vertices) v *= radial(random);
  std::vector<Eigen::Vector3d> direction(lump.vertex_count());
  for (Eigen::Vector3d& d : direction) {
    do d = Eigen::Vector3d(coordinate(random), coordinate(random), coordinate(random));
    while (d.norm() < 0.1 || d.norm() > 1.0);
    d.normalize();
  }
  std::size_t found_before = 0;
  for (const double reach : {0.004, 0.03, 1.0}) {
    const std::vector<SurfaceHit> hits = first_hits_from_vertices(lump, direction, reach);
    std::size_t found = 0;
    for (std::size_t i = 0; i < hits.size(); ++i) {
      const BruteHit expected = nearest_crossing(lump, i, direction[i], reach);
      ASSERT_EQ(hits[i].found, expected.found) << i << " reach " << reach;
      if (!expected.found) continue;
      ++found;
      EXPECT_EQ(hits[i].face, expected.face) << i << " reach " << reach;
      EXPECT_NEAR(hits[i].distance, expected.distance, 1e-12) << i << " reach " << reach;
    }
    // A longer reach finds more; about half the rays point inward, and across the whole
    // surface most of those find a face.
    EXPECT_GT(found, found_before) << reach;
    found_before = found;
    if (reach == 1.0) {
      EXPECT_GT(found, hits.size() / 3);
    }
  }
}
