// `pneuma render` end to end: --compare results and exit codes, one-line errors, --info.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <set>
#include <string>

#include "pneuma/render/image.h"
#include "test_support.h"

using namespace pneuma;
using test::run_pneuma;
using test::TempDir;

namespace {

render::Image checker(int w, int h, std::uint8_t level) {
  render::Image image(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const auto v = static_cast<std::uint8_t>(((x / 8 + y / 8) % 2) ? level : 40);
      image.set(x, y, {v, v, v, 255});
    }
  }
  return image;
}

}  // namespace

TEST(RenderCli, IdenticalImagesMatch) {
  TempDir dir;
  render::write_png(dir / "a.png", checker(64, 48, 200));
  render::write_png(dir / "b.png", checker(64, 48, 200));
  const auto r = run_pneuma({"render", "--compare", (dir / "a.png").string(), (dir / "b.png").string()});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(r.err.empty()) << r.err;
  EXPECT_EQ(r.out, "64x48 pixels; max difference R 0 G 0 B 0 A 0; mean R 0.000 G 0.000 B 0.000 A 0.000\n"
                   "0 pixels (0.000 %) differ by more than 8; tolerance 0.500 %: match\n");
}

TEST(RenderCli, DifferentImagesExitOneAndWriteTheDifference) {
  TempDir dir;
  const auto a = dir / "a.png", b = dir / "b.png", diff = dir / "out" / "diff.png";
  render::write_png(a, checker(64, 48, 200));
  render::write_png(b, checker(64, 48, 100));  // half the pixels 100 levels darker
  auto r = run_pneuma({"render", "--compare", a.string(), b.string(), "--diff", diff.string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, a.string() + " and " + b.string() + " differ\n");
  EXPECT_NE(r.out.find("1536 pixels (50.000 %) differ by more than 8; tolerance 0.500 %: DIFFER"), std::string::npos)
      << r.out;
  EXPECT_EQ(render::read_png(diff).width, 64);
  // A looser tolerance accepts them.
  r = run_pneuma({"render", "--compare", a.string(), b.string(), "--threshold", "100", "-q"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  r = run_pneuma({"render", "--compare", a.string(), b.string(), "--max-share", "60 %", "-q"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(r.out.empty());
}

struct BadCompare {
  const char* name;
  int exit_code;
  const char* message;  // {a} and {b} stand for the paths
};

class RenderCliErrors : public ::testing::TestWithParam<BadCompare> {};

TEST_P(RenderCliErrors, OneLineAndExitCode) {
  TempDir dir;
  const auto a = dir / "a.png";
  render::write_png(a, checker(160, 120, 200));
  std::filesystem::path b = dir / "b.png";
  const std::string name = GetParam().name;
  if (name == "missing") b = dir / "missing.png";
  if (name == "not_png") b = dir.write("b.png", "P3 1 1 255 0 0 0\n");
  if (name == "size") render::write_png(b, checker(100, 80, 200));
  const auto r = run_pneuma({"render", "--compare", a.string(), b.string()});
  std::string expected = GetParam().message;
  for (auto [key, value] : {std::pair{std::string("{a}"), a.string()}, std::pair{std::string("{b}"), b.string()}}) {
    for (auto at = expected.find(key); at != std::string::npos; at = expected.find(key)) expected.replace(at, 3, value);
  }
  EXPECT_EQ(r.exit_code, GetParam().exit_code);
  EXPECT_EQ(r.err, expected + "\n");
  EXPECT_TRUE(r.out.empty()) << r.out;
}

INSTANTIATE_TEST_SUITE_P(Compare, RenderCliErrors,
                         ::testing::Values(BadCompare{"missing", 4, "{b}: cannot open file"},
                                           BadCompare{"not_png", 3, "{b}: not a PNG image (no PNG signature)"},
                                           BadCompare{"size", 1, "{b}: image is 100x80, but {a} is 160x120"}),
                         [](const auto& test_info) { return std::string(test_info.param.name); });

TEST(RenderCli, CompareNeedsTwoFilesAndAKnownShare) {
  TempDir dir;
  auto r = run_pneuma({"render", "--compare", (dir / "a.png").string()});
  EXPECT_EQ(r.exit_code, 2);
  r = run_pneuma({"render"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err,
            "pneuma render: give --compare A.png B.png or --info (rendering a scenario comes with the runner)\n");
  render::write_png(dir / "a.png", checker(8, 8, 200));
  r = run_pneuma({"render", "--compare", (dir / "a.png").string(), (dir / "a.png").string(), "--max-share", "lots"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err.rfind("pneuma: --max-share: ", 0), 0u) << r.err;
}

TEST(RenderCli, InfoNamesTheOpenGlInUse) {
  const auto r = run_pneuma({"render", "--info"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("Core Profile"), std::string::npos) << r.out;
}

// Without OSMesa: one line that says what to install, exit 5.
TEST(RenderCli, NoOpenGlContextSaysWhatToInstall) {
  ::setenv("PNEUMA_OSMESA_LIBRARY", "/nonexistent/libOSMesa.so.8", 1);
  ::setenv("PNEUMA_EGL_LIBRARY", "/nonexistent/libEGL.so.1", 1);
  const auto osmesa = run_pneuma({"render", "--info", "--gl", "osmesa"});
  const auto egl = run_pneuma({"render", "--info", "--gl", "egl"});
  const auto neither = run_pneuma({"render", "--info"});
  ::unsetenv("PNEUMA_OSMESA_LIBRARY");
  ::unsetenv("PNEUMA_EGL_LIBRARY");
  EXPECT_EQ(osmesa.exit_code, 5);
  EXPECT_EQ(
      osmesa.err,
      "render: no OpenGL context: cannot load /nonexistent/libOSMesa.so.8; install the libosmesa6 package (Mesa's "
      "off-screen OpenGL with llvmpipe)\n");
  EXPECT_EQ(egl.exit_code, 5);
  EXPECT_EQ(
      egl.err,
      "render: no OpenGL context from EGL: cannot load /nonexistent/libEGL.so.1; install the libegl1, libegl-mesa0 "
      "and libgl1-mesa-dri packages (EGL with Mesa; on NVIDIA the driver's EGL)\n");
  EXPECT_EQ(neither.exit_code, 5);
  EXPECT_EQ(neither.err,
            "render: no OpenGL context: EGL: cannot load /nonexistent/libEGL.so.1; OSMesa: cannot load "
            "/nonexistent/libOSMesa.so.8; install the libegl1, libegl-mesa0 and libgl1-mesa-dri packages (or "
            "libosmesa6)\n");
}

TEST(RenderCli, InfoNamesTheBackend) {
  const auto osmesa = run_pneuma({"render", "--info", "--gl", "osmesa"});
  EXPECT_EQ(osmesa.exit_code, 0);
  EXPECT_EQ(osmesa.out.rfind("backend OSMesa\n", 0), 0u) << osmesa.out;
  const auto egl = run_pneuma({"render", "--info", "--gl", "egl"});
  if (egl.exit_code == 5) GTEST_SKIP() << egl.err;
  EXPECT_EQ(egl.exit_code, 0);
  EXPECT_EQ(egl.out.rfind("backend EGL (", 0), 0u) << egl.out;
  const auto bad = run_pneuma({"render", "--info", "--gl", "vulkan"});
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_EQ(bad.err, "pneuma: --gl: expected egl, osmesa or auto, got 'vulkan'\n");
}

// `pneuma run` with a `png` output: the renderer as a frame sink, end to end.
TEST(RenderCli, RunWritesPngFramesListedInTheManifest) {
  TempDir dir;
  const auto scenario = dir.write("s.yaml", R"(name: png-check
duration: 4 s
frames:
  rate: 5 Hz
mesh:
  phantom: right
  edge: 15 mm
  share: 55 %
field:
  tissue: healthy-upright
  cache: off
physiology:
  preset: healthy-adult
  output_rate: 100 Hz
outputs:
  physiology_csv: {enabled: false}
  gltf: {enabled: false}
  hdf5: {enabled: false}
  png: {width: 64, height: 48, camera: oblique, every: 5}
)");
  const auto out = dir / "out";
  const auto r = run_pneuma({"run", scenario.string(), "-o", out.string(), "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::vector<render::Image> frames;
  for (const char* name : {"frame_00000.png", "frame_00005.png", "frame_00010.png", "frame_00015.png"}) {
    frames.push_back(render::read_png(out / "png" / name));
    EXPECT_EQ(frames.back().width, 64);
    EXPECT_EQ(frames.back().height, 48);
  }
  EXPECT_FALSE(std::filesystem::exists(out / "png" / "frame_00001.png")) << "every: 5";
  EXPECT_NE(frames[0].rgba, frames[2].rgba) << "the lung moves between frames 0 and 10 (2 s apart)";
  EXPECT_NE(test::read_text(out / "manifest.json").find("png/frame_00015.png"), std::string::npos);
}

// `antialiasing`: without it a silhouette pixel is the lung's or the background's colour; MSAA and
// FXAA blend the two, so the same frame holds more distinct colours. A value not in the list is a
// one-line error at its place in the file.
TEST(RenderCli, AntialiasingKeyChoosesMsaaFxaaOrNone) {
  TempDir dir;
  const auto scenario_with = [&](const std::string& aa) {
    return dir.write("s-" + aa + ".yaml", R"(name: aa
duration: 1 s
frames:
  rate: 5 Hz
mesh:
  phantom: right
  edge: 15 mm
field:
  tissue: healthy-upright
  cache: off
physiology:
  preset: healthy-adult
outputs:
  physiology_csv: {enabled: false}
  gltf: {enabled: false}
  hdf5: {enabled: false}
  png: {width: 96, height: 72, camera: anterior, every: 5, antialiasing: )" +
                                              aa + "}\n");
  };
  const auto colours = [&](const std::string& aa) {
    const auto out = dir / ("out-" + aa);
    const auto r = run_pneuma({"run", scenario_with(aa).string(), "-o", out.string(), "-q"});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    const render::Image image = render::read_png(out / "png" / "frame_00000.png");
    std::set<std::uint32_t> distinct;
    for (std::size_t i = 0; i < image.pixel_count(); ++i) {
      const std::uint8_t* p = &image.rgba[4 * i];
      distinct.insert(std::uint32_t{p[0]} << 16 | std::uint32_t{p[1]} << 8 | p[2]);
    }
    return distinct.size();
  };
  const std::size_t none = colours("none"), msaa = colours("msaa"), fxaa = colours("fxaa");
  EXPECT_GT(msaa, none + 20);
  EXPECT_GT(fxaa, none + 20);
  const auto bad = run_pneuma({"run", scenario_with("ssaa").string(), "-o", (dir / "bad").string(), "-q"});
  EXPECT_EQ(bad.exit_code, 3);
  EXPECT_NE(bad.err.find(":17:"), std::string::npos) << bad.err;
  EXPECT_NE(bad.err.find("outputs.png.antialiasing"), std::string::npos) << bad.err;
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
}
