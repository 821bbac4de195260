#include "pneuma/frame/frame.h"

namespace pneuma::frame {

Frame::Frame(const model::Model& model)
    : positions(model.rest.vertex_count()),
      surface(model.rest.vertices, model.unit_displacement, model.rest.triangles) {}

void advance(const model::Model& model, const FrameInput& input, Frame& frame) {
  frame.index = input.index;
  frame.time_s = input.time_s;
  frame.lung_volume_m3 = input.lung_volume_m3;
  frame.scale = input.scale;
  frame.area_m2 = frame.surface.update(frame.scale, frame.positions).area_m2;
  frame.mesh_volume_m3 = model.volume_map.volume(frame.scale);
}

}  // namespace pneuma::frame
