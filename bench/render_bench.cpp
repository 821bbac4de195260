// Headless rendering at 1280x720 (OSMesa, llvmpipe) for ~82k and ~1.3M triangles (icosphere
// ellipsoids, 20 * 4^k triangles, k = 6 and 8) with a smooth field, split into the parts of a
// frame: the one-time upload (context, normal terms, buffers), the per-frame draw including
// MSAA resolve and read-back, and PNG encoding.
// Baseline in the same run: the same pipeline on an empty scene (clear, resolve, read back the
// same 1280x720 image), i.e. the cost of getting pixels out at all.
// Wall time is reported (UseRealTime): llvmpipe's rasteriser threads work outside the timed
// thread, so the "CPU" column only shows the calling thread's share.
// llvmpipe rasterises on LP_NUM_THREADS threads (default: one per core); run with
// LP_NUM_THREADS=1 and 2 to see the scaling. BENCHMARKS.md ("## Render") keeps the figures.
// BM_PngSequence: the scenario's PNG sink, with its encoding threaded or not.
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <ctime>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "pneuma/model/frame.h"
#include "pneuma/render/image.h"
#include "pneuma/render/png_sink.h"
#include "pneuma/render/renderer.h"

namespace {

using namespace pneuma;

constexpr int kWidth = 1280, kHeight = 720;

struct Model {
  mesh::TriangleMesh rest;
  std::vector<Eigen::Vector3d> field;
};

// A lung-sized ellipsoid (11 x 17 x 24 cm) and u = n * (4 + 10 * depth) mm per unit s.
const Model& model(int subdivisions) {
  static std::map<int, Model> cache;
  auto it = cache.find(subdivisions);
  if (it != cache.end()) return it->second;
  Model m;
  m.rest = mesh::make_icosphere(1.0, subdivisions);
  for (auto& p : m.rest.vertices) p = Eigen::Vector3d(0.055 * p.x(), 0.085 * p.y(), 0.12 * p.z());
  const auto normals = mesh::vertex_normals(m.rest);
  m.field.resize(normals.size());
  for (std::size_t i = 0; i < normals.size(); ++i) {
    m.field[i] = normals[i] * (0.004 + 0.010 * (0.12 - m.rest.vertices[i].z()) / 0.24);
  }
  return cache.emplace(subdivisions, std::move(m)).first->second;
}

// Anti-aliasing from the benchmark's arguments: MSAA samples and FXAA on (1) or off (0).
render::RenderOptions options(const benchmark::State& state, int first_argument) {
  render::RenderOptions o;
  o.width = kWidth;
  o.height = kHeight;
  o.camera = render::CameraPreset::oblique;
  o.msaa_samples = static_cast<int>(state.range(first_argument));
  o.fxaa = state.range(first_argument + 1) != 0;
  return o;
}

void name_antialiasing(benchmark::State& state, int first_argument) {
  const auto msaa = state.range(first_argument);
  const bool fxaa = state.range(first_argument + 1) != 0;
  state.SetLabel(msaa > 1 ? "MSAA " + std::to_string(msaa) + "x" + (fxaa ? " + FXAA" : "")
                 : fxaa   ? "FXAA"
                          : "no anti-aliasing");
}

// CPU time of the whole process (the calling thread and llvmpipe's threads), in ms. On a
// shared machine this is steadier than wall time; on an idle one wall time is about the larger
// of the calling thread's time and this divided by the cores.
double process_cpu_ms() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_nsec) * 1e-6;
}

void per_frame_cpu(benchmark::State& state, double cpu_start_ms) {
  state.counters["process_cpu_ms_per_frame"] =
      (process_cpu_ms() - cpu_start_ms) / static_cast<double>(state.iterations());
}

void label(benchmark::State& state, const Model& m) {
  state.counters["triangles"] = static_cast<double>(m.rest.triangle_count());
  state.counters["vertices"] = static_cast<double>(m.rest.vertex_count());
}

// The timed loop of the draw benchmarks: one warm-up draw (shader compilation happens on the
// first), then a draw and read-back per iteration at a moving s; frames/s and CPU per frame.
void time_frames(benchmark::State& state, render::Renderer& renderer, const Model& m) {
  render::Image image;
  renderer.render(0.0, image);
  int k = 0;
  const double cpu_start = process_cpu_ms();
  for (auto _ : state) {
    renderer.render(0.01 * (k++ % 100), image);
    benchmark::DoNotOptimize(image.rgba.data());
  }
  per_frame_cpu(state, cpu_start);
  label(state, m);
  state.counters["frames_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

// The same with the frames pipelined (Renderer::submit / collect, two in flight): the
// read-back of one frame overlaps the drawing of the next, as in the PNG sink.
// The loop of the pipelined benchmarks: a warm-up draw, then per iteration a frame submitted at a
// moving s and, with two in flight, the oldest collected; frames/s.
void run_pipelined_frames(benchmark::State& state, render::Renderer& renderer) {
  render::Image image;
  renderer.render(0.0, image);
  int k = 0;
  for (auto _ : state) {
    if (renderer.frames_in_flight() == render::Renderer::max_frames_in_flight) renderer.collect(image);
    renderer.submit(0.01 * (k++ % 100));
    benchmark::DoNotOptimize(image.rgba.data());
  }
  while (renderer.frames_in_flight() > 0) renderer.collect(image);
  state.counters["frames_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

void time_pipelined_frames(benchmark::State& state, render::Renderer& renderer, const Model& m) {
  const double cpu_start = process_cpu_ms();
  run_pipelined_frames(state, renderer);
  per_frame_cpu(state, cpu_start);
  label(state, m);
}

// Per frame: uniform s, draw, resolve, read back (the frame's pixels in memory).
// Arguments: subdivisions, MSAA samples (4: the default), FXAA (0/1).
void BM_Draw(benchmark::State& state) {
  const Model& m = model(static_cast<int>(state.range(0)));
  render::Renderer renderer(m.rest, m.field, 1.0, options(state, 1));
  name_antialiasing(state, 1);
  time_frames(state, renderer, m);
}
BENCHMARK(BM_Draw)
    ->Args({6, 4, 0})
    ->Args({8, 4, 0})
    ->Args({6, 0, 1})
    ->Args({8, 0, 1})
    ->Args({6, 0, 0})
    ->Args({8, 0, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Baseline: the same image size with nothing to draw (arguments: MSAA samples, FXAA).
void BM_ClearReadbackBaseline(benchmark::State& state) {
  render::Renderer renderer(mesh::TriangleMesh{}, {}, 1.0, options(state, 0));
  name_antialiasing(state, 0);
  render::Image image;
  renderer.render(0.0, image);
  const double cpu_start = process_cpu_ms();
  for (auto _ : state) {
    renderer.render(0.5, image);
    benchmark::DoNotOptimize(image.rgba.data());
  }
  per_frame_cpu(state, cpu_start);
  state.counters["frames_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ClearReadbackBaseline)
    ->Args({4, 0})
    ->Args({0, 1})
    ->Args({0, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Once per run: context, normal terms, vertex and index buffers, framebuffers, shaders, and
// the first draw (llvmpipe compiles shader variants lazily).
void BM_Upload(benchmark::State& state) {
  const Model& m = model(static_cast<int>(state.range(0)));
  render::Image image;
  for (auto _ : state) {
    render::Renderer renderer(m.rest, m.field, 1.0, options(state, 1));
    renderer.render(0.0, image);
  }
  label(state, m);
}
BENCHMARK(BM_Upload)->Args({6, 4, 0})->Args({8, 4, 0})->Unit(benchmark::kMillisecond)->UseRealTime();

// PNG encoding of a rendered 1280x720 frame: libpng default and fast (the frame sink's choice).
void BM_PngEncode(benchmark::State& state) {
  const Model& m = model(8);
  render::RenderOptions o;
  o.width = kWidth;
  o.height = kHeight;
  o.camera = render::CameraPreset::oblique;
  render::Renderer renderer(m.rest, m.field, 1.0, o);
  const render::Image image = renderer.render(1.0);
  const render::PngOptions png{.fast = state.range(0) != 0};
  std::size_t bytes = 0;
  for (auto _ : state) {
    const auto encoded = render::encode_png(image, png);
    bytes = encoded.size();
    benchmark::DoNotOptimize(encoded.data());
  }
  state.counters["kilobytes"] = static_cast<double>(bytes) / 1024.0;
  state.SetLabel(state.range(0) ? "fast" : "default");
}
BENCHMARK(BM_PngEncode)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// The whole per-frame path of the PNG sink, without the disk: draw, read back, encode (fast).
void BM_FrameToPng(benchmark::State& state) {
  const Model& m = model(static_cast<int>(state.range(0)));
  render::Renderer renderer(m.rest, m.field, 1.0, options(state, 1));
  name_antialiasing(state, 1);
  render::Image image;
  renderer.render(0.0, image);
  int k = 0;
  const double cpu_start = process_cpu_ms();
  for (auto _ : state) {
    renderer.render(0.01 * (k++ % 100), image);
    const auto encoded = render::encode_png(image, {.fast = true});
    benchmark::DoNotOptimize(encoded.data());
  }
  per_frame_cpu(state, cpu_start);
  label(state, m);
  state.counters["frames_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_FrameToPng)
    ->Args({6, 4, 0})
    ->Args({8, 4, 0})
    ->Args({8, 0, 1})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// A PNG sequence through the scenario's sink (render::PngFrameSink): 16 frames drawn, encoded
// (fast) and written to a temporary folder, the last file on disk included; the sink's set-up
// (context, upload) is not timed. Arguments: subdivisions, TBB threads for the encoder (1: the
// frames are encoded on the drawing thread, one after another, the baseline; 2: encoding
// overlaps the next frame's drawing), then MSAA samples and FXAA as above.
void BM_PngSequence(benchmark::State& state) {
  const Model& m = model(static_cast<int>(state.range(0)));
  const tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                                  static_cast<std::size_t>(state.range(1)));
  const model::Model breathing(model::make_model(m.rest, m.field, 1e-4));
  render::PngSinkOptions sink_options;
  sink_options.render = options(state, 2);
  name_antialiasing(state, 2);
  const auto folder = std::filesystem::temp_directory_path() / ("pneuma-png-bench-" + std::to_string(::getpid()));
  constexpr std::size_t kFrames = 16;
  model::Frame frame(breathing);
  const double cpu_start = process_cpu_ms();
  for (auto _ : state) {
    state.PauseTiming();
    render::PngFrameSink sink(folder, sink_options);
    sink.begin(breathing, outputs::RunInfo{kFrames, 30.0, {0.0}, {1.0}, folder});
    state.ResumeTiming();
    for (std::size_t k = 0; k < kFrames; ++k) {
      model::advance(breathing, {k, 0.0, 0.0, {static_cast<double>(k) / kFrames}}, frame);
      sink.frame(breathing, frame);
    }
    benchmark::DoNotOptimize(sink.finish(breathing, {}).size());
  }
  std::filesystem::remove_all(folder);
  state.counters["process_cpu_ms_per_frame"] =
      (process_cpu_ms() - cpu_start) / static_cast<double>(state.iterations() * kFrames);  // set-up included
  label(state, m);
  state.counters["frames_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations() * kFrames), benchmark::Counter::kIsRate);
  state.counters["encoder_threads"] = static_cast<double>(state.range(1));
}
BENCHMARK(BM_PngSequence)
    ->Args({8, 1, 0, 1})
    ->Args({8, 2, 0, 1})
    ->Args({6, 1, 4, 0})
    ->Args({6, 2, 4, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The OpenGL backends (render::GlBackend) side by side on the 1.3M-triangle mesh: per frame, set s,
// draw, resolve or filter, read back. Arguments: backend (0 OSMesa, 1 EGL), image size (0:
// 1280x720, 1: 1920x1080), MSAA samples, FXAA (0/1). EGL on this machine is Mesa's surfaceless
// platform (llvmpipe, like OSMesa); on a GPU machine it takes the GPU through the device platform
// (the label says which), so the same cases measure the GPU path there.

// The backend cases' options from the arguments (backend, image size, MSAA samples, FXAA).
render::RenderOptions backend_options(const benchmark::State& state) {
  render::RenderOptions o = options(state, 2);
  o.gl = state.range(0) ? render::GlBackend::egl : render::GlBackend::osmesa;
  if (state.range(1)) {
    o.width = 1920;
    o.height = 1080;
  }
  return o;
}

void name_backend(benchmark::State& state, const render::Renderer& renderer, const std::string& prefix) {
  const render::RenderOptions& o = renderer.options();
  state.SetLabel(prefix + renderer.gl_backend() + ", " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                 ", " + renderer.gl_renderer());
}

void backend_cases(benchmark::internal::Benchmark* b) {
  b->Args({0, 0, 0, 1})
      ->Args({1, 0, 0, 1})
      ->Args({0, 0, 0, 0})
      ->Args({1, 0, 0, 0})
      ->Args({1, 1, 0, 0})
      ->Args({1, 1, 0, 1})
      ->Args({1, 1, 4, 0})
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
}

void BM_DrawBackend(benchmark::State& state) {
  const Model& m = model(8);
  render::Renderer renderer(m.rest, m.field, 1.0, backend_options(state));
  name_antialiasing(state, 2);
  name_backend(state, renderer, "");
  time_frames(state, renderer, m);
}
BENCHMARK(BM_DrawBackend)->Apply(backend_cases);

// BM_DrawBackend's cases with the frames pipelined (two in flight).
void BM_DrawBackendPipelined(benchmark::State& state) {
  const Model& m = model(8);
  render::Renderer renderer(m.rest, m.field, 1.0, backend_options(state));
  name_antialiasing(state, 2);
  name_backend(state, renderer, "pipelined, ");
  time_pipelined_frames(state, renderer, m);
}
BENCHMARK(BM_DrawBackendPipelined)->Apply(backend_cases);

// The empty scene pipelined (arguments: backend, MSAA samples, FXAA): the cost of getting pixels
// out when read-backs overlap.
void BM_ClearReadbackPipelined(benchmark::State& state) {
  render::RenderOptions o = options(state, 1);
  o.gl = state.range(0) ? render::GlBackend::egl : render::GlBackend::osmesa;
  render::Renderer renderer(mesh::TriangleMesh{}, {}, 1.0, o);
  name_antialiasing(state, 1);
  state.SetLabel("pipelined, " + renderer.gl_backend() + ", " + renderer.gl_renderer());
  run_pipelined_frames(state, renderer);  // nothing to draw: s changes nothing
}
BENCHMARK(BM_ClearReadbackPipelined)->Args({1, 0, 0})->Args({1, 0, 1})->Unit(benchmark::kMillisecond)->UseRealTime();

// PNG encoding (fast, the sink's setting) of a 1920x1080 frame of the 1.3M-triangle mesh, timed
// apart from the drawing above.
void BM_PngEncodeFullHd(benchmark::State& state) {
  const Model& m = model(8);
  render::RenderOptions o;
  o.width = 1920;
  o.height = 1080;
  o.camera = render::CameraPreset::oblique;
  render::Renderer renderer(m.rest, m.field, 1.0, o);
  const render::Image image = renderer.render(1.0);
  std::size_t bytes = 0;
  for (auto _ : state) {
    const auto encoded = render::encode_png(image, {.fast = true});
    bytes = encoded.size();
    benchmark::DoNotOptimize(encoded.data());
  }
  state.counters["kilobytes"] = static_cast<double>(bytes) / 1024.0;
}
BENCHMARK(BM_PngEncodeFullHd)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
