#include "pneuma/outputs/breath_motion.h"

#include "pneuma/mesh/geometry/deformed_surface.h"

namespace pneuma::outputs {

std::vector<BreathMotion> breath_motion(const model::LungModel& model, const physiology::SimulationResult& drive,
                                        std::span<const double> scales) {
  std::vector<BreathMotion> out;
  const auto& t = drive.series.time_s;
  mesh::DeformedSurface kernel(model.rest.vertices, model.unit_displacement, model.rest.triangles);
  mesh::TriangleMesh from = model.rest;
  for (std::size_t b = 0; b < drive.breaths.size(); ++b) {
    const auto& breath = drive.breaths[b];
    std::size_t lo = scales.size(), hi = scales.size();
    for (std::size_t k = 0; k < scales.size(); ++k) {
      if (t[k] < breath.start_s || t[k] > breath.start_s + breath.duration_s) continue;
      if (lo == scales.size() || scales[k] < scales[lo]) lo = k;
      if (hi == scales.size() || scales[k] > scales[hi]) hi = k;
    }
    if (lo == scales.size()) continue;
    kernel.update(scales[lo], from.vertices);
    out.push_back({0, b, breath.start_s, scales[lo], scales[hi],
                   mesh::summarize_motion(from, model.unit_displacement, scales[hi] - scales[lo], model.regions)});
  }
  return out;
}

std::vector<BreathMotion> breath_motion(const model::Model& model, const physiology::SimulationResult& drive,
                                        const std::vector<std::span<const double>>& scales) {
  std::vector<BreathMotion> out;
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    for (BreathMotion& b : breath_motion(model.lungs[i], drive, scales[i])) {
      b.lung = i;
      out.push_back(b);
    }
  }
  return out;
}

}  // namespace pneuma::outputs
