// The field of a lung that breathes below its rest shape (docs/voxels.md, "The scan's place on
// the breath"): the inflation's field, smoothed in space just enough that its mirror does not
// pass one face of a thin part of the lung through the other nor stretch the surface between two
// of its points by more than their distance, and that its pull-back parts no two points by more
// than theirs.
#include <array>

#include "pneuma/core/error.h"
#include "pneuma/field/deflation.h"
#include "pneuma/mesh/geometry/surface_queries.h"
#include "pneuma/model/model.h"
#include "pneuma/model/volume_scale.h"

namespace pneuma::model {
namespace {

// s u at the scale whose volume is `depth_m3` below rest's (false when u cannot deflate that far).
bool scaled_to(const VolumeScaleMap& map, const std::vector<Eigen::Vector3d>& u, double depth_m3,
               std::vector<Eigen::Vector3d>& displacement) {
  const double target = map.volume(0.0) - depth_m3;
  if (!map.reachable(target)) return false;
  const double s = map.scale_for(target);
  displacement.resize(u.size());
  for (std::size_t i = 0; i < u.size(); ++i) displacement[i] = s * u[i];
  return true;
}

// True when, at `margin` times `depth_m3` below rest's volume, rest + s u is a surface without
// self-intersection whose displacement s u is a contraction on the surface, and when, at the
// depth itself, s u is a contraction by half (false also when u cannot deflate that far).
//
// The first contraction keeps the inside from tearing where the surface alone does not cross
// itself: s u with a Lipschitz constant below 1 on the surface extends into the lung with the same
// constant (Kirszbraun), so no two of the inside's neighbours need part by more than their
// distance (the upright phantom's lateral base, where the still costal face meets the rising dome
// 10-40 mm away, did: docs/voxels.md).
//
// The second is the pull-back's: a voxel at x of the deflated lung pulls back by
// v(x) = -s u(X), X its rest point, and two points whose rest points are a distance r apart with
// |s u(X) - s u(Y)| <= L r lie at least (1 - L) r apart, so their pull-backs differ by at most
// L / (1 - L) times their distance: no more than it where L <= 1/2. A lung compressed along a line
// to less than half (the wedge under the heart's overhang as the diaphragm rises 10-12 mm under a
// face that rises 1-2 mm: case005's left base at 2 mm voxels, 0.47 across 21-24 mm) has
// neighbours whose pull-backs part by more than their distance.
bool deflates_cleanly(const mesh::TriangleMesh& rest, const std::vector<Eigen::Vector3d>& u, double depth_m3,
                      double margin) {
  const VolumeScaleMap map(rest.vertices, u, rest.triangles);
  std::vector<Eigen::Vector3d> displacement;
  if (!scaled_to(map, u, depth_m3, displacement)) return false;
  for (Eigen::Vector3d& d : displacement) d *= 2.0;  // |s (u_i - u_j)| < |x_i - x_j| / 2
  if (!field::is_contraction(rest.vertices, displacement)) return false;
  if (!scaled_to(map, u, margin * depth_m3, displacement)) return false;
  if (!field::is_contraction(rest.vertices, displacement)) return false;
  mesh::TriangleMesh moved = rest;
  for (std::size_t i = 0; i < moved.vertices.size(); ++i) moved.vertices[i] += displacement[i];
  return !mesh::self_intersects(moved);
}

}  // namespace

DeflationField field_for_deflation(const mesh::TriangleMesh& rest, const std::vector<Eigen::Vector3d>& u,
                                   double depth_m3) {
  // The surface must deflate half as far again without its faces crossing: a wedge that closes
  // only there keeps about a third of its thickness at the depth itself, so the tetrahedra across
  // it do not fold either (on the shared CT lungs a field whose surface only just passes at the
  // depth folds 2-9 tetrahedra of the inside, that untangling does not mend).
  constexpr double kMargin = 1.5;
  if (!(depth_m3 > 0.0) || deflates_cleanly(rest, u, depth_m3, kMargin)) return {u, 0.0};
  // Lengths from half a 4 mm edge to about the thickness of the thinnest wedges of the shared CT
  // lungs' bases; the shortest that works changes the motion least.
  constexpr std::array<double, 6> kSigmas_m{2e-3, 4e-3, 6e-3, 8e-3, 12e-3, 16e-3};
  DeflationField out;
  for (const double sigma : kSigmas_m) {
    out = {field::smooth_field_in_space(rest, u, sigma), sigma, false};
    if (deflates_cleanly(rest, out.unit_displacement, depth_m3, kMargin)) {
      out.passes = true;
      break;
    }
  }
  return out;
}

}  // namespace pneuma::model
