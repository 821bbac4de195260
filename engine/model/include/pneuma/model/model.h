#pragma once
// The model: everything a run computes once and never changes while it runs (cf. MuJoCo's
// mjModel). compile() (compile.h) makes it from a scenario; frame::advance() reads it by const&.
#include <Eigen/Core>
#include <vector>

#include "pneuma/mesh/anatomy/regions.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"
#include "pneuma/model/volume_scale.h"

namespace pneuma::model {

struct Model {
  // ---- The surface at rest (metres, LPS) ------------------------------------------------------
  mesh::TriangleMesh rest;               // the exported surface
  std::vector<Eigen::Vector3d> normals;  // area-weighted unit normals of `rest`, one per vertex
  double rest_area_m2 = 0.0;
  mesh::SurfaceRegions regions;  // apex, costal, diaphragmatic, mediastinal (docs/realism.md)

  // ---- The field: a frame is rest + s * unit_displacement ----------------------------------------
  std::vector<Eigen::Vector3d> unit_displacement;  // u: metres per area unit of s, one per vertex
  double area_unit_m2 = 1e-4;                      // s counts these: A(s) - A(0) ~ s * area_unit

  // ---- Volume to scale --------------------------------------------------------------------------
  VolumeScaleMap volume_map;  // V(s) of rest + s u, an exact cubic
};

// The model of `rest` moved by `unit_displacement`: normals, the volume cubic, the rest area and
// the anatomical regions (in the body `axes`) are computed here, once; `regions`, when given,
// are rest's regions already found in `axes` (the field's), and are used instead.
// Throws ValueError when `regions` are not of `rest` in `axes` (mesh::require_regions_of).
Model make_model(mesh::TriangleMesh rest, std::vector<Eigen::Vector3d> unit_displacement, double area_unit_m2,
                 const mesh::BodyAxes& axes = {}, const mesh::SurfaceRegions* regions = nullptr);

}  // namespace pneuma::model
