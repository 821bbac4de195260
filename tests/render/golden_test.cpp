// Golden-image regression: small renders of the built-in lung phantom (right lung, as in the
// demo scenario) breathing with the real elastostatic field (healthy-upright tissue), against
// reviewed images in tests/golden/: the rest frame and a deep breath from two camera presets,
// plus the displacement overlay and FXAA. The tolerance (compare.h) absorbs llvmpipe rounding at anti-aliased edges and
// catches a real change. After an intended change, look at the new images and regenerate:
//   PNEUMA_REGENERATE_GOLDEN=1 ctest --preset release -R Golden
// A failure writes <name>-actual.png and <name>-diff.png under
// build/<preset>/tests/render/golden-output/ and names them in the message.
#include <gtest/gtest.h>

#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <ostream>
#include <string>

#include "pneuma/field/tissue.h"
#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/model/field_cache.h"
#include "pneuma/render/compare.h"
#include "pneuma/render/renderer.h"
#include "pneuma/scenario/physiology_config.h"
#include "pneuma/scenario/tissue_config.h"
#include "test_support.h"

using namespace pneuma;

namespace {

struct GoldenCase {
  const char* name;
  render::CameraPreset camera;
  double s;
  bool overlay = false;
  bool fxaa = false;  // FXAA instead of MSAA
};

// gtest names the case in a failure line (instead of dumping its bytes).
[[maybe_unused]] void PrintTo(const GoldenCase& c, std::ostream* os) { *os << c.name; }

// s in area units of 1 cm^2 (field::FieldOptions::area_unit): the demo scenario's right lung
// reaches about 75 at the end of a quiet inspiration, so s = 80 is a realistic deep-ish breath.
const GoldenCase kCases[] = {
    {"phantom-anterior-s0", render::CameraPreset::anterior, 0.0},
    {"phantom-anterior-s80", render::CameraPreset::anterior, 80.0},
    {"phantom-oblique-s0", render::CameraPreset::oblique, 0.0},
    {"phantom-oblique-s80", render::CameraPreset::oblique, 80.0},
    {"phantom-anterior-overlay-s80", render::CameraPreset::anterior, 80.0, true},
    {"phantom-oblique-fxaa-s40", render::CameraPreset::oblique, 40.0, false, true},
};

constexpr double kMaxScale = 80.0;  // every case is framed on the same bounds (rest .. s = 80)
constexpr int kWidth = 200, kHeight = 150;

// The right-lung phantom, coarse (10 mm edges: about 2k triangles) so the test stays fast and
// the goldens small, and its field as `pneuma field` computes it.
const model::FieldRecord& phantom_model() {
  static const model::FieldRecord model = [] {
    const mesh::TriangleMesh rest = mesh::make_lung_phantom({.lung = mesh::Lung::right, .edge_length_m = 0.010});
    const field::Tissue tissue =
        scenario::load_tissue(scenario::tissue_file("healthy-upright", scenario::default_config_dir()));
    return model::compute_field_record(rest, tissue, field::default_field_options);
  }();
  return model;
}

render::Image render_case(const GoldenCase& c, const render::Material& material = {}) {
  const model::FieldRecord& lung = phantom_model();
  render::RenderOptions options;
  options.width = kWidth;
  options.height = kHeight;
  options.camera = c.camera;
  options.material = material;
  options.overlay_magnitude = c.overlay;
  if (c.fxaa) {
    options.msaa_samples = 0;
    options.fxaa = true;
  }
  render::Renderer renderer(lung.rest, lung.unit_displacement, kMaxScale, options);
  return renderer.render(c.s);
}

std::filesystem::path golden_path(const GoldenCase& c) {
  return std::filesystem::path(PNEUMA_GOLDEN_DIR) / (std::string(c.name) + ".png");
}

bool regenerating() {
  const char* flag = std::getenv("PNEUMA_REGENERATE_GOLDEN");
  return flag && std::string(flag) == "1";
}

class Golden : public ::testing::TestWithParam<GoldenCase> {};

// Compares `actual` with tests/golden/<name>.png; on a mismatch writes <name>-actual.png and
// <name>-diff.png under `output_dir` and says so in the failure message.
::testing::AssertionResult matches_golden(const std::string& name, const render::Image& actual,
                                          const std::filesystem::path& output_dir = PNEUMA_GOLDEN_OUTPUT_DIR) {
  const auto golden = std::filesystem::path(PNEUMA_GOLDEN_DIR) / (name + ".png");
  if (!std::filesystem::exists(golden)) {
    return ::testing::AssertionFailure() << golden.string() << " is missing; run with PNEUMA_REGENERATE_GOLDEN=1";
  }
  const render::Image expected = render::read_png(golden);
  if (expected.width != actual.width || expected.height != actual.height) {
    return ::testing::AssertionFailure() << golden.string() << ": " << expected.width << "x" << expected.height
                                         << ", rendered " << actual.width << "x" << actual.height;
  }
  const render::Difference d = render::compare(expected, actual);
  if (d.within(render::default_tolerance)) return ::testing::AssertionSuccess();
  const auto actual_path = output_dir / (name + "-actual.png");
  const auto diff_path = output_dir / (name + "-diff.png");
  render::write_png(actual_path, actual);
  render::write_png(diff_path, d.image);
  return ::testing::AssertionFailure()
         << golden.string() << ": " << d.pixels_over << " pixels (" << 100.0 * d.share_over()
         << " %) differ by more than " << d.pixel_threshold << " (max R " << d.max[0] << " G " << d.max[1] << " B "
         << d.max[2] << "); wrote " << actual_path.string() << " and " << diff_path.string()
         << "; if the change is intended, review them and rerun with PNEUMA_REGENERATE_GOLDEN=1";
}

}  // namespace

TEST_P(Golden, MatchesTheReviewedImage) {
  const GoldenCase& c = GetParam();
  const render::Image actual = render_case(c);
  if (regenerating()) {
    render::write_png(golden_path(c), actual);
    GTEST_SKIP() << "regenerated " << golden_path(c).string() << ": review it before committing";
  }
  EXPECT_TRUE(matches_golden(c.name, actual));
}

INSTANTIATE_TEST_SUITE_P(Phantom, Golden, ::testing::ValuesIn(kCases), [](const auto& test_info) {
  std::string name = test_info.param.name;
  for (char& ch : name) {
    if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
  }
  return name;
});

// The comparison must catch a real change: a lung a little less red than the reviewed one, and
// (much smaller) 0.04 less green; a failure leaves the actual and difference images behind.
TEST(GoldenSensitivity, ChangedMaterialColourFails) {
  if (regenerating()) GTEST_SKIP();
  const GoldenCase& c = kCases[1];
  ASSERT_TRUE(matches_golden(c.name, render_case(c)));
  test::TempDir out;
  for (const Eigen::Vector3d& colour : {Eigen::Vector3d(0.80, 0.56, 0.62), Eigen::Vector3d(0.87, 0.52, 0.56)}) {
    render::Material changed;
    changed.base_colour = colour;
    const ::testing::AssertionResult result = matches_golden(c.name, render_case(c, changed), out.path());
    EXPECT_FALSE(result) << "colour " << colour.transpose();
    EXPECT_NE(std::string(result.message()).find((out / (std::string(c.name) + "-diff.png")).string()),
              std::string::npos)
        << result.message();
    EXPECT_EQ(render::read_png(out / (std::string(c.name) + "-actual.png")).width, kWidth);
    EXPECT_EQ(render::read_png(out / (std::string(c.name) + "-diff.png")).width, kWidth);
  }
}
