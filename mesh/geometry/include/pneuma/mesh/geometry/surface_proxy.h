#pragma once
// A coarse stand-in for a fine surface, for the realistic tissue's rules that read the surface at
// several millimetres (the thin lung's rays within 20 mm, the smoothed normals; #50). On a mesh of
// 0.3 mm edges those rules cost 3-4 times the field's solve while their results vary over
// millimetres; on the proxy they cost what they cost on a lung of a few thousand vertices.
//
// The proxy is the fine mesh clustered (vertex clustering, Rossignac & Borrel 1993): the fine
// vertices grouped by the cell of a grid of spacing `cell_m` they lie in and by the direction
// their vertex normal faces most (+-x, +-y, +-z), so the two faces of a part thinner than a cell
// stay apart; each group stands as its first vertex in vertex order (a fine vertex: values there
// are read without interpolation), each fine triangle becomes the triangle of its corners' groups,
// dropped where two corners share a group or it repeats an earlier one. Deterministic: the same
// mesh gives the same proxy, in a serial pass over vertex and triangle order.
#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <vector>

#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh {

struct SurfaceProxy {
  TriangleMesh mesh;                       // its vertices are fine vertices, in vertex order
  std::vector<std::uint32_t> fine_vertex;  // per proxy vertex: its index in the fine mesh
  std::vector<std::uint32_t> group;        // per fine vertex: the proxy vertex standing for it
  double cell_m = 0.0;                     // the grid's spacing
};

// The proxy of `mesh` at `cell_m` (above). The grid grows coarser past 2^24 cells. Throws
// ValueError for cell_m <= 0 or an empty mesh.
SurfaceProxy surface_proxy(const TriangleMesh& mesh, double cell_m);

// The mean length of the triangles' edges (each edge once per triangle side); 0 without triangles.
double mean_edge_length(const TriangleMesh& mesh);

// Below this mean edge the realistic tissue reads the surface through a proxy: the rules it
// serves smooth at 3-20 mm, and a lung meshed from a label map at 2-4 mm (every scenario's) keeps
// its own surface, bit for bit. 1.5 mm: the coarsest of those surfaces has mean edges of about
// 1.7 mm at 2 mm; a finer mesh pays for vertices closer than the rules can see.
inline constexpr double kProxyBelowEdgeM = 1.5e-3;
// The proxy's cell: 2 mm, a fifth of the 10 mm below which a thin part gives up all its excess
// stretch (field/thin_lung.h). At 3 mm the thin lung's change, carried back over two cells, was
// blurred at the thinnest edges: the twelve CT lungs at 1 mm read 10-20 % (of the field's
// maximum) from the field read from every vertex, 7-12 % at 2 mm, and case004's right lung at 1 mm
// (85k vertices) self-intersected in 11 places in a 1.5 L breath, 4 read from every vertex, none
// at 2 mm.
inline constexpr double kProxyCellM = 2e-3;
// The proxy of `mesh` at kProxyCellM when its mean edge is below kProxyBelowEdgeM; else null.
std::shared_ptr<const SurfaceProxy> proxy_for(const TriangleMesh& mesh);

// Per fine vertex: the values given per proxy vertex, carried back to the fine surface. Each fine
// vertex averages its group's proxy vertex and that vertex's neighbours along the proxy's edges,
// weighted by a bell of their distance d, (1 - d^2 / (2 cells)^2)^2: along the surface
// only, never across a thin part, and continuous to within the values' change over a cell.
// Throws ValueError for a size other than one value per proxy vertex, or a proxy of another mesh.
std::vector<Eigen::Vector3d> transferred_to_fine(const TriangleMesh& fine, const SurfaceProxy& proxy,
                                                 const std::vector<Eigen::Vector3d>& on_proxy);

}  // namespace pneuma::mesh
