// The fused frame kernel against independent oracles: CGAL's area (AreaMeter), the plain
// per-triangle sums, the exact scaling of a polyhedron, the per-vertex expression; determinism at
// 1, 2 and 4 threads and on both instruction sets.
#include "pneuma/mesh/geometry/deformed_surface.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>
#include <random>

#include "pneuma/core/error.h"
#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/mesh/geometry/surface_queries.h"

using namespace pneuma::mesh;

namespace {

std::vector<Eigen::Vector3d> random_field(std::size_t n, double magnitude, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> d(-magnitude, magnitude);
  std::vector<Eigen::Vector3d> u(n);
  for (auto& v : u) v = Eigen::Vector3d(d(rng), d(rng), d(rng));
  return u;
}

// The same mesh with its vertices renumbered at random (no locality at all: large halos).
TriangleMesh shuffled(const TriangleMesh& mesh, unsigned seed, std::vector<std::uint32_t>& new_index) {
  new_index.resize(mesh.vertex_count());
  std::iota(new_index.begin(), new_index.end(), 0u);
  std::shuffle(new_index.begin(), new_index.end(), std::mt19937(seed));
  TriangleMesh out;
  out.vertices.resize(mesh.vertex_count());
  for (std::size_t i = 0; i < mesh.vertex_count(); ++i) out.vertices[new_index[i]] = mesh.vertices[i];
  for (const auto& t : mesh.triangles) out.triangles.push_back({new_index[t[0]], new_index[t[1]], new_index[t[2]]});
  return out;
}

std::uint64_t bits(double x) {
  std::uint64_t b;
  std::memcpy(&b, &x, sizeof b);
  return b;
}

}  // namespace

TEST(DeformedSurface, PositionsAreTheSameBitsAsRestPlusScaleTimesField) {
  const TriangleMesh sphere = make_icosphere(0.1, 5);  // 10,242 vertices: several chunks
  const auto u = random_field(sphere.vertex_count(), 0.01, 1);
  DeformedSurface surface(sphere.vertices, u, sphere.triangles);
  ASSERT_GT(surface.chunk_count(), 1u);
  std::vector<Eigen::Vector3d> positions;
  for (double s : {0.0, 0.37, -1.25, 3.0}) {
    surface.update(s, positions);
    ASSERT_EQ(positions.size(), sphere.vertex_count());
    for (std::size_t i = 0; i < positions.size(); ++i) {
      const Eigen::Vector3d expected(sphere.vertices[i].x() + s * u[i].x(), sphere.vertices[i].y() + s * u[i].y(),
                                     sphere.vertices[i].z() + s * u[i].z());
      ASSERT_EQ(positions[i], expected) << "vertex " << i << " at s = " << s;
    }
  }
}

TEST(DeformedSurface, AreaMatchesCgalAndVolumeThePlainSum) {
  const TriangleMesh phantom = make_lung_phantom({.lung = kBothLungs, .edge_length_m = 6e-3});
  const auto u = random_field(phantom.vertex_count(), 1e-3, 2);
  DeformedSurface surface(phantom.vertices, u, phantom.triangles);
  AreaMeter cgal(phantom);
  std::vector<Eigen::Vector3d> positions;
  for (double s : {0.0, 0.5, 1.0, -0.8}) {
    const SurfaceMeasures m = surface.update(s, positions);
    const double area = cgal.area(positions);
    EXPECT_NEAR(m.area_m2, area, 1e-13 * area) << s;
    const double volume = enclosed_volume(positions, phantom.triangles);
    EXPECT_NEAR(m.volume_m3, volume, 1e-12 * volume) << s;
    const SurfaceMeasures only = surface.measure(s);
    EXPECT_EQ(bits(only.area_m2), bits(m.area_m2));
    EXPECT_EQ(bits(only.volume_m3), bits(m.volume_m3));
  }
}

TEST(DeformedSurface, VolumeIsTheCubicInScaleAndAreaTheQuadraticForAUniformStretch) {
  // u = c x (the vertex as seen from the centre): rest + s u = (1 + c s) rest, an exact scaling
  // of the polyhedron, so V(s) = (1 + c s)^3 V(0) and A(s) = (1 + c s)^2 A(0).
  const TriangleMesh sphere = make_icosphere(0.08, 6);
  const double c = 0.25;
  std::vector<Eigen::Vector3d> u;
  for (const auto& v : sphere.vertices) u.push_back(c * v);
  const double v0 = enclosed_volume(sphere), a0 = surface_area(sphere);
  DeformedSurface surface(sphere.vertices, u, sphere.triangles);
  for (double s : {0.0, 0.4, 1.0, 2.5, -1.5}) {
    const double k = 1.0 + c * s;
    const SurfaceMeasures m = surface.measure(s);
    EXPECT_NEAR(m.volume_m3, k * k * k * v0, 1e-12 * v0) << s;
    EXPECT_NEAR(m.area_m2, k * k * a0, 1e-12 * a0) << s;
  }
}

TEST(DeformedSurface, AnyVertexNumberingGivesTheSameMeasures) {
  // Randomly numbered vertices put most of a chunk's triangles' vertices in its halo: slower,
  // the same answer (to rounding: the summation order differs).
  const TriangleMesh sphere = make_icosphere(0.1, 5);
  const auto u = random_field(sphere.vertex_count(), 0.01, 3);
  std::vector<std::uint32_t> new_index;
  const TriangleMesh mixed = shuffled(sphere, 4, new_index);
  std::vector<Eigen::Vector3d> mixed_u(u.size());
  for (std::size_t i = 0; i < u.size(); ++i) mixed_u[new_index[i]] = u[i];
  DeformedSurface a(sphere.vertices, u, sphere.triangles), b(mixed.vertices, mixed_u, mixed.triangles);
  std::vector<Eigen::Vector3d> pa, pb;
  const SurfaceMeasures ma = a.update(0.7, pa), mb = b.update(0.7, pb);
  EXPECT_NEAR(ma.area_m2, mb.area_m2, 1e-13 * ma.area_m2);
  EXPECT_NEAR(ma.volume_m3, mb.volume_m3, 1e-12 * ma.volume_m3);
  for (std::size_t i = 0; i < pa.size(); ++i) ASSERT_EQ(pa[i], pb[new_index[i]]);
}

TEST(DeformedSurface, SameBitsAtOneTwoAndFourThreadsAndOnEitherInstructionSet) {
  const TriangleMesh phantom = make_lung_phantom({.lung = kBothLungs, .edge_length_m = 1.2e-3});
  const auto u = random_field(phantom.vertex_count(), 2e-3, 5);
  DeformedSurface surface(phantom.vertices, u, phantom.triangles);
  ASSERT_GT(surface.chunk_count(), 8u);
  std::vector<Eigen::Vector3d> reference_positions, positions;
  SurfaceMeasures reference;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    reference = surface.update(0.6, reference_positions);
  }
  for (int threads : {2, 4}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
    for (int repeat = 0; repeat < 3; ++repeat) {
      const SurfaceMeasures m = surface.update(0.6, positions);
      EXPECT_EQ(bits(m.area_m2), bits(reference.area_m2)) << threads << " threads";
      EXPECT_EQ(bits(m.volume_m3), bits(reference.volume_m3)) << threads << " threads";
      EXPECT_TRUE(positions == reference_positions);
    }
  }
  const std::string best = DeformedSurface::instruction_set();
  DeformedSurface::limit_instruction_set("sse2");
  const SurfaceMeasures baseline = surface.update(0.6, positions);
  DeformedSurface::limit_instruction_set("avx2");
  EXPECT_EQ(DeformedSurface::instruction_set(), best);
  EXPECT_EQ(bits(baseline.area_m2), bits(reference.area_m2));
  EXPECT_EQ(bits(baseline.volume_m3), bits(reference.volume_m3));
  EXPECT_TRUE(positions == reference_positions);
}

TEST(DeformedSurface, SmallAndEmptySurfaces) {
  // One tetrahedron (one chunk, one padded group), and no vertices at all.
  const std::vector<Eigen::Vector3d> rest{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  const std::vector<Triangle> triangles{{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  const std::vector<Eigen::Vector3d> zero(4, Eigen::Vector3d::Zero());
  DeformedSurface tetra(rest, zero, triangles);
  const SurfaceMeasures m = tetra.measure(1.0);
  EXPECT_NEAR(m.volume_m3, 1.0 / 6.0, 1e-15);
  EXPECT_NEAR(m.area_m2, 1.5 + 0.5 * std::sqrt(3.0), 1e-15);
  DeformedSurface empty({}, {}, {});
  std::vector<Eigen::Vector3d> positions;
  const SurfaceMeasures e = empty.update(1.0, positions);
  EXPECT_EQ(e.area_m2, 0.0);
  EXPECT_EQ(e.volume_m3, 0.0);
  EXPECT_TRUE(positions.empty());
}

TEST(DeformedSurface, MismatchedInputIsAnInputError) {
  const std::vector<Eigen::Vector3d> rest{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  EXPECT_THROW(DeformedSurface(rest, std::vector<Eigen::Vector3d>(2), {{0, 1, 2}}), pneuma::InputError);
  EXPECT_THROW(DeformedSurface(rest, std::vector<Eigen::Vector3d>(3), {{0, 1, 3}}), pneuma::InputError);
}

TEST(DeformedSurface, TabulatedMeasuresMatchTheExactSumsAndPositionsKeepTheirBits) {
  // The oracle: the exact per-frame sums (measure()) and rest + s u per vertex; the table must
  // agree with the first within its tolerance everywhere in its range (not only at its nodes).
  const TriangleMesh phantom = make_lung_phantom({.lung = kBothLungs, .edge_length_m = 4e-3});
  std::vector<Eigen::Vector3d> u = vertex_normals(phantom);
  for (auto& v : u) v *= 9e-3;
  DeformedSurface exact(phantom.vertices, u, phantom.triangles);
  DeformedSurface table(phantom.vertices, u, phantom.triangles);
  ASSERT_TRUE(table.tabulate_measures(-0.2, 1.3));
  EXPECT_TRUE(table.tabulated(-0.2) && table.tabulated(1.3) && table.tabulated(0.77));
  EXPECT_FALSE(table.tabulated(1.31));
  std::vector<Eigen::Vector3d> p, q;
  double worst_volume = 0.0, worst_area = 0.0;
  for (double s = -0.2; s <= 1.3; s += 0.0137) {
    const SurfaceMeasures a = exact.update(s, p), b = table.update(s, q);
    worst_volume = std::max(worst_volume, std::abs(a.volume_m3 - b.volume_m3) / a.volume_m3);
    worst_area = std::max(worst_area, std::abs(a.area_m2 - b.area_m2) / a.area_m2);
    for (std::size_t i = 0; i < p.size(); ++i) {
      for (int c = 0; c < 3; ++c) ASSERT_EQ(bits(q[i][c]), bits(phantom.vertices[i][c] + s * u[i][c])) << i;
    }
  }
  EXPECT_LT(worst_volume, 1e-12);
  EXPECT_LT(worst_area, 1e-12);
  EXPECT_GT(worst_area, 0.0);  // it is an interpolant, not the sum (else this test checks nothing)
  // Outside the range: the exact sum, to the bit.
  const SurfaceMeasures outside = table.update(1.5, q), reference = exact.update(1.5, p);
  EXPECT_EQ(bits(outside.area_m2), bits(reference.area_m2));
  // A table made at one thread gives the same bits as one made at two.
  DeformedSurface one(phantom.vertices, u, phantom.triangles);
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    ASSERT_TRUE(one.tabulate_measures(-0.2, 1.3));
  }
  EXPECT_EQ(bits(one.update(0.613, p).area_m2), bits(table.update(0.613, q).area_m2));
}

TEST(DeformedSurface, NoTableWhenATriangleCollapsesInTheRange) {
  // A tetrahedron whose apex comes down onto the edge 0-1 at s = 1: the face (0, 1, 3) has area
  // |1 - s| / 2, a kink there, so the table must refuse a range holding s = 1.
  const std::vector<Eigen::Vector3d> rest = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.5, 0, 1}};
  const std::vector<Eigen::Vector3d> u = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}, {0, 0, -1}};
  const std::vector<Triangle> faces = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {2, 0, 3}};
  DeformedSurface surface(rest, u, faces);
  EXPECT_FALSE(surface.tabulate_measures(0.0, 2.0));
  EXPECT_FALSE(surface.tabulated(0.5));
  EXPECT_TRUE(surface.tabulate_measures(0.0, 0.5));
}
