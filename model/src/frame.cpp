#include "pneuma/model/frame.h"

namespace pneuma::model {

LungFrame::LungFrame(const model::LungModel& lung, std::optional<ScaleRange> scales)
    : positions(lung.rest.vertex_count()), surface(lung.rest.vertices, lung.unit_displacement, lung.rest.triangles) {
  // No table (the exact sum every frame) when A(s) is not smooth over the range.
  if (scales) surface.tabulate_measures(scales->min, scales->max);
}

Frame::Frame(const model::Model& model, std::span<const ScaleRange> scales) {
  lungs.reserve(model.lungs.size());
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    lungs.emplace_back(model.lungs[i], i < scales.size() ? std::optional<ScaleRange>(scales[i]) : std::nullopt);
  }
}

void advance(const model::Model& model, const FrameInput& input, Frame& frame) {
  frame.index = input.index;
  frame.time_s = input.time_s;
  frame.lung_volume_m3 = input.lung_volume_m3;
  for (std::size_t i = 0; i < frame.lungs.size(); ++i) {
    LungFrame& lung = frame.lungs[i];
    lung.scale = input.scale[i];
    lung.area_m2 = lung.surface.update(lung.scale, lung.positions).area_m2;
    lung.mesh_volume_m3 = model.lungs[i].volume_map.volume(lung.scale);
  }
}

}  // namespace pneuma::model
