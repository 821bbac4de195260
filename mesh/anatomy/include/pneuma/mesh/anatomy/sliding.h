#pragma once
// The lung slides along the chest wall (docs/realism.md, 7.): as the diaphragm descends, the
// costal surface (and, by a share, the mediastinal one) slides caudally along the parietal
// pleura, the more the lower it lies; lying supine, it also slides forward as the anterior chest
// wall rises. A tangential field: it moves the surface within itself, so it changes neither the
// shape nor, to first order, the volume, but the inside of the lung, which follows the whole
// surface, moves as 4D-CT shows.
#include <Eigen/Core>
#include <vector>

#include "pneuma/mesh/anatomy/regions.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh {

// Amplitudes relative to the lung's own diaphragm (its area-weighted mean caudal displacement),
// so they follow whatever load drives the diaphragm. All 0: no sliding.
struct Sliding {
  double caudal = 0.0;       // caudal slide at the base (height 0), falling linearly to 0 at the apex
  double anterior = 0.0;     // anterior slide at the most anterior vertex, 0 at the most posterior
  double mediastinal = 0.0;  // the mediastinal surface's factor on both (the costal one's is 1)
  // The costal share blurred in space at this sigma (0: not blurred), so that surfaces close in
  // space slide alike however far apart along the surface: the diaphragm's rim beside the costal
  // recess, both faces of a thin margin. Kept off the mediastinal face (it would move > 1 mm).
  double blur_m = 0.0;
  double exponent = 1.0;  // the caudal profile (1 - h)^exponent: 1 linear, < 1 fuller at mid-height
  double base = 0.0;      // the slide fades in over this lowest fraction of the height (0: none)
  bool active() const { return caudal != 0.0 || anterior != 0.0; }
};

// Per vertex: the slide per unit of diaphragm descent,
//   f(h) (caudal (1 - h)^exponent P(-up) + anterior a P(anterior)) share,
//   share = w_costal + mediastinal w_mediastinal                              (blur 0)
//   share = B[w_costal] (1 - w_mediastinal) + mediastinal w_mediastinal       (blur > 0),
// B the Gaussian average in space at sigma `blur` (mesh::blurred_in_space), f a smooth step from 0 at the base to 1 at
// height `base` (1 everywhere when base is 0), with h the height (0 at the base, 1 at the apex), a the anterior
// position (0 at the most posterior vertex, 1 at the most anterior), w the region weights and P(v) = v - (v.N) N the
// part of v across the normal N smoothed in space at `sigma` (mesh::smoothed_normals). P is not
// renormalised: it fades where N turns toward v (the apex's cap, the diaphragm), and every factor
// is a smooth function of position, so the field is smooth in space and cannot fold the surface.
// Throws ValueError for negative amplitudes, or regions of another surface.
std::vector<Eigen::Vector3d> sliding_field(const TriangleMesh& mesh, const SurfaceRegions& regions,
                                           const Sliding& sliding, double sigma);
// The same with N given: `smoothed_normal` = smoothed_normals(mesh, sigma), computed once by a
// caller whose other rules use it too (field::compute_field); not read when nothing slides, else
// one per vertex (ValueError).
std::vector<Eigen::Vector3d> sliding_field(const TriangleMesh& mesh, const SurfaceRegions& regions,
                                           const Sliding& sliding, const std::vector<Eigen::Vector3d>& smoothed_normal);

// The diaphragm's area-weighted mean descent (along -up) of a per-vertex displacement, weighted
// by the diaphragmatic region weight; 0 when the surface has no diaphragm.
double diaphragm_descent(const TriangleMesh& mesh, const SurfaceRegions& regions,
                         const std::vector<Eigen::Vector3d>& displacement);

}  // namespace pneuma::mesh
