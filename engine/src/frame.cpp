#include "pneuma/engine/frame.h"

namespace pneuma::engine {

void displace(const BreathingModel& model, double scale, std::vector<Eigen::Vector3d>& positions) {
  const std::size_t n = model.rest.vertices.size();
  const Eigen::Vector3d* rest = model.rest.vertices.data();
  const Eigen::Vector3d* u = model.field.data();
  Eigen::Vector3d* out = positions.data();
  for (std::size_t i = 0; i < n; ++i) out[i] = rest[i] + scale * u[i];
}

}  // namespace pneuma::engine
