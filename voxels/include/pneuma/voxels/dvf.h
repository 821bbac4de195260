#pragma once
// Dense displacement vector fields (DVFs) on a voxel grid, from lungs in motion. Two directions,
// never to be confused (docs/formats.md, "Voxel outputs"):
//
//   forward   u(x): where the tissue at rest point x goes, x -> x + u(x). For landmarks and
//             dose accumulation. Inside a lung's rest tet: the P1 interpolation of s * U.
//   pull-back v(x): out(x) = in(x + v(x)), the convention of ITK, plastimatch and elastix for
//             warping an image. Inside a deformed tet T (nodes moved by s * U) the point x has
//             barycentric coordinates l, and the rest point it came from is p = sum l_i rest_i:
//             v(x) = p - x, the exact inverse of the piecewise-linear forward map.
//
// Both in metres, LPS. A voxel belongs to the tet whose (rest or deformed) closed simplex holds
// its centre, within an inclusive barycentric tolerance (kBarycentricTolerance, so that no
// voxel centre on a shared face falls between two tets); when several do, the first lung in
// the list and in it the lowest tet index wins. Tets are rasterised over their bounding boxes in
// index space, in parallel over slabs of k; the result does not depend on the thread count.
// Voxels outside every lung get `outside(x)` (an empty function: 0), the door for a body field.
#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "pneuma/mesh/geometry/tet_mesh.h"
#include "pneuma/voxels/grid.h"
#include "pneuma/voxels/lung_motion.h"

namespace pneuma::voxels {

// Barycentric coordinates down to -kBarycentricTolerance count as inside.
inline constexpr double kBarycentricTolerance = 1e-10;

// The value at a voxel centre x (LPS metres) outside every lung, in the field's own direction.
// `guess`: from the values just given to the voxels before x in its row, when they are outside
// every lung too, else null: 2 f(i - 1) - f(i - 2) (the line through them: a smooth field's next
// value to second order) when both are, f(i - 1) when only that one is. A starting guess for a
// field found by iteration (the pull-back field's inverse), the same at any thread count (a row is
// filled in order, by one task). Called from several threads at once.
using OutsideField = std::function<Eigen::Vector3d(const Eigen::Vector3d& x_lps_m, const Eigen::Vector3d* guess)>;

struct DisplacementField {
  Grid grid;
  // One per voxel, metres, LPS. float32, what every DVF file holds (computed in double and
  // rounded once): half the memory of double at a CT's own grid (#50: 0.85 GB per field at
  // 512 x 512 x 270), 1e-7 relative, far below a voxel.
  std::vector<Eigen::Vector3f> displacement_m;
  // Per voxel: 0 outside every lung, else 1 + the index of the lung (in the list given) whose
  // tet holds it (rest tets for the forward field, deformed tets for the pull-back).
  std::vector<std::uint8_t> lung;

  std::size_t inside_count() const;
};

// The rest tets rasterised on a grid, kept for the next time point (TimePoint's scratch): every
// time point's forward field and Jacobian image visit the same voxels with the same tets and
// barycentric coordinates (only the lungs' scales differ), so the later ones replay this instead
// of rasterising again (#50). 32 bytes per lung voxel (0.33 GB at case004's own grid).
struct RestRaster {
  struct Entry {
    std::uint32_t voxel = 0, tet = 0;
    Eigen::Vector3d l123 = Eigen::Vector3d::Zero();  // barycentric coordinates 1 to 3 (l0 = 1 - their sum)
  };
  Grid grid;
  std::vector<std::vector<mesh::Tetrahedron>> tets;  // the lungs' rest tets it was made from
  std::vector<std::vector<Eigen::Vector3d>> nodes;
  std::vector<std::uint8_t> owner;        // per voxel, as DisplacementField::lung
  std::vector<std::vector<Entry>> slabs;  // per slab of k (rasterize.h), the lung voxels
  // Whether this was made on `grid` from these lungs' rest tets (compared whole, not by address).
  bool holds(const Grid& grid, std::span<const LungMotion> lungs) const;
};

// Throws ValueError for a lung that check_lung_motion() refuses or more than 255 lungs.
DisplacementField forward_dvf(const Grid& grid, std::span<const LungMotion> lungs, const OutsideField& outside = {});
DisplacementField pullback_dvf(const Grid& grid, std::span<const LungMotion> lungs, const OutsideField& outside = {});
// Per voxel: 0 when no lung's rest mesh holds its centre, else 1 + that lung's index (the rule
// of forward_dvf's `lung`, without the field: a byte per voxel, for warp_labels' `rest_lung`).
std::vector<std::uint8_t> rest_lungs(const Grid& grid, std::span<const LungMotion> lungs);
// The same into `field`, whose buffers are reused when they have the grid's size (no allocation
// and no first touch of fresh pages per time point; the same values as the two above).
// With `rest`: replayed from it when it holds this grid and these lungs, else rasterised and
// kept there (the same values either way).
void forward_dvf(const Grid& grid, std::span<const LungMotion> lungs, DisplacementField& field,
                 const OutsideField& outside = {}, RestRaster* rest = nullptr);
void pullback_dvf(const Grid& grid, std::span<const LungMotion> lungs, DisplacementField& field,
                  const OutsideField& outside = {});

}  // namespace pneuma::voxels
