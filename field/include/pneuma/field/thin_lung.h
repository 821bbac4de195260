#pragma once
// A thin part of the lung is not stretched across its thickness more than the lung breathes
// (#45 at 2 mm voxels, docs/voxels.md "The thin lung across the diaphragm"). The surface field
// moves each face of the lung by its own region's rule, and where the lung is thin (a 5-9 mm
// tongue under the diaphragm's slope, the costophrenic margin) its two faces can move apart or
// together by as much as the part is thick: case009's tongue was stretched up to 2x across its
// thickness at a 500 mL breath, though the lung as a whole grows by about a sixth. In life the
// thin part's volume changes like the parenchyma around it: regional ventilation in a healthy
// lung is within a few times the lung's mean (more at the base than at the apex, never a
// doubling of one part while the rest grows by a sixth). So across every thin part the strain
// along the ray between its two faces (their relative displacement along the inward normal over
// the distance between them) is held below (1 + spread) times the lung's mean volume strain;
// beyond it both faces give up the excess in equal shares along the ray, so the part keeps its
// mean motion. Only where the part is thin (up to 10 mm fully, none from 20 mm): a thicker
// part's inside carries its own strain. The change is smoothed along the surface: without that,
// neighbouring vertices stepped apart and every case's surface self-intersected at a 1.5 L
// breath.
#include <Eigen/Core>
#include <vector>

#include "pneuma/mesh/geometry/surface_proxy.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::field {

struct ThinLung {
  double spread = 2.0;  // the strain across a thin part stays below (1 + spread) times the mean
  double thin = 0.01;   // metres: up to this thickness the excess is given up fully (a recess's
                        // thickness, the recess rule's blur: field/heart.h)
  double thick = 0.02;  // metres: from this thickness not at all (a smooth step between)
};

// The lung's mean volume strain under the field u: (sum_i dV/dx_i . u_i) / V, the first-order
// change of the enclosed volume over the volume. Throws ValueError for a surface of no volume
// or one displacement per vertex missing.
double mean_volume_strain(const mesh::TriangleMesh& mesh, const std::vector<Eigen::Vector3d>& u);

// Holds the strain across the surface's thin parts below `high` (per unit of u's scale): from
// each vertex a ray along its inward normal (smoothed in space at 3 mm) finds the face across
// (mesh::first_hits_from_vertices, within `thin.thick`), at distance t; the strain across is
// e = (u_across - u_i) . d / t, u_across interpolated in the face across, d the ray's direction.
// Where e > high, the vertex and the face across are each asked to move by half the excess,
// s(t) (e - high) t / 2, along d toward each other's motion (s 1 up to `thin.thin`, 0 from
// `thin.thick`); each vertex takes the mean of what its rays ask, and that is iterated; the
// change is then averaged over the surface's edges (8 umbrella passes), so that neighbouring
// vertices do not step apart. A thin part that is compressed is left alone (its faces approach:
// no tear). Nothing moves where every ray's strain lies below `high` or where no ray finds a
// face within reach. In place; the caller scales the field back to its unit.
void limit_the_stretch_across_thin_parts(const mesh::TriangleMesh& mesh, std::vector<Eigen::Vector3d>& u, double high,
                                         const ThinLung& thin = {});
// The same with the outward normals smoothed at 3 mm given (mesh::smoothed_normals(mesh,
// kFaceNormalSigma), field/heart.h), computed once for this and the recess rule (compute_field).
void limit_the_stretch_across_thin_parts(const mesh::TriangleMesh& mesh, std::vector<Eigen::Vector3d>& u, double high,
                                         const ThinLung& thin, const std::vector<Eigen::Vector3d>& face_normal);

// The lung's own bound: high = m (1 + spread), m = mean_volume_strain(mesh, u) (nothing where
// m <= 0: a field that does not inflate the lung).
void limit_the_stretch_across_thin_lung(const mesh::TriangleMesh& mesh, std::vector<Eigen::Vector3d>& u,
                                        const ThinLung& thin = {});
void limit_the_stretch_across_thin_lung(const mesh::TriangleMesh& mesh, std::vector<Eigen::Vector3d>& u,
                                        const ThinLung& thin, const std::vector<Eigen::Vector3d>& face_normal);
// The same read through the surface's proxy (mesh::proxy_for, a fine surface's; #50): the rays,
// rounds and smoothing over the proxy's vertices (u and the normals read at the fine vertices they
// are), the change carried back to every vertex (mesh::transferred_to_fine); the bound from the
// fine surface's own mean strain. `face_normal` is the fine surface's.
void limit_the_stretch_across_thin_lung(const mesh::TriangleMesh& mesh, const mesh::SurfaceProxy& proxy,
                                        std::vector<Eigen::Vector3d>& u, const ThinLung& thin,
                                        const std::vector<Eigen::Vector3d>& face_normal);

}  // namespace pneuma::field
