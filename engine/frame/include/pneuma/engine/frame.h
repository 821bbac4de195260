#pragma once
// What a run animates (immutable, built once) and what changes per frame, plus the one small
// interface every output implements (ARCHITECTURE.md: a new output is a new sink).
#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "pneuma/engine/volume_scale.h"
#include "pneuma/mesh/deformed_surface.h"
#include "pneuma/mesh/regions.h"
#include "pneuma/mesh/triangle_mesh.h"

namespace pneuma::engine {

// Computed once; never changes during a run (cf. MuJoCo's mjModel).
struct BreathingModel {
  mesh::TriangleMesh rest;                          // the exported surface at rest (metres)
  std::vector<Eigen::Vector3d> unit_displacement;   // u: metres per area unit of s, one per rest vertex
  std::vector<Eigen::Vector3d> normals;             // area-weighted unit normals of the rest surface
  double area_unit_m2 = 1e-4;                       // s counts these: A(s) - A(0) ~ s * area_unit
  VolumeScaleMap volume_map;                        // V(s) of rest + s u, exact cubic
  double rest_area_m2 = 0.0;
  mesh::SurfaceRegions regions;                     // apex, costal, diaphragmatic, mediastinal (docs/realism.md)
};

// The model of `rest` moved by `unit_displacement`: normals, the volume cubic, the rest area and
// the anatomical regions (in the body axes `frame`) are computed here, once; `regions`, when
// given, are rest's regions already found in `frame` (the field's), and are used instead.
// Throws ValueError when `regions` are not of `rest` in `frame` (mesh::require_regions_of).
BreathingModel make_breathing_model(mesh::TriangleMesh rest, std::vector<Eigen::Vector3d> unit_displacement,
                                    double area_unit_m2, const mesh::BodyFrame& frame = {},
                                    const mesh::SurfaceRegions* regions = nullptr);

// The per-frame state (cf. mjData), the only thing that changes during a run. Built once for a
// model; advance() updates it in place and allocates nothing.
struct Frame {
  explicit Frame(const BreathingModel& model);

  std::size_t index = 0;
  double time_s = 0.0;
  double lung_volume_m3 = 0.0;   // physiology: volume above the relaxed volume
  double mesh_volume_m3 = 0.0;   // enclosed volume of the frame's surface
  double scale = 0.0;            // s
  double area_m2 = 0.0;          // A(s)
  std::vector<Eigen::Vector3d> positions;
  mesh::DeformedSurface surface;  // the fused positions + area kernel, bound to the model's mesh
};

// What the run loop knows of frame k before the model is applied.
struct FrameInput {
  std::size_t index = 0;
  double time_s = 0.0;
  double lung_volume_m3 = 0.0;
  double scale = 0.0;
};

// One step (cf. mj_step): positions = rest + s u and the area A(s) in one fused, threaded pass
// (mesh::DeformedSurface: the same bits at any thread count), the volume from the exact cubic.
void advance(const BreathingModel& model, const FrameInput& input, Frame& frame);

// Facts about the whole run that sinks need before the first frame.
struct RunInfo {
  std::size_t frame_count = 0;
  double frame_rate_hz = 0.0;
  double min_scale = 0.0;  // over all frames
  double max_scale = 0.0;
  std::filesystem::path output_dir;
};

// One output. begin() once, frame() for every frame in order, end() once; end() returns
// the files written (for the manifest). Files appear under their final names only when
// complete: a sink that fails or is destroyed early leaves nothing partial behind.
class FrameSink {
 public:
  virtual ~FrameSink() = default;
  virtual std::string name() const = 0;
  virtual void begin(const BreathingModel& model, const RunInfo& run) = 0;
  virtual void frame(const BreathingModel& model, const Frame& frame) = 0;
  virtual std::vector<std::filesystem::path> end() = 0;
};

// Fills frame.positions = rest + scale * u (sizes must already match; no allocation).
void displace(const BreathingModel& model, double scale, std::vector<Eigen::Vector3d>& positions);

}  // namespace pneuma::engine
