#include "pneuma/render/png_sink.h"

#include <fmt/format.h>

#include "pneuma/core/error.h"

namespace pneuma::render {

PngFrameSink::PngFrameSink(std::filesystem::path directory, PngSinkOptions options)
    : directory_(std::move(directory)), options_(std::move(options)) {}

PngFrameSink::~PngFrameSink() = default;

void PngFrameSink::begin(const mesh::TriangleMesh& rest, const std::vector<Eigen::Vector3d>& field, ScaleRange scales) {
  renderer_ = std::make_unique<Renderer>(rest, field, scales, options_.render);
  written_.clear();
}

std::filesystem::path PngFrameSink::path_of(std::size_t index) const {
  return directory_ / fmt::format("{}{:05d}.png", options_.prefix, index);
}

void PngFrameSink::frame(std::size_t index, double s) {
  if (!renderer_) throw Error(ExitCode::failure, "render: PngFrameSink::frame() called before begin()");
  renderer_->render(s, image_);
  const auto path = path_of(index);
  write_png(path, image_, options_.png);
  written_.push_back(path);
}

std::vector<std::filesystem::path> PngFrameSink::end() {
  renderer_.reset();
  return written_;
}

}  // namespace pneuma::render
