// The breathing model takes the field's regions instead of finding them again.
#include <gtest/gtest.h>

#include "pneuma/core/error.h"
#include "pneuma/engine/frame.h"
#include "pneuma/mesh/triangle_mesh.h"

using namespace pneuma;
using namespace pneuma::engine;

TEST(BreathingModel, RegionsGivenAreTheRegionsItWouldFind) {
  const auto rest = mesh::make_icosphere(0.1, 3);
  const std::vector<Eigen::Vector3d> u = mesh::vertex_normals(rest);
  mesh::BodyFrame supine;
  supine.up = {0.0, -1.0, 0.0};  // LPS: anterior is up when lying on the back
  supine.anterior = {0.0, 0.0, -1.0};
  const BreathingModel found = make_breathing_model(rest, u, 1e-4, supine);
  const BreathingModel given = make_breathing_model(rest, u, 1e-4, supine, &found.regions);
  EXPECT_EQ(given.regions.label, found.regions.label);
  EXPECT_EQ(given.regions.weight, found.regions.weight);
  // In another body frame or on another surface they are not the rest surface's regions.
  EXPECT_THROW(make_breathing_model(rest, u, 1e-4, {}, &found.regions), ValueError);
  const auto other = mesh::make_icosphere(0.1, 2);
  EXPECT_THROW(make_breathing_model(other, mesh::vertex_normals(other), 1e-4, supine, &found.regions), ValueError);
}
