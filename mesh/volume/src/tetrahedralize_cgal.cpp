// CGAL Mesh_3 on the polyhedral domain a closed surface bounds, and the entry point of both
// meshers. The only translation unit of mesh/volume that includes Mesh_3 (slow to compile). Sequential, seeded
// (CGAL::Random(0)): deterministic.
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polyhedral_mesh_domain_3.h>
#include <CGAL/make_mesh_3.h>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <unordered_map>

#include "pneuma/core/error.h"
#include "pneuma/mesh/cgal/cgal_surface_mesh.h"
#include "pneuma/mesh/volume/tetrahedralize.h"
#include "tet_quality.h"

namespace pneuma::mesh {
namespace {

using detail::Kernel;
using detail::SurfaceMesh;
using Domain = CGAL::Polyhedral_mesh_domain_3<SurfaceMesh, Kernel>;
using Tr = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr>;
using Criteria = CGAL::Mesh_criteria_3<Tr>;

// Mesh_3 works in millimetres (criteria and error bounds of order 1).
constexpr double kMm = 1e-3;

}  // namespace

const char* tet_mesher_name(TetMesher mesher) { return mesher == TetMesher::lattice ? "lattice" : "delaunay"; }

VolumeMesh tetrahedralize(const TriangleMesh& closed_surface, const TetrahedralizeOptions& options) {
  if (!(options.edge_length_m > 0.0) || !std::isfinite(options.edge_length_m)) {
    throw ValueError(fmt::format("tetrahedralize: expected a positive edge length, got {} m", options.edge_length_m));
  }
  TriangleMesh mm = closed_surface;
  for (auto& v : mm.vertices) v /= kMm;
  auto sm = detail::to_surface_mesh(mm);
  if (!sm || !CGAL::is_closed(*sm)) {
    throw ValueError("tetrahedralize: the surface is not closed and manifold, so it bounds no volume");
  }
  if (options.mesher == TetMesher::lattice)
    return detail::tetrahedralize_lattice(closed_surface, options.edge_length_m);

  CGAL::Random rng(0);
  const Domain domain(*sm, &rng);
  const double edge_mm = options.edge_length_m / kMm;
  const double distance_mm =
      (options.max_distance_m > 0.0 ? options.max_distance_m : options.edge_length_m / 10.0) / kMm;
  const Criteria criteria(CGAL::parameters::facet_angle = 25.0, CGAL::parameters::facet_size = edge_mm,
                          CGAL::parameters::facet_distance = distance_mm,
                          CGAL::parameters::cell_radius_edge_ratio = 3.0, CGAL::parameters::cell_size = edge_mm);
  const C3t3 c3t3 =
      options.sliver_bound_deg > 0.0
          ? CGAL::make_mesh_3<C3t3>(domain, criteria, CGAL::parameters::no_perturb(),
                                    CGAL::parameters::exude(CGAL::parameters::time_limit = 0,
                                                            CGAL::parameters::sliver_bound = options.sliver_bound_deg))
          : CGAL::make_mesh_3<C3t3>(domain, criteria, CGAL::parameters::no_perturb(), CGAL::parameters::no_exude());

  VolumeMesh out;
  // Nodes numbered by first use over the cells in the complex (the triangulation's own order:
  // deterministic for a deterministic refinement).
  // A hash map (#50: an ordered map's lookups were 2 % of the shipped 4D scenario's CPU); the
  // numbering is the order of first use, whatever the map's own order.
  const auto address = [](Tr::Vertex_handle v) { return std::hash<const void*>()(&*v); };
  std::unordered_map<Tr::Vertex_handle, std::uint32_t, decltype(address)> index(
      static_cast<std::size_t>(c3t3.triangulation().number_of_vertices()), address);
  auto node = [&](Tr::Vertex_handle v) {
    auto [it, inserted] = index.emplace(v, static_cast<std::uint32_t>(out.mesh.nodes.size()));
    if (inserted) {
      const auto& p = v->point().point();
      out.mesh.nodes.emplace_back(p.x() * kMm, p.y() * kMm, p.z() * kMm);
    }
    return it->second;
  };
  out.mesh.tets.reserve(static_cast<std::size_t>(c3t3.number_of_cells_in_complex()));
  out.min_volume_m3 = std::numeric_limits<double>::infinity();
  out.min_dihedral_deg = 180.0;
  for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c) {
    Tetrahedron t{node(c->vertex(0)), node(c->vertex(1)), node(c->vertex(2)), node(c->vertex(3))};
    const auto& n = out.mesh.nodes;
    double v6 = tet_volume6(n[t[0]], n[t[1]], n[t[2]], n[t[3]]);
    if (v6 < 0.0) {
      std::swap(t[2], t[3]);
      v6 = -v6;
    }
    out.mesh.tets.push_back(t);
    out.volume_m3 += v6 / 6.0;
    out.min_volume_m3 = std::min(out.min_volume_m3, v6 / 6.0);
    out.min_dihedral_deg = std::min(out.min_dihedral_deg, detail::min_dihedral_deg(n[t[0]], n[t[1]], n[t[2]], n[t[3]]));
  }
  if (out.mesh.tets.empty()) throw ValueError("tetrahedralize: Mesh_3 found no cell inside the surface");

  std::vector<char> on_boundary(out.mesh.nodes.size(), 0);
  for (auto f = c3t3.facets_in_complex_begin(); f != c3t3.facets_in_complex_end(); ++f) {
    for (int k = 1; k < 4; ++k) {
      const auto it = index.find(f->first->vertex((f->second + k) & 3));
      if (it != index.end()) on_boundary[it->second] = 1;
    }
  }
  for (std::uint32_t i = 0; i < on_boundary.size(); ++i) {
    if (on_boundary[i]) out.boundary_nodes.push_back(i);
  }
  return out;
}

}  // namespace pneuma::mesh
