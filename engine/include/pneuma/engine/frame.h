#pragma once
// What a run animates (immutable, built once) and what changes per frame, plus the one small
// interface every output implements (ARCHITECTURE.md: a new output is a new sink).
#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "pneuma/engine/volume_scale.h"
#include "pneuma/mesh/triangle_mesh.h"

namespace pneuma::engine {

// Computed once; never changes during a run (cf. MuJoCo's mjModel).
struct BreathingModel {
  mesh::TriangleMesh rest;                // the exported surface at rest (metres)
  std::vector<Eigen::Vector3d> field;     // u: displacement per unit scale (m), one per rest vertex
  std::vector<Eigen::Vector3d> normals;   // area-weighted unit normals of the rest surface
  double area_unit_m2 = 1e-4;             // s counts these: A(s) - A(0) ~ s * area_unit for small s
  VolumeScaleMap volume_map;              // V(s) of rest + s u, exact cubic
  double rest_area_m2 = 0.0;
};

// The per-frame state (cf. mjData): positions are updated in place, never reallocated.
struct Frame {
  std::size_t index = 0;
  double time_s = 0.0;
  double lung_volume_m3 = 0.0;   // physiology: volume above the relaxed volume
  double mesh_volume_m3 = 0.0;   // enclosed volume of the frame's surface
  double scale = 0.0;            // s
  double area_m2 = 0.0;          // A(s)
  std::vector<Eigen::Vector3d> positions;
};

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
