#pragma once
// PNG frames of a breathing sequence: the `png` output of a scenario, one outputs::Output.
// begin() makes the renderer and uploads the model once (rest mesh and unit displacement, framed
// over the run's range of scales); frame() renders every `every`-th frame at its scale and hands
// it to an encoder that writes <prefix><index, 5 digits>.png atomically on another thread (TBB,
// within tbb::global_control's thread limit), so the next frame draws while this one encodes;
// finish() waits for every file and releases the OpenGL context. Each frame is encoded on its own,
// so the files are the same bytes at any thread count.
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "pneuma/outputs/output.h"
#include "pneuma/render/image.h"
#include "pneuma/render/renderer.h"

namespace pneuma::render {

struct PngSinkOptions {
  RenderOptions render;
  PngOptions png{.fast = true};
  std::string prefix = "frame_";  // as the mesh sequence
  std::size_t every = 1;          // every n-th frame
};

class PngFrameSink final : public outputs::Output {
 public:
  PngFrameSink(std::filesystem::path directory, PngSinkOptions options = {});
  ~PngFrameSink() override;

  std::string name() const override { return "png"; }
  // Throws what Renderer's constructor throws (UnsupportedError without OpenGL).
  void begin(const model::Model& model, const outputs::RunInfo& run) override;
  // A frame that cannot be written throws IoError from a later frame() or from finish().
  void frame(const model::Model& model, const model::Frame& frame) override;
  std::vector<std::filesystem::path> finish(const model::Model& model, const outputs::RunRecord& run) override;

  std::filesystem::path path_of(std::size_t index) const;

 private:
  // Collects the oldest frame in flight and hands it to the encoder.
  void encode_oldest();

  std::filesystem::path directory_;
  PngSinkOptions options_;
  std::unique_ptr<Renderer> renderer_;
  std::vector<double> scales_;  // each lung's s for the frame being drawn
  class Encoder;
  std::unique_ptr<Encoder> encoder_;
  std::vector<std::filesystem::path> written_;
};

// `outputs: {png: {width: 800, height: 600, camera: oblique, every: 1, overlay: false, gl: auto}}`
// (off by default): frames in png/.
outputs::OutputPlugin png_output();

}  // namespace pneuma::render
