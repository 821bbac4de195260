#include "pneuma/render/png_sink.h"

#include <fmt/format.h>

#include <algorithm>

#include "pneuma/core/error.h"

namespace pneuma::render {

PngFrameSink::PngFrameSink(std::filesystem::path directory, PngSinkOptions options)
    : directory_(std::move(directory)), options_(std::move(options)) {
  if (options_.every == 0) throw ValueError("png: every must be at least 1");
}

PngFrameSink::~PngFrameSink() = default;

void PngFrameSink::begin(const engine::BreathingModel& model, const engine::RunInfo& run) {
  // The rest pose (s = 0) is always in frame, even when every frame of the run inflates.
  const ScaleRange scales{std::min(run.min_scale, 0.0), std::max(run.max_scale, 0.0)};
  renderer_ = std::make_unique<Renderer>(model.rest, model.unit_displacement, scales, options_.render);
  written_.clear();
}

std::filesystem::path PngFrameSink::path_of(std::size_t index) const {
  return directory_ / fmt::format("{}{:05d}.png", options_.prefix, index);
}

void PngFrameSink::frame(const engine::BreathingModel&, const engine::Frame& frame) {
  if (!renderer_) throw Error(ExitCode::failure, "render: PngFrameSink::frame() called before begin()");
  if (frame.index % options_.every != 0) return;
  renderer_->render(frame.scale, image_);
  const auto path = path_of(frame.index);
  write_png(path, image_, options_.png);
  written_.push_back(path);
}

std::vector<std::filesystem::path> PngFrameSink::end() {
  renderer_.reset();
  return written_;
}

}  // namespace pneuma::render
