// mesh/volume: the inside of a closed surface as tetrahedra. Oracles: the enclosed volume of
// the input surface (divergence theorem), the sphere's radii, orientation and determinism.
#include <gtest/gtest.h>

#include <tbb/global_control.h>

#include <cmath>
#include <map>

#include "pneuma/core/error.h"
#include "pneuma/mesh/volume/tetrahedralize.h"

namespace pneuma::mesh {
namespace {

// The tets' total volume; every tet must be positively oriented.
double checked_tets_volume(const TetMesh& mesh) {
  double sum = 0.0;
  std::size_t not_positive = 0;
  for (const auto& t : mesh.tets) {
    const double v = tet_volume6(mesh.nodes[t[0]], mesh.nodes[t[1]], mesh.nodes[t[2]], mesh.nodes[t[3]]) / 6.0;
    not_positive += v > 0.0 ? 0 : 1;
    sum += v;
  }
  EXPECT_EQ(not_positive, 0u);
  return sum;
}

TEST(Tetrahedralize, FillsAnIcosphereWithPositiveTetsWhoseVolumesSumToTheEnclosedVolume) {
  const double radius = 0.05;
  const TriangleMesh sphere = make_icosphere(radius, 4);
  const VolumeMesh volume = tetrahedralize(sphere, {.edge_length_m = 8e-3});
  ASSERT_GT(volume.mesh.tet_count(), 200u);
  const double sum = checked_tets_volume(volume.mesh);
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

// The lattice mesher's tets, as faces: each face of a tet is shared by exactly one other tet
// (inside) or by none (the boundary), and the boundary faces form a closed surface whose enclosed
// volume (divergence theorem) equals the tets' total: no gap, no overlap.
struct FaceCount {
  std::map<std::array<std::uint32_t, 3>, int> count;
  std::vector<Triangle> boundary;
};
FaceCount count_faces(const TetMesh& mesh) {
  FaceCount out;
  std::map<std::array<std::uint32_t, 3>, std::array<std::uint32_t, 3>> oriented;
  for (const auto& t : mesh.tets) {
    // Outward faces of a positively oriented tet.
    const std::array<std::array<std::uint32_t, 3>, 4> faces{
        {{t[1], t[2], t[3]}, {t[0], t[3], t[2]}, {t[0], t[1], t[3]}, {t[0], t[2], t[1]}}};
    for (const auto& f : faces) {
      auto key = f;
      std::sort(key.begin(), key.end());
      ++out.count[key];
      oriented[key] = f;
    }
  }
  for (const auto& [key, n] : out.count) {
    if (n == 1) out.boundary.push_back(oriented[key]);
  }
  return out;
}

TEST(TetrahedralizeLattice, FillsAnIcosphereConformingWithBoundaryNodesOnTheSurface) {
  const double radius = 0.05;
  const TriangleMesh sphere = make_icosphere(radius, 4);
  const VolumeMesh volume = tetrahedralize(sphere, {.mesher = TetMesher::lattice, .edge_length_m = 6e-3});
  ASSERT_GT(volume.mesh.tet_count(), 1000u);
  const double sum = checked_tets_volume(volume.mesh);
  EXPECT_NEAR(sum, volume.volume_m3, 1e-15);
  EXPECT_GT(volume.min_dihedral_deg, 1.0);

  const FaceCount faces = count_faces(volume.mesh);
  for (const auto& [key, n] : faces.count) ASSERT_LE(n, 2) << "a face of three or more tets";
  const TriangleMesh hull{volume.mesh.nodes, faces.boundary};
  EXPECT_NEAR(enclosed_volume(hull) / sum, 1.0, 1e-12);
  // The cut follows the surface: the volume within a chord error of the icosphere's.
  EXPECT_NEAR(sum / enclosed_volume(sphere), 1.0, 0.01);

  // Boundary nodes lie on the icosphere's triangles; every other node is strictly inside, and
  // every node of a boundary face is a boundary node.
  const double inner = radius * std::cos(std::atan(1.0) * 4.0 / 5.0 / 16.0 * 3.0);
  std::vector<char> boundary(volume.mesh.node_count(), 0);
  for (const auto b : volume.boundary_nodes) {
    boundary[b] = 1;
    const double r = volume.mesh.nodes[b].norm();
    EXPECT_LE(r, radius * (1.0 + 1e-9));
    EXPECT_GE(r, inner);
  }
  for (const auto& f : faces.boundary) {
    for (const auto v : f) EXPECT_TRUE(boundary[v]) << "node " << v << " of a boundary face";
  }
  for (std::size_t i = 0; i < volume.mesh.node_count(); ++i) {
    if (!boundary[i]) {
      EXPECT_LT(volume.mesh.nodes[i].norm(), radius * (1.0 - 1e-9));
    }
  }
}

TEST(TetrahedralizeLattice, IsTheSameAtOneAndTwoThreadsAndScalesWithTheEdge) {
  const TriangleMesh sphere = make_icosphere(0.04, 3);
  const auto mesh_at = [&](int threads, double edge_m) {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
    return tetrahedralize(sphere, {.mesher = TetMesher::lattice, .edge_length_m = edge_m});
  };
  const VolumeMesh one = mesh_at(1, 5e-3), two = mesh_at(2, 5e-3);
  ASSERT_EQ(one.mesh.tets, two.mesh.tets);
  ASSERT_EQ(one.mesh.nodes, two.mesh.nodes);
  EXPECT_EQ(one.boundary_nodes, two.boundary_nodes);
  // Halving the edge: about 8x the tets (6 per cube of the lattice inside, plus the cut ones).
  const VolumeMesh fine = mesh_at(2, 2.5e-3);
  const double ratio = static_cast<double>(fine.mesh.tet_count()) / static_cast<double>(one.mesh.tet_count());
  EXPECT_GT(ratio, 6.5);
  EXPECT_LT(ratio, 9.0);
}

TEST(TetrahedralizeLattice, FillsTwoSeparateBallsAndRefusesAnOpenSurface) {
  TriangleMesh two = make_icosphere(0.02, 3);
  TriangleMesh other = make_icosphere(0.015, 3);
  const auto offset = static_cast<std::uint32_t>(two.vertices.size());
  for (auto& v : other.vertices) two.vertices.push_back(v + Eigen::Vector3d(0.05, 0.01, -0.02));
  for (auto t : other.triangles) two.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  const VolumeMesh volume = tetrahedralize(two, {.mesher = TetMesher::lattice, .edge_length_m = 3e-3});
  const double sum = checked_tets_volume(volume.mesh);
  EXPECT_NEAR(sum / enclosed_volume(two), 1.0, 0.02);

  TriangleMesh open = make_icosphere(0.04, 2);
  open.triangles.pop_back();
  EXPECT_THROW(tetrahedralize(open, {.mesher = TetMesher::lattice}), ValueError);
  EXPECT_THROW(tetrahedralize(make_icosphere(0.04, 2), {.mesher = TetMesher::lattice, .edge_length_m = 0.0}),
               ValueError);
  // A lattice of 8e9 nodes is refused before anything is allocated.
  EXPECT_THROW(tetrahedralize(make_icosphere(1.0, 1), {.mesher = TetMesher::lattice, .edge_length_m = 0.5e-3}),
               ValueError);
}

}  // namespace
}  // namespace pneuma::mesh
