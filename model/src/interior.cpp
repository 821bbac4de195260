// A lung's inside: tetrahedra of the rest surface (Mesh_3 or the lattice), the surface field carried to their
// boundary nodes, the interior field solved for the rest.
#include <fmt/format.h>

#include <cmath>
#include <span>
#include <vector>

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
  // The breaths each direction's unfolding keeps (scales of the field as given): one U serves the
  // inflation and the deflation, so the moves for one may not steepen the other (#45 at 2 mm: the
  // moves for 1 L above rest left case004's quiet deflation at J = 0.27-0.37 under its left base).
  // The deflation is the run's own breath (a breath-hold scan's end-expiration): kept whole; the
  // inflation as its own unfolding keeps it (whole up to half of `unfold`, a floor beyond).
  double inflation_scale = 0.0, deflation_scale = 0.0;
  if (options.unfold_volume_m3 > 0.0) {
    // The breath of unfold_volume_m3 above rest, or the deepest this field reaches.
    const double target = volume_map.volume(0.0) + options.unfold_volume_m3;
    inflation_scale = target < volume_map.max_volume() ? volume_map.scale_for(target) : volume_map.max_scale();
  }
  if (options.unfold_deflation_m3 > 0.0) {
    // The deepest deflation the run asks for (a breath-hold scan's end-expiration).
    const double target = volume_map.volume(0.0) - options.unfold_deflation_m3;
    deflation_scale = target > volume_map.min_volume() ? volume_map.scale_for(target) : volume_map.min_scale();
  }
  const auto usable = [](double scale) { return scale != 0.0 && std::isfinite(scale); };
  std::vector<field::KeptBreath> the_deflation, the_inflation;
  if (usable(deflation_scale) && deflation_scale < 0.0)
    for (const field::KeptBreath& b : field::unfolding_breaths(-deflation_scale, 0.2, -1.0))
      the_deflation.push_back({b.scale, 1.0});
  // Seen from the deflation's unfolding, which works on -U: the inflation at negative scales.
  if (usable(inflation_scale) && inflation_scale > 0.0)
    the_inflation = field::unfolding_breaths(inflation_scale, 0.2, -1.0);
  // Unfold for `scale` (> 0: the inflation; < 0: the deflation, as the field -u at -scale).
  const auto unfold = [&](double scale, std::span<const field::KeptBreath> kept) {
    if (!usable(scale)) return;
    std::vector<Eigen::Vector3d>& d = solution.displacement;
    if (scale < 0.0)
      for (Eigen::Vector3d& v : d) v = -v;
    const field::UntangleReport u =
        field::untangle_interior(volume.mesh, volume.boundary_nodes, d, std::abs(scale), 0.2, 20, kept);
    const field::DroppedTets dropped =
        field::drop_folded_boundary_tets(volume.mesh, volume.boundary_nodes, d, std::abs(scale));
    if (scale < 0.0)
      for (Eigen::Vector3d& v : d) v = -v;
    solution.report.unfolded_nodes += u.nodes_moved;
    solution.report.dropped_tets += dropped.count;
    solution.report.dropped_volume_m3 += dropped.rest_volume_m3;
  };
  if (options.unfold_volume_m3 > 0.0) unfold(inflation_scale, the_deflation);
  if (options.unfold_deflation_m3 > 0.0) unfold(deflation_scale, the_inflation);  // last
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
