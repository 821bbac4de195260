#pragma once
// The per-frame state of a run (cf. MuJoCo's mjData) and the one step that updates it.
#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <optional>
#include <span>
#include <vector>

#include "pneuma/mesh/geometry/deformed_surface.h"
#include "pneuma/model/model.h"

namespace pneuma::model {

// The scales a run will visit (all of a lung's frames lie in [min, max]).
struct ScaleRange {
  double min = 0.0;
  double max = 0.0;
};

// One lung's part of a frame (model::LungModel's).
struct LungFrame {
  // With the run's range of s, the area comes from a table over that range
  // (mesh::DeformedSurface::tabulate_measures) and a frame only writes positions.
  explicit LungFrame(const model::LungModel& lung, std::optional<ScaleRange> scales = std::nullopt);

  double mesh_volume_m3 = 0.0;  // enclosed volume of the lung's surface
  double scale = 0.0;           // s of this lung
  double area_m2 = 0.0;         // A(s)
  std::vector<Eigen::Vector3d> positions;
  mesh::DeformedSurface surface;  // the rest + s u kernel, bound to the lung's mesh
};

// The only thing that changes during a run. Built once for a model; advance() updates it in
// place and allocates nothing.
struct Frame {
  // `scales`: one range per model lung (or empty: every frame sums its area exactly).
  explicit Frame(const model::Model& model, std::span<const ScaleRange> scales = {});

  std::size_t index = 0;
  double time_s = 0.0;
  double lung_volume_m3 = 0.0;   // physiology: volume above the relaxed volume (both lungs)
  std::vector<LungFrame> lungs;  // one per model lung, in its order
};

// What the run loop knows of frame k before the model is applied.
struct FrameInput {
  std::size_t index = 0;
  double time_s = 0.0;
  double lung_volume_m3 = 0.0;
  std::array<double, model::kMaxLungs> scale{};  // s of each model lung
};

// One step (cf. mj_step): for each lung, positions = rest + s u and the area A(s) in one fused,
// threaded pass (mesh::DeformedSurface, the one rest + s u kernel: the same bits at any thread
// count), or the positions alone and A(s) from the lung's table when the Frame was given the run's
// scales; the volume from the exact cubic.
void advance(const model::Model& model, const FrameInput& input, Frame& frame);

}  // namespace pneuma::model
