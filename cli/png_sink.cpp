// The `png` output of a scenario (outputs: png: {width, height, camera, every, overlay}): an
// engine::FrameSink around render::PngFrameSink. It lives here, in the CLI, because render
// must not depend on engine (which links physiology); the runner takes it as an extra sink.
#include <memory>

#include "commands.h"
#include "pneuma/core/error.h"
#include "pneuma/engine/runner.h"
#include "pneuma/render/camera.h"
#include "pneuma/render/png_sink.h"

namespace pneuma::cli {
namespace {

class PngSink final : public engine::FrameSink {
 public:
  PngSink(const std::filesystem::path& dir, const engine::PngSpec& spec, const std::string& scenario_file)
      : every_(spec.every) {
    render::PngSinkOptions options;
    options.render.width = spec.width;
    options.render.height = spec.height;
    options.render.overlay_magnitude = spec.overlay;
    if (!render::parse_camera_preset(spec.camera, options.render.camera)) {
      throw InputError(scenario_file + ": outputs.png.camera: unknown camera '" + spec.camera + "'");
    }
    sink_ = std::make_unique<render::PngFrameSink>(dir, options);
  }
  std::string name() const override { return "png"; }

  void begin(const engine::BreathingModel& model, const engine::RunInfo& run) override {
    sink_->begin(model.rest, model.field, {std::min(run.min_scale, 0.0), std::max(run.max_scale, 0.0)});
  }

  void frame(const engine::BreathingModel&, const engine::Frame& f) override {
    if (f.index % every_ == 0) sink_->frame(f.index, f.scale);
  }

  std::vector<std::filesystem::path> end() override { return sink_->end(); }

 private:
  std::size_t every_ = 1;
  std::unique_ptr<render::PngFrameSink> sink_;
};

}  // namespace

engine::SinkFactory png_sink_factory() {
  return [](const engine::Scenario& scenario, const std::filesystem::path& output_dir) -> std::unique_ptr<engine::FrameSink> {
    if (!scenario.outputs.png) return nullptr;
    return std::make_unique<PngSink>(output_dir / "png", *scenario.outputs.png, scenario.file.string());
  };
}

}  // namespace pneuma::cli
