// The renderer against independent oracles: the CPU-displaced mesh, exact normals, projected
// bounds, the silhouette's growth and the anatomical orientation of the presets.
#include <gtest/gtest.h>

#include <tbb/global_control.h>

#include <Eigen/Geometry>
#include <array>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <memory>
#include <span>

#include "pneuma/core/error.h"
#include "pneuma/render/compare.h"
#include "pneuma/render/png_sink.h"
#include "pneuma/render/renderer.h"
#include "render_fixture.h"
#include "test_support.h"

using namespace pneuma;
using test::make_lung_stand_in;

namespace {

render::RenderOptions small_options(render::CameraPreset camera = render::CameraPreset::anterior) {
  render::RenderOptions o;
  o.width = 160;
  o.height = 120;
  o.camera = camera;
  return o;
}

std::vector<Eigen::Vector3d> displaced(const test::LungStandIn& lung, double s) {
  std::vector<Eigen::Vector3d> x(lung.rest.vertices);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] += s * lung.field[i];
  return x;
}

}  // namespace

TEST(NormalTerms, GiveTheAreaWeightedNormalsOfEveryFrame) {
  const auto lung = make_lung_stand_in(2);
  const render::NormalTerms terms = render::normal_terms(lung.rest, lung.field);
  for (double s : {-0.7, 0.0, 0.5, 1.3, 4.0}) {
    mesh::TriangleMesh frame{displaced(lung, s), lung.rest.triangles};
    const auto expected = mesh::vertex_normals(frame);
    for (std::size_t i = 0; i < expected.size(); ++i) {
      const Eigen::Vector3d n = (terms.n0[i] + s * terms.n1[i] + s * s * terms.n2[i]).normalized();
      ASSERT_NEAR((n - expected[i]).norm(), 0.0, 1e-12) << "vertex " << i << " at s = " << s;
    }
  }
}

// The oracle: displacing on the CPU and uploading the frame as the rest mesh (u = 0) must give
// the image the vertex shader gives, under the same camera.
TEST(Renderer, ShaderDisplacementEqualsCpuDisplacement) {
  const auto lung = make_lung_stand_in();
  const std::vector<Eigen::Vector3d> zero(lung.field.size(), Eigen::Vector3d::Zero());
  for (auto preset : {render::CameraPreset::anterior, render::CameraPreset::oblique}) {
    render::Renderer shader(lung.rest, lung.field, 1.5, small_options(preset));
    for (double s : {-0.6, 0.5, 1.0, 1.5}) {
      const render::Image gpu = shader.render(s);
      render::Renderer cpu(mesh::TriangleMesh{displaced(lung, s), lung.rest.triangles}, zero, 0.0,
                           small_options(preset));
      cpu.set_camera(shader.camera());
      const render::Image expected = cpu.render(0.0);
      const render::Difference d = render::compare(gpu, expected);
      EXPECT_TRUE(d.within(render::default_tolerance))
          << render::camera_preset_name(preset) << " s = " << s << ": " << d.pixels_over << " pixels differ";
      EXPECT_LT(d.mean[0] + d.mean[1] + d.mean[2], 0.5) << render::camera_preset_name(preset) << " s = " << s;
      // And the frame really moved: the rest image differs.
      EXPECT_FALSE(render::compare(shader.render(0.0), gpu).within(render::default_tolerance)) << "s = " << s;
    }
  }
}

// Two surfaces (two lungs) in one image, each at its own s: the image of the union displaced on
// the CPU, rendered still; a wrong number of scales is refused.
TEST(Renderer, TwoSurfacesEachMoveWithTheirOwnScale) {
  test::LungStandIn left = make_lung_stand_in(3);
  for (Eigen::Vector3d& p : left.rest.vertices) p.x() += 0.07;  // left of the midline (LPS: +x)
  test::LungStandIn right = left;                               // its mirror image across the midline
  for (Eigen::Vector3d& p : right.rest.vertices) p.x() = -p.x();
  for (Eigen::Vector3d& u : right.field) u.x() = -u.x();
  for (mesh::Triangle& t : right.rest.triangles) std::swap(t[1], t[2]);  // mirrored: keep it outward
  const std::array<render::RenderPart, 2> parts{render::RenderPart{&right.rest, &right.field, {0.0, 1.5}},
                                                render::RenderPart{&left.rest, &left.field, {0.0, 1.5}}};
  render::Renderer shader(parts, small_options(render::CameraPreset::anterior));
  const std::array<double, 2> s{1.5, 0.2};
  const render::Image gpu = shader.render(std::span<const double>(s));
  mesh::TriangleMesh both{displaced(right, s[0]), right.rest.triangles};
  const auto offset = static_cast<std::uint32_t>(both.vertices.size());
  for (const Eigen::Vector3d& p : displaced(left, s[1])) both.vertices.push_back(p);
  for (mesh::Triangle t : left.rest.triangles) {
    for (auto& v : t) v += offset;
    both.triangles.push_back(t);
  }
  const std::vector<Eigen::Vector3d> zero(both.vertex_count(), Eigen::Vector3d::Zero());
  render::Renderer cpu(both, zero, 0.0, small_options(render::CameraPreset::anterior));
  cpu.set_camera(shader.camera());
  const render::Difference d = render::compare(gpu, cpu.render(0.0));
  EXPECT_TRUE(d.within(render::default_tolerance)) << d.pixels_over << " pixels differ";
  // Each surface has its own s: both at 1.5 is another image.
  const std::array<double, 2> same{1.5, 1.5};
  EXPECT_FALSE(render::compare(shader.render(std::span<const double>(same)), gpu).within(render::default_tolerance));
  EXPECT_LE(shader.drawn_triangles(0.0), right.rest.triangle_count() + left.rest.triangle_count());
  const std::array<double, 1> one{1.0};
  EXPECT_THROW(shader.render(std::span<const double>(one)), ValueError);
}

TEST(Renderer, SilhouetteGrowsWithScale) {
  const auto lung = make_lung_stand_in();
  const auto options = small_options();
  render::Renderer renderer(lung.rest, lung.field, 2.0, options);
  const render::Rgba background = test::to_rgba8(options.background);
  std::size_t previous = 0;
  for (double s : {0.0, 0.5, 1.0, 1.5, 2.0}) {
    const std::size_t area = test::silhouette_pixels(renderer.render(s), background);
    EXPECT_GT(area, previous) << "s = " << s;
    previous = area;
  }
  EXPECT_GT(previous, 1000u);
}

TEST(Renderer, EmptySceneIsBackgroundOnly) {
  auto options = small_options();
  options.background = {0.2, 0.5, 0.9};
  render::Renderer renderer(mesh::TriangleMesh{}, {}, 1.0, options);
  const render::Image image = renderer.render(1.0);
  ASSERT_EQ(image.width, 160);
  ASSERT_EQ(image.height, 120);
  EXPECT_EQ(test::silhouette_pixels(image, test::to_rgba8(options.background)), 0u);
}

TEST(Renderer, FramingFitsTheBoundsOfTheLargestFrame) {
  const auto lung = make_lung_stand_in(3);
  for (auto preset :
       {render::CameraPreset::anterior, render::CameraPreset::posterior, render::CameraPreset::left_lateral,
        render::CameraPreset::right_lateral, render::CameraPreset::oblique}) {
    const auto options = small_options(preset);
    render::Renderer renderer(lung.rest, lung.field, 2.0, options);
    const auto& [lo, hi] = renderer.framed_bounds();
    // The bounds hold the largest frame.
    for (const auto& p : displaced(lung, 2.0)) {
      ASSERT_TRUE((p.array() >= lo.array() - 1e-15).all() && (p.array() <= hi.array() + 1e-15).all());
    }
    const Eigen::Matrix4d clip =
        render::projection_matrix(renderer.camera(), 160.0 / 120.0) * render::view_matrix(renderer.camera());
    double largest = 0.0;
    for (int corner = 0; corner < 8; ++corner) {
      const Eigen::Vector4d p((corner & 1) ? hi.x() : lo.x(), (corner & 2) ? hi.y() : lo.y(),
                              (corner & 4) ? hi.z() : lo.z(), 1.0);
      const Eigen::Vector4d c = clip * p;
      ASSERT_GT(c.w(), 0.0);
      largest = std::max({largest, std::abs(c.x() / c.w()), std::abs(c.y() / c.w())});
      EXPECT_LT(std::abs(c.z() / c.w()), 1.0) << "inside the depth range";
    }
    EXPECT_NEAR(largest, 1.0 / options.margin, 1e-9)
        << render::camera_preset_name(preset) << ": the tightest fit with the margin";
  }
}

// A chest-radiograph view: the patient's left (+x) on the image's right from the front, on
// the left from the back; superior (+z) up in every preset.
TEST(Renderer, PresetsFollowThePatientsAxes) {
  mesh::TriangleMesh scene = mesh::make_icosphere(0.05, 2);
  mesh::TriangleMesh marker = mesh::make_icosphere(0.02, 2);
  const auto offset = static_cast<std::uint32_t>(scene.vertices.size());
  for (const auto& v : marker.vertices) scene.vertices.push_back(v + Eigen::Vector3d(0.1, 0.0, 0.1));  // left, superior
  for (const auto& t : marker.triangles) scene.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  const std::vector<Eigen::Vector3d> zero(scene.vertices.size(), Eigen::Vector3d::Zero());
  struct Expect {
    render::CameraPreset preset;
    bool marker_right;
  };
  for (const Expect& e :
       {Expect{render::CameraPreset::anterior, true}, Expect{render::CameraPreset::posterior, false}}) {
    auto options = small_options(e.preset);
    render::Renderer renderer(scene, zero, 0.0, options);
    const render::Image image = renderer.render(0.0);
    const render::Rgba background = test::to_rgba8(options.background);
    // The marker is the only thing in the upper quarter of the image.
    double sum_x = 0.0;
    int count = 0;
    for (int y = 0; y < image.height / 4; ++y) {
      for (int x = 0; x < image.width; ++x) {
        if (!(image.at(x, y) == background)) {
          sum_x += x;
          ++count;
        }
      }
    }
    ASSERT_GT(count, 20) << render::camera_preset_name(e.preset);
    EXPECT_EQ(sum_x / count > image.width / 2.0, e.marker_right) << render::camera_preset_name(e.preset);
  }
}

TEST(Renderer, BadModelsAndOptionsAreRefused) {
  const auto lung = make_lung_stand_in(1);
  auto field = lung.field;
  field.pop_back();
  EXPECT_THROW(render::Renderer(lung.rest, field, 1.0), InputError);
  auto broken = lung.rest;
  broken.triangles[3][1] = 9999;
  EXPECT_THROW(render::Renderer(broken, lung.field, 1.0), InputError);
  auto options = small_options();
  options.width = 0;
  EXPECT_THROW(render::Renderer(lung.rest, lung.field, 1.0, options), UsageError);
}

TEST(Renderer, ReusedOutputImageGivesTheSamePixels) {
  const auto lung = make_lung_stand_in(3);
  render::Renderer renderer(lung.rest, lung.field, 1.0, small_options());
  render::Image reused;
  renderer.render(0.3, reused);
  renderer.render(0.9, reused);
  EXPECT_EQ(reused.rgba, renderer.render(0.9).rgba);
}

TEST(Renderer, FramesTheWholeRangeOfScales) {
  const auto lung = make_lung_stand_in(3);
  render::Renderer renderer(lung.rest, lung.field, render::ScaleRange{-1.0, 2.0}, small_options());
  const auto& [lo, hi] = renderer.framed_bounds();
  for (double s : {-1.0, 0.0, 2.0}) {
    for (const auto& p : displaced(lung, s)) {
      ASSERT_TRUE((p.array() >= lo.array() - 1e-15).all() && (p.array() <= hi.array() + 1e-15).all()) << "s = " << s;
    }
  }
  double max_field = 0.0;
  for (const auto& u : lung.field) max_field = std::max(max_field, u.norm());
  EXPECT_DOUBLE_EQ(renderer.overlay_max_m(), 2.0 * max_field);
  EXPECT_THROW(render::Renderer(lung.rest, lung.field, render::ScaleRange{1.0, 0.0}), InputError);
}

TEST(PngFrameSink, WritesEveryNthFrameAndNothingElse) {
  const auto lung = make_lung_stand_in(3);
  const model::Model model(model::make_model(lung.rest, lung.field, 1e-4));
  test::TempDir dir;
  render::PngSinkOptions options;
  options.render = small_options();
  options.every = 2;
  render::PngFrameSink sink(dir / "frames", options);
  sink.begin(model, outputs::RunInfo{5, 30.0, {-0.5}, {1.0}, dir.path()});
  const double scales[] = {-0.5, 0.25, 1.0, 0.1, 0.25};
  model::Frame frame(model);
  for (std::size_t k = 0; k < 5; ++k) {
    model::advance(model, {k, 0.0, 0.0, {scales[k]}}, frame);
    sink.frame(model, frame);
  }
  const auto written = sink.finish(model, {});
  ASSERT_EQ(written.size(), 3u);
  EXPECT_EQ(written[2], dir / "frames" / "frame_00004.png");
  EXPECT_EQ(dir.files().size(), 3u) << "no temporaries left";
  // Each file is the renderer's image of its frame.
  render::Renderer renderer(lung.rest, lung.field, render::ScaleRange{-0.5, 1.0}, small_options());
  EXPECT_EQ(render::read_png(written[0]).rgba, renderer.render(-0.5).rgba);
  EXPECT_EQ(render::read_png(written[1]).rgba, renderer.render(1.0).rgba);
  EXPECT_EQ(render::read_png(written[2]).rgba, renderer.render(0.25).rgba);
}

// Pipelined frames (two in flight) come back in the order submitted, each the image that
// render() gives on its own, the overlay's legend included.
TEST(Renderer, PipelinedFramesAreTheFramesRenderGives) {
  const auto lung = make_lung_stand_in(3);
  render::RenderOptions options = small_options(render::CameraPreset::oblique);
  options.overlay_magnitude = true;
  render::Renderer renderer(lung.rest, lung.field, render::ScaleRange{-0.5, 1.0}, options);
  const std::vector<double> scales = {0.0, 1.0, -0.5, 0.3, 0.7};
  std::vector<render::Image> expected(scales.size());
  for (std::size_t k = 0; k < scales.size(); ++k) renderer.render(scales[k], expected[k]);
  ASSERT_NE(expected[0].rgba, expected[1].rgba);  // the frames differ, so the order shows
  std::vector<render::Image> pipelined;
  for (double s : scales) {
    if (renderer.frames_in_flight() == render::Renderer::max_frames_in_flight)
      renderer.collect(pipelined.emplace_back());
    renderer.submit(s);
  }
  while (renderer.frames_in_flight() > 0) renderer.collect(pipelined.emplace_back());
  ASSERT_EQ(pipelined.size(), scales.size());
  for (std::size_t k = 0; k < scales.size(); ++k) EXPECT_EQ(pipelined[k].rgba, expected[k].rgba) << "frame " << k;
}

TEST(Renderer, PipelineRefusesAThirdFrameInFlightAndAnEmptyCollect) {
  const auto lung = make_lung_stand_in(2);
  render::Renderer renderer(lung.rest, lung.field, 1.0, small_options());
  render::Image image;
  EXPECT_THROW(renderer.collect(image), Error);
  renderer.submit(0.2);
  EXPECT_THROW(renderer.render(0.5, image), Error);  // render() needs none in flight
  renderer.submit(0.4);
  EXPECT_THROW(renderer.submit(0.6), Error);
  EXPECT_EQ(renderer.frames_in_flight(), 2u);
  render::Image second;
  renderer.collect(image);
  renderer.collect(second);
  EXPECT_EQ(renderer.frames_in_flight(), 0u);
  EXPECT_THROW(renderer.collect(image), Error);
  EXPECT_EQ(image.rgba, renderer.render(0.2).rgba);
  EXPECT_EQ(second.rgba, renderer.render(0.4).rgba);
}

// The pre-cull leaves out the triangles that face away from the camera at every scale of the
// range; OpenGL's own back-face culling is the oracle: with every triangle drawn
// (PNEUMA_DRAW_ALL_TRIANGLES=1) the images are the same, bit for bit, at any s of the range and
// from every side. About half of a closed surface faces away.
TEST(Renderer, PreCullGivesTheImageOfDrawingEveryTriangle) {
  const auto lung = make_lung_stand_in(4);
  const render::ScaleRange range{-0.5, 1.5};
  for (auto camera :
       {render::CameraPreset::anterior, render::CameraPreset::oblique, render::CameraPreset::left_lateral}) {
    render::Renderer culled(lung.rest, lung.field, range, small_options(camera));
    ::setenv("PNEUMA_DRAW_ALL_TRIANGLES", "1", 1);
    render::Renderer every(lung.rest, lung.field, range, small_options(camera));
    ::unsetenv("PNEUMA_DRAW_ALL_TRIANGLES");
    const std::size_t total = lung.rest.triangle_count();
    EXPECT_EQ(every.drawn_triangles(0.0), total);
    EXPECT_GT(culled.drawn_triangles(0.0), total * 3 / 10);
    EXPECT_LT(culled.drawn_triangles(0.0), total * 7 / 10);
    for (double s : {-0.5, 0.0, 0.7, 1.5}) EXPECT_EQ(culled.render(s).rgba, every.render(s).rgba) << "s = " << s;
    // Outside the range the pre-cull does not hold: every triangle is drawn.
    EXPECT_EQ(culled.drawn_triangles(3.0), total);
    EXPECT_EQ(culled.render(3.0).rgba, every.render(3.0).rgba);
  }
  render::RenderOptions no_culling = small_options();
  no_culling.cull_back_faces = false;
  EXPECT_EQ(render::Renderer(lung.rest, lung.field, range, no_culling).drawn_triangles(0.0),
            lung.rest.triangle_count());
}

namespace {

// Runs a PngFrameSink over `scales` (every frame) under a TBB thread limit; returns the files.
std::vector<std::filesystem::path> write_sequence(const test::LungStandIn& lung, const std::filesystem::path& folder,
                                                  const std::vector<double>& scales, std::size_t threads) {
  const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  const model::Model model(model::make_model(lung.rest, lung.field, 1e-4));
  render::PngSinkOptions options;
  options.render = small_options(render::CameraPreset::oblique);
  render::PngFrameSink sink(folder, options);
  sink.begin(model, outputs::RunInfo{scales.size(), 30.0, {0.0}, {1.0}, folder});
  model::Frame frame(model);
  for (std::size_t k = 0; k < scales.size(); ++k) {
    model::advance(model, {k, 0.0, 0.0, {scales[k]}}, frame);
    sink.frame(model, frame);
  }
  return sink.finish(model, {});
}

std::string file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

// Frames are encoded on worker threads, several in flight: every file is still its own frame's
// image, and the bytes do not depend on the thread count.
TEST(PngFrameSink, ThreadedEncodingGivesTheSameBytesAtAnyThreadCount) {
  const auto lung = make_lung_stand_in(3);
  test::TempDir dir;
  std::vector<double> scales(12);
  for (std::size_t k = 0; k < scales.size(); ++k) scales[k] = static_cast<double>(k) / 11.0;
  const auto one = write_sequence(lung, dir / "one", scales, 1);
  const auto four = write_sequence(lung, dir / "four", scales, 4);
  ASSERT_EQ(one.size(), scales.size());
  ASSERT_EQ(four.size(), scales.size());
  render::Renderer renderer(lung.rest, lung.field, render::ScaleRange{0.0, 1.0},
                            small_options(render::CameraPreset::oblique));
  for (std::size_t k = 0; k < scales.size(); ++k) {
    EXPECT_EQ(one[k].filename(), four[k].filename());
    EXPECT_EQ(file_bytes(one[k]), file_bytes(four[k])) << one[k].filename();
    EXPECT_EQ(render::read_png(four[k]).rgba, renderer.render(scales[k]).rgba) << "frame " << k;
  }
}

// A frame that cannot be written (its folder is a file) fails the run with the file's name, on
// one line, whichever thread wrote it; nothing is left behind.
TEST(PngFrameSink, AFrameThatCannotBeWrittenIsAnIoError) {
  const auto lung = make_lung_stand_in(2);
  test::TempDir dir;
  const auto blocker = dir.write("frames", "a file where the frames' folder should be");
  try {
    write_sequence(lung, blocker, {0.0, 0.5, 1.0}, 4);
    FAIL() << "expected an IoError";
  } catch (const IoError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("frame_0000"), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
  EXPECT_EQ(dir.files(), std::vector<std::string>{"frames"});
}

// FXAA (post-process anti-aliasing) leaves flat neighbourhoods alone (an empty scene, smooth
// shading), works mostly at the silhouette, and does smooth it.
TEST(Renderer, FxaaChangesOnlyContrastedPixelsMostlyAtTheSilhouette) {
  const auto lung = make_lung_stand_in();
  auto options = small_options(render::CameraPreset::oblique);
  options.msaa_samples = 0;
  render::Renderer plain(lung.rest, lung.field, 1.0, options);
  options.fxaa = true;
  render::Renderer fxaa(lung.rest, lung.field, 1.0, options);
  const render::Image a = plain.render(1.0), b = fxaa.render(1.0);
  const render::Rgba background = test::to_rgba8(options.background);
  auto pixel = [&](int x, int y) { return a.at(std::clamp(x, 0, a.width - 1), std::clamp(y, 0, a.height - 1)); };
  int changed = 0, at_silhouette = 0;
  for (int y = 0; y < a.height; ++y) {
    for (int x = 0; x < a.width; ++x) {
      if (a.at(x, y) == b.at(x, y)) continue;
      ++changed;
      int range = 0;
      bool silhouette = false;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const render::Rgba p = pixel(x + dx, y + dy), c = a.at(x, y);
          range = std::max({range, std::abs(p.r - c.r), std::abs(p.g - c.g), std::abs(p.b - c.b)});
          silhouette |= (p == background) != (c == background);
        }
      }
      // Below FXAA's contrast threshold (1/24 in luma) a pixel must stay as it was.
      EXPECT_GE(range, 8) << "pixel " << x << ", " << y << " changed in a flat neighbourhood";
      at_silhouette += silhouette ? 1 : 0;
    }
  }
  EXPECT_GT(changed, 50) << "FXAA smoothed the silhouette";
  EXPECT_GT(at_silhouette, changed * 3 / 4);

  render::Renderer empty(mesh::TriangleMesh{}, {}, 1.0, options);
  EXPECT_EQ(test::silhouette_pixels(empty.render(0.0), background), 0u);
}

TEST(Renderer, EglAndOsmesaGiveTheSameImage) {
  // Both backends on this machine drive Mesa's llvmpipe through the same shaders: the same
  // pixels (a GPU through EGL would differ in the last bits; the golden tests allow for that).
  const test::LungStandIn lung = test::make_lung_stand_in(4);
  render::RenderOptions options;
  options.width = 160;
  options.height = 120;
  options.gl = render::GlBackend::osmesa;
  render::Renderer osmesa(lung.rest, lung.field, 1.0, options);
  EXPECT_EQ(osmesa.gl_backend(), "OSMesa");
  options.gl = render::GlBackend::egl;
  std::unique_ptr<render::Renderer> egl;
  try {
    egl = std::make_unique<render::Renderer>(lung.rest, lung.field, 1.0, options);
  } catch (const UnsupportedError& e) {
    GTEST_SKIP() << e.what();
  }
  EXPECT_EQ(egl->gl_backend().rfind("EGL", 0), 0u) << egl->gl_backend();
  EXPECT_EQ(egl->gl_version().rfind("4.", 0), 0u) << egl->gl_version();  // a 4.x core context
  const render::Image a = osmesa.render(0.7), b = egl->render(0.7);
  const render::Difference d = render::compare(a, b, 2);
  EXPECT_TRUE(d.within({2, 0.001})) << d.pixels_over << " pixels differ";
}

TEST(GlBackend, ParsesTheCommandLineNames) {
  render::GlBackend b = render::GlBackend::osmesa;
  EXPECT_TRUE(render::parse_gl_backend("auto", b));
  EXPECT_EQ(b, render::GlBackend::automatic);
  EXPECT_TRUE(render::parse_gl_backend("egl", b));
  EXPECT_EQ(b, render::GlBackend::egl);
  EXPECT_TRUE(render::parse_gl_backend("osmesa", b));
  EXPECT_EQ(b, render::GlBackend::osmesa);
  EXPECT_FALSE(render::parse_gl_backend("vulkan", b));
}
