#pragma once
// How each anatomical region of the surface moved in each completed breath (docs/realism.md):
// computed once per run for every output that shows it (motion.csv, report.html).
#include <cstddef>
#include <span>
#include <vector>

#include "pneuma/mesh/anatomy/motion_summary.h"
#include "pneuma/model/model.h"
#include "pneuma/physiology/simulate.h"

namespace pneuma::outputs {

struct BreathMotion {
  std::size_t lung = 0;    // index in model::Model::lungs
  std::size_t breath = 0;  // index in physiology-breaths.csv
  double start_s = 0.0;
  double scale_from = 0.0;  // the breath's lowest and highest scale s: the motion is between them
  double scale_to = 0.0;
  mesh::MotionSummary summary;
};

// Each breath of `drive` (the physiology at the frame rate, one sample per frame, whose scales are
// `scales`), from its lowest to its highest scale among the frames inside it, measured on the
// surface at the lowest. Breaths with no frame inside are left out.
std::vector<BreathMotion> breath_motion(const model::LungModel& lung, const physiology::SimulationResult& drive,
                                        std::span<const double> scales);
// The same for every lung of `model` (`scales` one span per lung): lung by lung, each lung's
// breaths in order.
std::vector<BreathMotion> breath_motion(const model::Model& model, const physiology::SimulationResult& drive,
                                        const std::vector<std::span<const double>>& scales);

}  // namespace pneuma::outputs
