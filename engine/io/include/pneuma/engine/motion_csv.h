#pragma once
// motion.csv: how each anatomical region of the surface moved in each breath (docs/realism.md):
// one row per breath and region, displacements in mm along the body axes (caudal: downward
// positive; anterior; lateral: away from the midline), the region's share of the volume change.
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "pneuma/mesh/motion_summary.h"

namespace pneuma::engine {

struct BreathMotion {
  std::size_t breath = 0;   // index in physiology-breaths.csv
  double start_s = 0.0;
  double scale_from = 0.0;  // the breath's lowest and highest scale s: the motion is between them
  double scale_to = 0.0;
  mesh::MotionSummary summary;
};

// Writes the file atomically. Throws IoError.
void write_motion_csv(const std::filesystem::path& path, const std::vector<BreathMotion>& breaths);

// Means over the breaths, as manifest facts ("motion.diaphragmatic.caudal_mean_mm", ...).
std::vector<std::pair<std::string, std::string>> motion_facts(const std::vector<BreathMotion>& breaths);

}  // namespace pneuma::engine
