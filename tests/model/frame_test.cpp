// The breathing model takes the field's regions instead of finding them again.
#include <gtest/gtest.h>

#include "pneuma/core/error.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"
#include "pneuma/model/model.h"

using namespace pneuma;

TEST(Model, RegionsAreThoseOfTheRestSurfaceWhetherFoundOrGiven) {
  const auto rest = mesh::make_icosphere(0.1, 3);
  const std::vector<Eigen::Vector3d> u = mesh::vertex_normals(rest);
  mesh::RegionOptions supine;
  supine.axes.up = {0.0, -1.0, 0.0};  // LPS: anterior is up when lying on the back
  supine.axes.anterior = {0.0, 0.0, -1.0};
  const mesh::SurfaceRegions direct = mesh::find_regions(rest, supine);
  for (const mesh::SurfaceRegions* given : {static_cast<const mesh::SurfaceRegions*>(nullptr), &direct}) {
    const model::LungModel model = model::make_model(rest, u, 1e-4, supine.axes, given);
    EXPECT_EQ(model.regions.label, direct.label);
    EXPECT_EQ(model.regions.weight, direct.weight);
  }
  // Regions found in another body frame or on another surface are refused.
  EXPECT_THROW(model::make_model(rest, u, 1e-4, {}, &direct), ValueError);
  const auto other = mesh::make_icosphere(0.1, 2);
  EXPECT_THROW(model::make_model(other, mesh::vertex_normals(other), 1e-4, supine.axes, &direct), ValueError);
}
