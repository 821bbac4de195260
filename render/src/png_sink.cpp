#include "pneuma/render/png_sink.h"

#include <fmt/format.h>
#include <tbb/global_control.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <mutex>
#include <string>

#include "pneuma/core/error.h"
#include "pneuma/core/tsan.h"
#include "pneuma/render/camera.h"

namespace pneuma::render {

// Encodes and writes frames as TBB tasks; after `limit` frames submitted since the last wait, the
// next one first waits for all of them (so memory stays bounded). The images' buffers are recycled. With one thread
// allowed (tbb::global_control) there are no workers: the tasks run on the caller's thread when it waits.
class PngFrameSink::Encoder {
 public:
  explicit Encoder(const PngOptions& png)
      : png_(png), limit_(2 * tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism)) {}
  Encoder(const Encoder&) = delete;
  Encoder& operator=(const Encoder&) = delete;
  // An interrupted run (an exception on its way out): tasks not started are dropped, running ones
  // finish their atomic write; their errors no longer matter.
  ~Encoder() {
    tasks_.cancel();
    try {
      tasks_.wait();
    } catch (...) {
    }
  }

  Image take_buffer() {
    const std::lock_guard lock(mutex_);
    if (free_.empty()) return {};
    Image image = std::move(free_.back());
    free_.pop_back();
    return image;
  }

  // Rethrows the error of an earlier frame, if any (tbb::task_group::wait rethrows it).
  void submit(Image image, std::filesystem::path path) {
    if (queued_ >= limit_) wait();
    ++queued_;
    // TBB calls a task through a const reference; the image is handed back from there.
    struct Job {
      mutable Image image;
      std::filesystem::path path;
    };
    tasks_.run(region_.wrap([this, job = Job{std::move(image), std::move(path)}] {
      write_png(job.path, job.image, png_);
      const std::lock_guard lock(mutex_);
      free_.push_back(std::move(job.image));
    }));
  }

  void wait() {
    queued_ = 0;
    tasks_.wait();
    region_.join();
  }

 private:
  const PngOptions png_;
  const std::size_t limit_;
  std::size_t queued_ = 0;  // submitted since the last wait
  tbb::task_group tasks_;
  const tsan::Region region_;  // for ThreadSanitizer only: the frames' tasks against the caller
  std::mutex mutex_;
  std::vector<Image> free_;
};

PngFrameSink::PngFrameSink(std::filesystem::path directory, PngSinkOptions options)
    : directory_(std::move(directory)), options_(std::move(options)) {
  if (options_.every == 0) throw ValueError("png: every must be at least 1");
}

PngFrameSink::~PngFrameSink() = default;

void PngFrameSink::begin(const model::Model& model, const outputs::RunInfo& run) {
  // The rest pose (s = 0) is always in frame, even when every frame of the run inflates.
  // Two lungs: one image of both, each lung at its own scale.
  std::vector<RenderPart> parts;
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    const model::LungModel& lung = model.lungs[i];
    parts.push_back({&lung.rest, &lung.unit_displacement,
                     ScaleRange{std::min(run.min_scale[i], 0.0), std::max(run.max_scale[i], 0.0)}});
  }
  renderer_ = std::make_unique<Renderer>(std::span<const RenderPart>(parts), options_.render);
  scales_.assign(model.lungs.size(), 0.0);
  encoder_ = std::make_unique<Encoder>(options_.png);
  written_.clear();
}

std::filesystem::path PngFrameSink::path_of(std::size_t index) const {
  return directory_ / fmt::format("{}{:05d}.png", options_.prefix, index);
}

void PngFrameSink::frame(const model::Model&, const model::Frame& frame) {
  if (!renderer_) throw Error(ExitCode::failure, "render: PngFrameSink::frame() called before begin()");
  if (frame.index % options_.every != 0) return;
  for (std::size_t i = 0; i < scales_.size(); ++i) scales_[i] = frame.lungs[i].scale;
  // The frame is drawn now and comes back while the next one is drawn (Renderer::submit).
  if (renderer_->frames_in_flight() == Renderer::max_frames_in_flight) encode_oldest();
  renderer_->submit(std::span<const double>(scales_));
  written_.push_back(path_of(frame.index));
}

void PngFrameSink::encode_oldest() {
  Image image = encoder_->take_buffer();
  renderer_->collect(image);
  const std::size_t frame = written_.size() - renderer_->frames_in_flight() - 1;
  encoder_->submit(std::move(image), written_[frame]);
}

std::vector<std::filesystem::path> PngFrameSink::finish(const model::Model&, const outputs::RunRecord&) {
  if (renderer_) {
    while (renderer_->frames_in_flight() > 0) encode_oldest();
  }
  renderer_.reset();
  if (encoder_) {
    const auto encoder = std::move(encoder_);
    encoder->wait();
  }
  return written_;
}

outputs::OutputPlugin png_output() {
  const auto read = [](const scenario::Node* png, const scenario::Scenario& /*run*/) -> std::any {
    PngSinkOptions spec;
    if (png) {
      RenderOptions& r = spec.render;
      r.width = static_cast<int>(png->integer("width", r.width, 16, 8192));
      r.height = static_cast<int>(png->integer("height", r.height, 16, 8192));
      if (png->has("camera")) {
        parse_camera_preset(png->choice("camera", {"anterior", "posterior", "left", "right", "oblique"}), r.camera);
      }
      spec.every = static_cast<std::size_t>(png->integer("every", 1, 1, 1000000));
      r.overlay_magnitude = png->boolean("overlay", false);
      if (png->has("antialiasing")) {
        // msaa: 4 samples of the geometry (the default); fxaa: a filter pass over the image
        // (cheaper on llvmpipe, softer); none: the fastest, stair-stepped silhouettes.
        const std::string aa = png->choice("antialiasing", {"msaa", "fxaa", "none"});
        r.msaa_samples = aa == "msaa" ? 4 : 0;
        r.fxaa = aa == "fxaa";
      }
      if (png->has("gl")) parse_gl_backend(png->choice("gl", {"auto", "egl", "osmesa"}), r.gl);
    }
    return spec;
  };
  return {{"png", false, read}, {}, [](const std::any& settings, const std::filesystem::path& out) {
            return std::make_unique<PngFrameSink>(out / "png", std::any_cast<const PngSinkOptions&>(settings));
          }};
}

}  // namespace pneuma::render
