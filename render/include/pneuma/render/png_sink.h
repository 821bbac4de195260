#pragma once
// PNG frames of a breathing sequence, in the shape of a frame sink: begin() with the model
// (rest mesh, field, range of scales), frame() per frame, end(). engine::FrameSink can wrap this
// class one-to-one (cli/png_sink.cpp: begin: model.rest, model.field, {run.min_scale,
// run.max_scale}; frame: frame.index, frame.scale; end: the files). The wrapper lives outside
// render, which must not depend on the engine (it links physiology).
//
//   PngFrameSink sink("out/frames", {});
//   sink.begin(rest, field, {run.min_scale, run.max_scale});
//   for (k...) sink.frame(k, s[k]);   // writes out/frames/frame_00000.png, ...
//   sink.end();
#include <Eigen/Core>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "pneuma/mesh/triangle_mesh.h"
#include "pneuma/render/image.h"
#include "pneuma/render/renderer.h"

namespace pneuma::render {

struct PngSinkOptions {
  RenderOptions render;
  PngOptions png{.fast = true};
  std::string prefix = "frame_";  // files are <prefix><index, 5 digits>.png, as the mesh sequence
};

class PngFrameSink {
 public:
  PngFrameSink(std::filesystem::path directory, PngSinkOptions options = {});
  ~PngFrameSink();

  // Creates the renderer and uploads the model; `scales` spans every s that frame() will get
  // (RunInfo's min_scale and max_scale). Throws what Renderer's constructor throws.
  void begin(const mesh::TriangleMesh& rest, const std::vector<Eigen::Vector3d>& field, ScaleRange scales);
  // Renders the frame at scale s and writes it atomically. Throws IoError.
  void frame(std::size_t index, double s);
  // Releases the OpenGL context; returns the files written.
  std::vector<std::filesystem::path> end();

  std::filesystem::path path_of(std::size_t index) const;
  const std::vector<std::filesystem::path>& written() const { return written_; }

 private:
  std::filesystem::path directory_;
  PngSinkOptions options_;
  std::unique_ptr<Renderer> renderer_;
  Image image_;  // reused across frames
  std::vector<std::filesystem::path> written_;
};

}  // namespace pneuma::render
