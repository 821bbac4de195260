#pragma once
// A deterministic lung-like stand-in for the renderer's unit tests (analytic, any resolution,
// no engine; the golden images use the real phantom and field, golden_test.cpp): a
// left lung in LPS patient coordinates (+x left, +y posterior, +z superior), about 24 cm tall,
// narrow at the apex, its medial side flattened and notched, and a smooth field that moves the base
// (diaphragm) most: u = n * (4 mm + 10 mm * depth below the apex) per unit s.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <vector>

#include "pneuma/mesh/geometry/triangle_mesh.h"
#include "pneuma/render/image.h"

namespace pneuma::test {

struct LungStandIn {
  mesh::TriangleMesh rest;
  std::vector<Eigen::Vector3d> field;
};

inline LungStandIn make_lung_stand_in(int subdivisions = 4) {
  LungStandIn lung;
  lung.rest = mesh::make_icosphere(1.0, subdivisions);
  for (Eigen::Vector3d& p : lung.rest.vertices) {
    const double taper = 0.72 - 0.32 * p.z();  // 0.4 at the apex, 1.04 at the base
    double x = p.x();
    if (x < 0.0) {  // the medial side: flattened, hollowed where the heart lies (cardiac notch)
      const double notch = std::exp(-std::pow((p.z() + 0.15) / 0.3, 2.0));
      x = (x + 0.3 * x * x) * (1.0 - 0.3 * notch);
    }
    p = Eigen::Vector3d(0.055 * taper * x, 0.085 * taper * p.y(), 0.12 * p.z());
  }
  const std::vector<Eigen::Vector3d> normals = mesh::vertex_normals(lung.rest);
  lung.field.resize(lung.rest.vertex_count());
  for (std::size_t i = 0; i < lung.field.size(); ++i) {
    const double depth = (0.12 - lung.rest.vertices[i].z()) / 0.24;  // 0 at the apex, 1 at the base
    lung.field[i] = normals[i] * (0.004 + 0.010 * depth);
  }
  return lung;
}

// Pixels that differ from the background colour.
inline std::size_t silhouette_pixels(const render::Image& image, render::Rgba background) {
  std::size_t n = 0;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) n += image.at(x, y) == background ? 0 : 1;
  }
  return n;
}

inline render::Rgba to_rgba8(const Eigen::Vector3d& srgb) {
  auto c = [](double v) { return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255.0)); };
  return {c(srgb.x()), c(srgb.y()), c(srgb.z()), 255};
}

}  // namespace pneuma::test
