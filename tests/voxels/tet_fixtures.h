#pragma once
// Small tet meshes with known geometry for the voxel tests.
#include <Eigen/Core>
#include <functional>
#include <vector>

#include "pneuma/image/label_map.h"
#include "pneuma/mesh/geometry/tet_mesh.h"
#include "pneuma/voxels/grid.h"

namespace pneuma::voxels::test {

// n x n x n cubic cells of edge h_m from `origin_m`, each cut into the 6 Kuhn tets (along the
// main diagonal: conforming across cells), positively oriented; `keep(cell centre)` chooses
// the cells (all by default). Unused nodes are kept (they carry no tet).
mesh::TetMesh cube_cells(const Eigen::Vector3d& origin_m, double h_m, int n,
                         const std::function<bool(const Eigen::Vector3d&)>& keep = {});

// U(x) = A x + b at every node.
std::vector<Eigen::Vector3d> affine_field(const mesh::TetMesh& mesh, const Eigen::Matrix3d& a,
                                          const Eigen::Vector3d& b);

// A grid with axes rotated by `rotation`, spacings `spacing_m`, voxel 0's centre at `origin_m`.
Grid oblique_grid(const std::array<std::size_t, 3>& size, const Eigen::Matrix3d& rotation,
                  const Eigen::Vector3d& spacing_m, const Eigen::Vector3d& origin_m);

// A ball-like lung: the 2.5 mm cells of a 40 mm cube whose centres lie within 19 mm of the
// centre, on a 64^3 grid of 1 mm voxels (shifted 0.3 mm so that no voxel centre lies on a cell
// face), with a label map: 1 inside the mesh left of the centre (x < centre.x), 2 right of it,
// 7 in a slab above the ball (z above centre + 26 mm), 0 elsewhere.
struct Ball {
  Eigen::Vector3d centre_m{0.005, -0.010, 0.020};
  double cell_m = 2.5e-3;
  int cells = 16;
  double radius_m = 19e-3;
  mesh::TetMesh mesh;
  Grid grid;
  image::LabelMap labels;

  Eigen::Vector3d corner_m() const { return centre_m - Eigen::Vector3d::Constant(cell_m * cells / 2); }
  // The oracle for "inside the rest mesh": the cell holding p is one of the mesh's.
  bool inside(const Eigen::Vector3d& p) const;
  // U(x) = c (x - centre) + shift at every node.
  std::vector<Eigen::Vector3d> radial(double c, const Eigen::Vector3d& shift_m = Eigen::Vector3d::Zero()) const;
};
Ball make_ball();

}  // namespace pneuma::voxels::test
