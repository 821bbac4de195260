#include "pneuma/model/model.h"

namespace pneuma::model {

std::size_t Model::vertex_count() const {
  std::size_t n = 0;
  for (const LungModel& lung : lungs) n += lung.rest.vertex_count();
  return n;
}

std::size_t Model::triangle_count() const {
  std::size_t n = 0;
  for (const LungModel& lung : lungs) n += lung.rest.triangle_count();
  return n;
}

LungModel make_model(mesh::TriangleMesh rest, std::vector<Eigen::Vector3d> unit_displacement, double area_unit_m2,
                     const mesh::BodyAxes& axes, const mesh::SurfaceRegions* known_regions,
                     std::optional<mesh::Lung> side) {
  if (known_regions) mesh::require_regions_of(*known_regions, rest, axes, "make_model");
  // Regions found from the geometry name a side; a lung of a two-lung model knows its own.
  if (known_regions && side && known_regions->side != *side) known_regions = nullptr;
  std::vector<Eigen::Vector3d> normals = mesh::vertex_normals(rest);
  VolumeScaleMap map(rest.vertices, unit_displacement, rest.triangles);
  const double area = mesh::surface_area(rest);
  mesh::RegionOptions region_options;
  region_options.axes = axes;
  region_options.side = side;
  mesh::SurfaceRegions regions = known_regions ? *known_regions : mesh::find_regions(rest, region_options);
  LungModel lung{std::move(rest),
                 std::move(normals),
                 area,
                 std::move(regions),
                 std::move(unit_displacement),
                 area_unit_m2,
                 map,
                 side};
  return lung;
}

}  // namespace pneuma::model
