// The recovered gradient and its Jacobian (voxels/jacobian.h: recovered_gradients,
// recovered_jacobian) and the Jacobian image made from it (voxels/density.h). Oracles: analytic
// maps. An affine map's gradient is recovered exactly on any mesh; on a structured (Kuhn) mesh,
// whose node patches are symmetric about each node, a quadratic map's is exact at the nodes inside,
// and a smooth map's recovered Jacobian converges at second order under refinement where the
// per-tet Jacobian converges at first (both measured against det(I + s grad u) of the map itself).
#include <gtest/gtest.h>

#include <Eigen/LU>  // determinant()
#include <algorithm>
#include <cmath>
#include <iostream>
#include <numbers>
#include <random>
#include <vector>

#include "pneuma/voxels/density.h"
#include "pneuma/voxels/dvf.h"
#include "pneuma/voxels/jacobian.h"
#include "tet_fixtures.h"

namespace pneuma::voxels {
namespace {

// A smooth map u(x) on a cube of side kSide: its value and its exact gradient.
constexpr double kSide = 0.04;
struct SmoothMap {
  double amplitude = 0.0015;  // metres: J from 0.57 to 1.54 at s = 1
  double wave = 2.0 * std::numbers::pi / kSide;
  Eigen::Vector3d value(const Eigen::Vector3d& x) const {
    return amplitude * Eigen::Vector3d(std::sin(wave * x.y()) + std::cos(wave * x.x()),
                                       std::sin(wave * (x.z() + x.x())),
                                       std::cos(wave * x.y()) * std::sin(wave * x.z()));
  }
  Eigen::Matrix3d gradient(const Eigen::Vector3d& x) const {
    Eigen::Matrix3d g;
    const double w = wave;
    g << -w * std::sin(w * x.x()), w * std::cos(w * x.y()), 0.0,                    //
        w * std::cos(w * (x.z() + x.x())), 0.0, w * std::cos(w * (x.z() + x.x())),  //
        0.0, -w * std::sin(w * x.y()) * std::sin(w * x.z()), w * std::cos(w * x.y()) * std::cos(w * x.z());
    return amplitude * g;
  }
};

std::vector<Eigen::Vector3d> sampled(const mesh::TetMesh& mesh, const auto& u) {
  std::vector<Eigen::Vector3d> out;
  out.reserve(mesh.node_count());
  for (const Eigen::Vector3d& x : mesh.nodes) out.push_back(u(x));
  return out;
}

Eigen::Vector3d centroid(const mesh::TetMesh& mesh, const mesh::Tetrahedron& tet) {
  return 0.25 * (mesh.nodes[tet[0]] + mesh.nodes[tet[1]] + mesh.nodes[tet[2]] + mesh.nodes[tet[3]]);
}

// Inside the central half of the cube: away from the surface, where the recovery is one-sided.
bool central(const mesh::TetMesh& mesh, const mesh::Tetrahedron& tet) {
  for (const std::uint32_t n : tet)
    if ((mesh.nodes[n].array() < 0.25 * kSide).any() || (mesh.nodes[n].array() > 0.75 * kSide).any()) return false;
  return true;
}

TEST(RecoveredGradient, AnAffineMapIsRecoveredExactlyOnAnIrregularMesh) {
  // The ball's mesh with its nodes moved at random by up to 0.1 of a cell: no two patches alike.
  test::Ball ball = test::make_ball();
  std::mt19937 random(45);
  std::uniform_real_distribution<double> jitter(-0.1 * ball.cell_m, 0.1 * ball.cell_m);
  for (Eigen::Vector3d& x : ball.mesh.nodes) x += Eigen::Vector3d(jitter(random), jitter(random), jitter(random));
  for (const mesh::Tetrahedron& t : ball.mesh.tets)
    ASSERT_GT(
        mesh::tet_volume6(ball.mesh.nodes[t[0]], ball.mesh.nodes[t[1]], ball.mesh.nodes[t[2]], ball.mesh.nodes[t[3]]),
        0.0);
  Eigen::Matrix3d a;
  a << 0.10, 0.02, -0.01, 0.00, 0.05, 0.03, 0.01, -0.02, 0.20;
  const double s = 0.8;
  const std::vector<Eigen::Vector3d> u = test::affine_field(ball.mesh, a, Eigen::Vector3d(0.001, -0.002, 0.003));
  const LungMotion lung{ball.mesh, u, s};
  const std::vector<Eigen::Matrix3d> g = recovered_gradients(lung);
  ASSERT_EQ(g.size(), ball.mesh.node_count());
  std::vector<bool> used(ball.mesh.node_count(), false);
  for (const mesh::Tetrahedron& t : ball.mesh.tets)
    for (const std::uint32_t n : t) used[n] = true;
  for (std::size_t n = 0; n < g.size(); ++n) {
    if (used[n]) {
      EXPECT_LT((g[n] - s * a).norm(), 1e-12) << n;
    } else {
      EXPECT_EQ(g[n], Eigen::Matrix3d::Zero()) << n;  // a node of no tet
    }
  }
  const double expected = (Eigen::Matrix3d::Identity() + s * a).determinant();
  for (std::size_t t = 0; t < ball.mesh.tet_count(); t += 97)
    EXPECT_NEAR(recovered_jacobian(g, ball.mesh.tets[t], Eigen::Vector4d(0.1, 0.2, 0.3, 0.4)), expected, 1e-12) << t;
}

TEST(RecoveredGradient, AQuadraticMapIsExactInsideAStructuredMesh) {
  // u = s (B x + x^T Q x terms): grad u is linear, so the per-tet gradients are off by O(h) and
  // their mean over a node's symmetric patch cancels it; inside, the linear interpolation of exact
  // nodal gradients is exact.
  const mesh::TetMesh cube = test::cube_cells(Eigen::Vector3d::Zero(), kSide / 8, 8);
  const auto u = [](const Eigen::Vector3d& x) {
    return Eigen::Vector3d(0.05 * x.x() + 4.0 * x.y() * x.z(), -3.0 * x.x() * x.x() + 0.02 * x.z(),
                           2.5 * x.y() * x.y() - 1.5 * x.x() * x.z());
  };
  const auto grad = [](const Eigen::Vector3d& x) {
    Eigen::Matrix3d g;
    g << 0.05, 4.0 * x.z(), 4.0 * x.y(),  //
        -6.0 * x.x(), 0.0, 0.02,          //
        -1.5 * x.z(), 5.0 * x.y(), -1.5 * x.x();
    return g;
  };
  const std::vector<Eigen::Vector3d> field = sampled(cube, u);
  const double s = 0.7;
  const std::vector<Eigen::Matrix3d> g = recovered_gradients(LungMotion{cube, field, s});
  const std::vector<double> per_tet = tet_jacobians(LungMotion{cube, field, s});
  std::size_t checked = 0;
  double per_tet_error = 0.0;
  for (std::size_t t = 0; t < cube.tet_count(); ++t) {
    if (!central(cube, cube.tets[t])) continue;
    const Eigen::Vector4d l(0.4, 0.3, 0.2, 0.1);
    Eigen::Vector3d at = Eigen::Vector3d::Zero();
    for (std::size_t c = 0; c < 4; ++c) at += l[static_cast<Eigen::Index>(c)] * cube.nodes[cube.tets[t][c]];
    const double exact = (Eigen::Matrix3d::Identity() + s * grad(at)).determinant();
    EXPECT_NEAR(recovered_jacobian(g, cube.tets[t], l), exact, 1e-12) << t;
    per_tet_error = std::max(per_tet_error, std::abs(per_tet[t] - exact));
    ++checked;
  }
  EXPECT_GT(checked, 300u);
  EXPECT_GT(per_tet_error, 1e-3);  // the per-tet Jacobian is not: the test can tell them apart
}

// The largest error of the recovered and of the per-tet Jacobian at the centroids of the central
// tets, on a cube of n^3 cells.
struct Errors {
  double recovered = 0.0, per_tet = 0.0;
};
Errors smooth_map_errors(int n) {
  const SmoothMap map;
  const mesh::TetMesh cube = test::cube_cells(Eigen::Vector3d::Zero(), kSide / n, n);
  const std::vector<Eigen::Vector3d> field = sampled(cube, [&](const Eigen::Vector3d& x) { return map.value(x); });
  const LungMotion lung{cube, field, 1.0};
  const std::vector<Eigen::Matrix3d> g = recovered_gradients(lung);
  const std::vector<double> per_tet = tet_jacobians(lung);
  Errors e;
  for (std::size_t t = 0; t < cube.tet_count(); ++t) {
    if (!central(cube, cube.tets[t])) continue;
    const double exact = (Eigen::Matrix3d::Identity() + map.gradient(centroid(cube, cube.tets[t]))).determinant();
    e.recovered =
        std::max(e.recovered, std::abs(recovered_jacobian(g, cube.tets[t], Eigen::Vector4d::Constant(0.25)) - exact));
    e.per_tet = std::max(e.per_tet, std::abs(per_tet[t] - exact));
  }
  return e;
}

TEST(RecoveredJacobian, ConvergesAtSecondOrderWhereThePerTetJacobianConvergesAtFirst) {
  const Errors coarse = smooth_map_errors(16), fine = smooth_map_errors(32);
  const double recovered_order = std::log2(coarse.recovered / fine.recovered);
  const double per_tet_order = std::log2(coarse.per_tet / fine.per_tet);
  std::cout << "largest |J error| at 2.5 / 1.25 mm cells: recovered " << coarse.recovered << " / " << fine.recovered
            << " (order " << recovered_order << "), per tet " << coarse.per_tet << " / " << fine.per_tet << " (order "
            << per_tet_order << ")\n";
  EXPECT_GT(recovered_order, 1.8);
  EXPECT_NEAR(per_tet_order, 1.0, 0.25);
  EXPECT_LT(fine.recovered, 0.3 * fine.per_tet);  // 0.26 at 1.25 mm cells
}

// Two lungs side by side, each with its own affine map: each voxel of the Jacobian image shows its
// own lung's determinant, up to the face they share (nothing averaged across the pleura).
TEST(JacobianImage, EachLungIsRecoveredFromItsOwnTetsOnly) {
  const double h = 2.5e-3;
  const mesh::TetMesh right = test::cube_cells(Eigen::Vector3d::Zero(), h, 8);
  const mesh::TetMesh left = test::cube_cells(Eigen::Vector3d(8 * h, 0.0, 0.0), h, 8);
  Eigen::Matrix3d a_right, a_left;
  a_right << 0.10, 0.02, 0.0, 0.0, 0.05, 0.0, 0.0, 0.0, 0.20;
  a_left << -0.10, 0.0, 0.03, 0.0, 0.0, 0.0, 0.01, 0.0, 0.05;
  const std::vector<Eigen::Vector3d> u_right = test::affine_field(right, a_right, Eigen::Vector3d::Zero());
  const std::vector<Eigen::Vector3d> u_left = test::affine_field(left, a_left, Eigen::Vector3d(0.002, 0.0, 0.0));
  const std::vector<LungMotion> lungs{LungMotion{right, u_right, 1.0}, LungMotion{left, u_left, 1.0}};
  // 1 mm voxels over both cubes, shifted 0.3 mm off the cells' faces.
  const Grid grid = test::oblique_grid({40, 20, 20}, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Constant(1e-3),
                                       Eigen::Vector3d::Constant(0.3e-3));
  const DisplacementField forward = forward_dvf(grid, lungs);
  Image image;
  jacobian_image(lungs, forward, image);
  const double j_right = (Eigen::Matrix3d::Identity() + a_right).determinant();
  const double j_left = (Eigen::Matrix3d::Identity() + a_left).determinant();
  std::size_t seen[2] = {0, 0};
  for (std::size_t v = 0; v < grid.voxel_count(); ++v) {
    if (forward.lung[v] == 0) continue;
    const std::size_t lung = forward.lung[v] - 1u;
    EXPECT_NEAR(image.values[v], lung == 0 ? j_right : j_left, 1e-6) << v;
    ++seen[lung];
  }
  EXPECT_EQ(seen[0], 20u * 20u * 20u);
  EXPECT_EQ(seen[1], 20u * 20u * 20u);
}

}  // namespace
}  // namespace pneuma::voxels
