#include "pneuma/model/model.h"

namespace pneuma::model {

Model make_model(mesh::TriangleMesh rest, std::vector<Eigen::Vector3d> unit_displacement, double area_unit_m2,
                 const mesh::BodyAxes& axes, const mesh::SurfaceRegions* known_regions) {
  if (known_regions) mesh::require_regions_of(*known_regions, rest, axes, "make_model");
  std::vector<Eigen::Vector3d> normals = mesh::vertex_normals(rest);
  VolumeScaleMap map(rest.vertices, unit_displacement, rest.triangles);
  const double area = mesh::surface_area(rest);
  mesh::RegionOptions region_options;
  region_options.axes = axes;
  mesh::SurfaceRegions regions = known_regions ? *known_regions : mesh::find_regions(rest, region_options);
  return Model{
      std::move(rest), std::move(normals), area, std::move(regions), std::move(unit_displacement), area_unit_m2, map};
}

}  // namespace pneuma::model
