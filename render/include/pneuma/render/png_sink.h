#pragma once
// PNG frames of a breathing sequence: the `png` output of a scenario, one engine::FrameSink.
// begin() makes the renderer and uploads the model once (rest mesh and unit displacement, framed
// over the run's range of scales); frame() renders every `every`-th frame at its scale and writes
// <prefix><index, 5 digits>.png atomically; end() releases the OpenGL context.
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "pneuma/engine/frame.h"
#include "pneuma/render/image.h"
#include "pneuma/render/renderer.h"

namespace pneuma::render {

struct PngSinkOptions {
  RenderOptions render;
  PngOptions png{.fast = true};
  std::string prefix = "frame_";  // as the mesh sequence
  std::size_t every = 1;          // every n-th frame
};

class PngFrameSink final : public engine::FrameSink {
 public:
  PngFrameSink(std::filesystem::path directory, PngSinkOptions options = {});
  ~PngFrameSink() override;

  std::string name() const override { return "png"; }
  // Throws what Renderer's constructor throws (UnsupportedError without OpenGL).
  void begin(const engine::BreathingModel& model, const engine::RunInfo& run) override;
  // Throws IoError when the file cannot be written.
  void frame(const engine::BreathingModel& model, const engine::Frame& frame) override;
  std::vector<std::filesystem::path> end() override;

  std::filesystem::path path_of(std::size_t index) const;

 private:
  std::filesystem::path directory_;
  PngSinkOptions options_;
  std::unique_ptr<Renderer> renderer_;
  Image image_;  // reused across frames
  std::vector<std::filesystem::path> written_;
};

}  // namespace pneuma::render
