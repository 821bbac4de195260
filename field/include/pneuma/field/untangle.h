#pragma once
// Unfolding the interior field (docs/voxels.md, "No folded tetrahedron"): linear elasticity
// with boundary data that change fast (where the diaphragm, which descends, meets the
// mediastinal face, which stands still) can move a node near the boundary past the surface
// patch beside it, so a tetrahedron with two or three nodes on the surface inverts at a deep
// enough breath. The map x -> x + s U folds there although the surface does not.
//
// untangle_interior() moves the free nodes of every tetrahedron whose Jacobian at the scale
// `scale` is below `min_jacobian`, one node at a time, to the deformed position that maximises
// the smallest Jacobian of the tetrahedra around it (Freitag & Plassmann, Int J Numer Meth Eng
// 49:109, 2000: the volume of a tetrahedron is affine in each of its nodes, so this is a linear
// program in four unknowns, solved exactly by visiting the vertices of its feasible set), and
// moves that node's U toward the one that reaches it at `scale`, only as far as the floor needs.
// The Jacobian is cubic in s, so breaths of 1/8, 2/8, ..., 8/8 of `scale` are treated in turn,
// and a move for a deeper one may not lower a lighter one's smallest Jacobian around the node at
// all up to half of `scale` (a quiet breath keeps the elastic field's inside: #45, where the
// moves for 1 L left J = 0.25-0.55 and tears of 3-5 mm inside a 250 mL breath), nor beyond it
// below a floor that falls linearly to `min_jacobian` at `scale` (or below where it was). Nor may
// it raise the largest Jacobian around the node, at its own breath or a lighter one, above 2 up
// to half of `scale` and 1 / the floor beyond (or above where it was): a move that lifts a
// compressed tet must not tear the tets across the node (#45, the phantom at 2 mm voxels).
// `kept`: breaths of the same U outside (0, scale], each with a floor, which a move may not push below
// min(floor, where the star was) either: one U serves the inflation (s > 0) and a breath-hold scan's
// deflation (s < 0), and the moves for one direction must not steepen the other (#45 at 2 mm: the
// moves made for 1 L above rest left a quiet deflation's inside at J = 0.27-0.37 under case004's
// left base; docs/voxels.md, "No folded tetrahedron").
// Sequential sweeps in node order: the same result at any thread count.
// Boundary nodes are never moved (they carry the surface field), so a tetrahedron with all four
// nodes on the surface that folds stays folded, and is counted.
#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "pneuma/mesh/geometry/tet_mesh.h"

namespace pneuma::field {

struct UntangleReport {
  std::size_t tets_below_before = 0, tets_below_after = 0;  // Jacobian < min_jacobian at `scale`
  std::size_t folded_before = 0, folded_after = 0;          // Jacobian <= 0 at `scale`
  double min_jacobian_before = 0.0, min_jacobian_after = 0.0;
  std::size_t folded_all_boundary = 0;  // of folded_after: tets with all four nodes on the boundary
  std::size_t nodes_moved = 0, sweeps = 0;
};

// A breath x + s U whose Jacobians a move may not lower below min(floor, where they were).
struct KeptBreath {
  double scale = 0.0;
  double floor = 1.0;
};

// The breaths untangle_interior() keeps while it unfolds up to `scale` (> 0): 1/8, ..., 8/8 of it,
// the floor 1 up to half of it and falling linearly to `min_jacobian` at the whole; each scale
// times `sign` (-1: the same breaths as seen from the opposite direction's call).
std::vector<KeptBreath> unfolding_breaths(double scale, double min_jacobian = 0.2, double sign = 1.0);

// `displacement` per node (metres per unit of s), changed in place at free nodes only;
// `boundary_nodes` ascending. Throws ValueError for sizes that do not match, a scale that is not
// positive and finite, min_jacobian outside (0, 1), or a kept breath that is not finite.
UntangleReport untangle_interior(const mesh::TetMesh& mesh, std::span<const std::uint32_t> boundary_nodes,
                                 std::vector<Eigen::Vector3d>& displacement, double scale, double min_jacobian = 0.2,
                                 std::size_t max_sweeps = 20, std::span<const KeptBreath> kept = {});

struct DroppedTets {
  std::size_t count = 0;
  double rest_volume_m3 = 0.0;
};

// Leaves out of `mesh` the tetrahedra with all four nodes among `boundary_nodes` (ascending) that
// fold at a breath up to `scale` (the breaths untangle_interior() checks): their motion is the
// surface field's own, which no free node can mend, where the lung is thinner than a
// tetrahedron or the surface bends sharply. Their rest volume is returned; the nodes are kept.
DroppedTets drop_folded_boundary_tets(mesh::TetMesh& mesh, std::span<const std::uint32_t> boundary_nodes,
                                      const std::vector<Eigen::Vector3d>& displacement, double scale);

}  // namespace pneuma::field
