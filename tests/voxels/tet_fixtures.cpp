#include "tet_fixtures.h"

#include <Eigen/Geometry>  // cross(), used by tet_mesh.h's tet_volume6
#include <algorithm>
#include <array>
#include <utility>

namespace pneuma::voxels::test {

mesh::TetMesh cube_cells(const Eigen::Vector3d& origin_m, double h_m, int n,
                         const std::function<bool(const Eigen::Vector3d&)>& keep) {
  mesh::TetMesh m;
  const int p = n + 1;
  for (int k = 0; k < p; ++k)
    for (int j = 0; j < p; ++j)
      for (int i = 0; i < p; ++i) m.nodes.push_back(origin_m + h_m * Eigen::Vector3d(i, j, k));
  const auto node = [&](int i, int j, int k) { return static_cast<std::uint32_t>(i + p * (j + p * k)); };
  const std::array<std::array<int, 3>, 6> orders{{{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}}};
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const Eigen::Vector3d centre = origin_m + h_m * Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5);
        if (keep && !keep(centre)) continue;
        for (const auto& order : orders) {
          std::array<int, 3> at{i, j, k};
          mesh::Tetrahedron tet{};
          tet[0] = node(at[0], at[1], at[2]);
          for (std::size_t s = 0; s < 3; ++s) {
            ++at[static_cast<std::size_t>(order[s])];
            tet[s + 1] = node(at[0], at[1], at[2]);
          }
          if (mesh::tet_volume6(m.nodes[tet[0]], m.nodes[tet[1]], m.nodes[tet[2]], m.nodes[tet[3]]) < 0) {
            std::swap(tet[2], tet[3]);
          }
          m.tets.push_back(tet);
        }
      }
  return m;
}

std::vector<Eigen::Vector3d> affine_field(const mesh::TetMesh& mesh, const Eigen::Matrix3d& a,
                                          const Eigen::Vector3d& b) {
  std::vector<Eigen::Vector3d> u;
  u.reserve(mesh.node_count());
  for (const Eigen::Vector3d& x : mesh.nodes) u.emplace_back(a * x + b);
  return u;
}

Grid oblique_grid(const std::array<std::size_t, 3>& size, const Eigen::Matrix3d& rotation,
                  const Eigen::Vector3d& spacing_m, const Eigen::Vector3d& origin_m) {
  Grid g;
  g.size = size;
  g.ijk_to_lps.block<3, 3>(0, 0) = rotation * spacing_m.asDiagonal();
  g.ijk_to_lps.block<3, 1>(0, 3) = origin_m;
  return g;
}

bool Ball::inside(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d cell = ((p - corner_m()) / cell_m).array().floor();
  if (cell.minCoeff() < 0 || cell.maxCoeff() >= cells) return false;
  return (corner_m() + cell_m * (cell + Eigen::Vector3d::Constant(0.5)) - centre_m).norm() < radius_m;
}

std::vector<Eigen::Vector3d> Ball::radial(double c, const Eigen::Vector3d& shift_m) const {
  std::vector<Eigen::Vector3d> u;
  u.reserve(mesh.node_count());
  for (const Eigen::Vector3d& x : mesh.nodes) u.emplace_back(c * (x - centre_m) + shift_m);
  return u;
}

Ball make_ball() {
  Ball b;
  b.mesh = cube_cells(b.corner_m(), b.cell_m, b.cells,
                      [&](const Eigen::Vector3d& c) { return (c - b.centre_m).norm() < b.radius_m; });
  b.grid = oblique_grid({64, 64, 64}, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Constant(1e-3),
                        b.centre_m - Eigen::Vector3d::Constant(31.5e-3 - 0.3e-3));
  b.labels.size = b.grid.size;
  b.labels.ijk_to_lps = b.grid.ijk_to_lps;
  b.labels.labels.assign(b.grid.voxel_count(), 0);
  b.labels.segments = {{"left", 1}, {"right", 2}, {"above", 7}};
  for (std::size_t k = 0; k < 64; ++k)
    for (std::size_t j = 0; j < 64; ++j)
      for (std::size_t i = 0; i < 64; ++i) {
        const Eigen::Vector3d x = b.grid.centre_m(i, j, k);
        std::int32_t label = 0;
        if (b.inside(x)) label = x.x() < b.centre_m.x() ? 1 : 2;
        if (x.z() > b.centre_m.z() + 26e-3) label = 7;
        b.labels.labels[b.grid.index(i, j, k)] = label;
      }
  return b;
}

}  // namespace pneuma::voxels::test
