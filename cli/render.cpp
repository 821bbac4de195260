// pneuma render --compare A.png B.png: how far two images are apart (regression checks).
// pneuma render --info: which OpenGL the renderer gets on this machine.
// (pneuma render SCENARIO.yaml -o DIR comes with the scenario runner.)
#include <fmt/format.h>

#include <memory>
#include <string>
#include <vector>

#include "commands.h"
#include "pneuma/core/error.h"
#include "pneuma/core/units.h"
#include "pneuma/render/compare.h"
#include "pneuma/render/image.h"
#include "pneuma/render/renderer.h"

namespace pneuma::cli {
namespace {

struct RenderCliOptions {
  std::vector<std::string> compare;
  std::string diff;
  int threshold = render::default_tolerance.pixel_threshold;
  double max_share = render::default_tolerance.max_share_over;
  bool info = false;
  render::GlBackend gl = render::GlBackend::automatic;
  bool quiet = false;
};

// Exit status: 0 when the images match within the tolerance, 1 when they differ (also in size).
void run_compare(const RenderCliOptions& o) {
  const std::string& path_a = o.compare[0];
  const std::string& path_b = o.compare[1];
  const render::Image a = render::read_png(path_a);
  const render::Image b = render::read_png(path_b);
  if (a.width != b.width || a.height != b.height) {
    throw Error(ExitCode::failure, fmt::format("{}: image is {}x{}, but {} is {}x{}", path_b, b.width, b.height, path_a,
                                               a.width, a.height));
  }
  const render::Difference d = render::compare(a, b, o.threshold);
  if (!o.diff.empty()) render::write_png(o.diff, d.image);
  const bool match = d.within({o.threshold, o.max_share});
  if (!o.quiet) {
    fmt::print("{}x{} pixels; max difference R {} G {} B {} A {}; mean R {:.3f} G {:.3f} B {:.3f} A {:.3f}\n", a.width,
               a.height, d.max[0], d.max[1], d.max[2], d.max[3], d.mean[0], d.mean[1], d.mean[2], d.mean[3]);
    fmt::print("{} pixels ({:.3f} %) differ by more than {}; tolerance {:.3f} %: {}\n", d.pixels_over,
               100.0 * d.share_over(), o.threshold, 100.0 * o.max_share, match ? "match" : "DIFFER");
    if (!o.diff.empty()) fmt::print("wrote {}\n", o.diff);
  }
  if (!match) throw Error(ExitCode::failure, fmt::format("{} and {} differ", path_a, path_b));
}

void run_info(render::GlBackend gl) {
  mesh::TriangleMesh empty;
  render::RenderOptions options;
  options.width = options.height = 16;
  options.gl = gl;
  const render::Renderer renderer(empty, {}, 0.0, options);
  fmt::print("backend {}\nOpenGL {}\nrenderer {}\nanti-aliasing {} samples\n", renderer.gl_backend(),
             renderer.gl_version(), renderer.gl_renderer(), renderer.msaa_samples());
}

void run_render(const RenderCliOptions& o) {
  if (o.info) return run_info(o.gl);
  if (o.compare.empty()) {
    throw UsageError(
        "pneuma render: give --compare A.png B.png or --info (rendering a scenario comes with the runner)");
  }
  run_compare(o);
}

}  // namespace

void register_render(CLI::App& app) {
  auto options = std::make_shared<RenderCliOptions>();
  CLI::App* cmd = app.add_subcommand("render", "Headless rendering: compare images, report the OpenGL in use");
  cmd->add_option("--compare", options->compare,
                  "Compare two PNG images: exit 0 when they match within the tolerance, 1 when they differ")
      ->expected(2)
      ->type_name("A.png B.png");
  cmd->add_option("--diff", options->diff, "With --compare: write a difference image (differing pixels in red)");
  cmd->add_option("--threshold", options->threshold,
                  "With --compare: a pixel differs when a channel differs by more than this (0-255)")
      ->check(CLI::Range(0, 255))
      ->capture_default_str();
  cmd->add_option_function<std::string>(
         "--max-share",
         [options](const std::string& text) {
           try {
             options->max_share = units::parse(text, units::kind::fraction);
           } catch (const units::UnitError& e) {
             throw UsageError(std::string("pneuma: --max-share: ") + e.what());
           }
         },
         "With --compare: the largest share of differing pixels that still matches (default 0.5 %)")
      ->type_name("<0.5 %>");
  cmd->add_option_function<std::string>(
         "--gl",
         [options](const std::string& text) {
           if (!render::parse_gl_backend(text, options->gl)) {
             throw UsageError("pneuma: --gl: expected egl, osmesa or auto, got '" + text + "'");
           }
         },
         "Where the OpenGL context comes from: egl (GPU, or Mesa's llvmpipe), osmesa, or auto (EGL when it "
         "works, else OSMesa; also PNEUMA_GL in the environment)")
      ->type_name("egl|osmesa|auto");
  cmd->add_flag("--info", options->info, "Print the OpenGL version and renderer that rendering gets here");
  cmd->add_flag("-q,--quiet", options->quiet, "Print nothing (the exit status tells)");
  add_examples(*cmd, {"pneuma render --info --gl egl",
                      "pneuma render --compare expected.png out/demo/png/frame_00000.png --diff diff.png"});
  cmd->callback([options] { run_render(*options); });
}

}  // namespace pneuma::cli
