#pragma once
// The per-frame state of a run (cf. MuJoCo's mjData) and the one step that updates it.
#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "pneuma/mesh/geometry/deformed_surface.h"
#include "pneuma/model/model.h"

namespace pneuma::frame {

// The only thing that changes during a run. Built once for a model; advance() updates it in
// place and allocates nothing.
struct Frame {
  explicit Frame(const model::Model& model);

  std::size_t index = 0;
  double time_s = 0.0;
  double lung_volume_m3 = 0.0;  // physiology: volume above the relaxed volume
  double mesh_volume_m3 = 0.0;  // enclosed volume of the frame's surface
  double scale = 0.0;           // s
  double area_m2 = 0.0;         // A(s)
  std::vector<Eigen::Vector3d> positions;
  mesh::DeformedSurface surface;  // the rest + s u kernel, bound to the model's mesh
};

// What the run loop knows of frame k before the model is applied.
struct FrameInput {
  std::size_t index = 0;
  double time_s = 0.0;
  double lung_volume_m3 = 0.0;
  double scale = 0.0;
};

// One step (cf. mj_step): positions = rest + s u and the area A(s) in one fused, threaded pass
// (mesh::DeformedSurface, the one rest + s u kernel: the same bits at any thread count), the
// volume from the exact cubic.
void advance(const model::Model& model, const FrameInput& input, Frame& frame);

}  // namespace pneuma::frame
