// A lung's inside: tetrahedra of the rest surface (Mesh_3 or the lattice), the surface field carried to their
// boundary nodes, the interior field solved for the rest.
#include <fmt/format.h>

#include <cmath>

#include "pneuma/core/error.h"
#include "pneuma/field/untangle.h"
#include "pneuma/mesh/geometry/surface_queries.h"
#include "pneuma/mesh/volume/tetrahedralize.h"
#include "pneuma/model/model.h"
#include "pneuma/model/volume_scale.h"

namespace pneuma::model {

std::shared_ptr<LungInterior> compute_interior(const mesh::TriangleMesh& rest,
                                               const std::vector<Eigen::Vector3d>& unit_displacement, double edge_m,
                                               const field::InteriorOptions& options, mesh::TetMesher mesher) {
  auto out = std::make_shared<LungInterior>();
  mesh::VolumeMesh volume = mesh::tetrahedralize(rest, {.mesher = mesher, .edge_length_m = edge_m});
  std::vector<Eigen::Vector3d> boundary_points;
  boundary_points.reserve(volume.boundary_nodes.size());
  for (const std::uint32_t b : volume.boundary_nodes) boundary_points.push_back(volume.mesh.nodes[b]);
  const std::vector<Eigen::Vector3d> boundary = mesh::transfer_vertex_field(rest, unit_displacement, boundary_points);
  field::InteriorSolution solution = field::solve_interior(volume.mesh, volume.boundary_nodes, boundary, options);
  const VolumeScaleMap volume_map(rest.vertices, unit_displacement, rest.triangles);
  // Unfold for `scale` (> 0: the inflation; < 0: the deflation, as the field -u at -scale).
  const auto unfold = [&](double scale) {
    if (!(scale != 0.0 && std::isfinite(scale))) return;
    std::vector<Eigen::Vector3d>& d = solution.displacement;
    if (scale < 0.0)
      for (Eigen::Vector3d& v : d) v = -v;
    const field::UntangleReport u = field::untangle_interior(volume.mesh, volume.boundary_nodes, d, std::abs(scale));
    const field::DroppedTets dropped =
        field::drop_folded_boundary_tets(volume.mesh, volume.boundary_nodes, d, std::abs(scale));
    if (scale < 0.0)
      for (Eigen::Vector3d& v : d) v = -v;
    solution.report.unfolded_nodes += u.nodes_moved;
    solution.report.dropped_tets += dropped.count;
    solution.report.dropped_volume_m3 += dropped.rest_volume_m3;
  };
  if (options.unfold_volume_m3 > 0.0) {
    // The breath of unfold_volume_m3 above rest, or the deepest this field reaches.
    const double target = volume_map.volume(0.0) + options.unfold_volume_m3;
    unfold(target < volume_map.max_volume() ? volume_map.scale_for(target) : volume_map.max_scale());
  }
  if (options.unfold_deflation_m3 > 0.0) {
    // Last: the deepest deflation the run asks for (a breath-hold scan's end-expiration).
    const double target = volume_map.volume(0.0) - options.unfold_deflation_m3;
    unfold(target > volume_map.min_volume() ? volume_map.scale_for(target) : volume_map.min_scale());
  }
  out->mesh = std::move(volume.mesh);
  out->boundary_nodes = std::move(volume.boundary_nodes);
  out->unit_displacement = std::move(solution.displacement);
  out->edge_m = edge_m;
  out->mesher = mesher;
  out->options = options;
  out->report = solution.report;
  return out;
}

}  // namespace pneuma::model
