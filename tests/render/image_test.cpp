// PNG input/output and image comparison.
#include <gtest/gtest.h>

#include "pneuma/core/error.h"
#include "pneuma/render/compare.h"
#include "pneuma/render/image.h"
#include "test_support.h"

using namespace pneuma;

namespace {

render::Image gradient(int w, int h) {
  render::Image image(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      image.set(x, y, {static_cast<std::uint8_t>(x * 255 / w), static_cast<std::uint8_t>(y * 255 / h), 77, 255});
    }
  }
  return image;
}

}  // namespace

TEST(Png, RoundTripKeepsEveryByte) {
  test::TempDir dir;
  const render::Image image = gradient(37, 21);
  for (bool fast : {false, true}) {
    render::write_png(dir / "a.png", image, {.fast = fast});
    const render::Image back = render::read_png(dir / "a.png");
    EXPECT_EQ(back.width, 37);
    EXPECT_EQ(back.height, 21);
    EXPECT_EQ(back.rgba, image.rgba);
  }
  EXPECT_EQ(dir.files(), std::vector<std::string>{"a.png"}) << "no temporary left";
}

TEST(Png, OpaqueImagesAreWrittenAsRgbAndTranslucentOnesKeepTheirAlpha) {
  // The PNG header's colour type (byte 25: 2 = RGB, 6 = RGBA) is the oracle, and the round trip.
  render::Image image = gradient(64, 48);
  for (bool fast : {false, true}) {
    const std::vector<std::uint8_t> opaque = render::encode_png(image, {.fast = fast});
    ASSERT_GT(opaque.size(), 26u);
    EXPECT_EQ(opaque[25], 2);
  }
  image.set(63, 47, {1, 2, 3, 128});
  const std::vector<std::uint8_t> translucent = render::encode_png(image, {.fast = true});
  EXPECT_EQ(translucent[25], 6);
  test::TempDir dir;
  render::write_png(dir / "t.png", image, {.fast = true});
  EXPECT_EQ(render::read_png(dir / "t.png").rgba, image.rgba);
}

TEST(Png, MissingAndForeignFilesAreOneLineErrors) {
  test::TempDir dir;
  try {
    render::read_png(dir / "none.png");
    FAIL();
  } catch (const IoError& e) {
    EXPECT_EQ(std::string(e.what()), (dir / "none.png").string() + ": cannot open file");
  }
  const auto text = dir.write("text.png", "hello, not an image");
  EXPECT_THROW(render::read_png(text), InputError);
  // A PNG signature followed by garbage.
  const auto truncated = dir.write("cut.png", std::string("\x89PNG\r\n\x1a\n\0\0\0\rIHDR", 16));
  try {
    render::read_png(truncated);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(truncated.string() + ": not a PNG image (", 0), 0u) << e.what();
  }
}

TEST(Compare, CountsWhatDiffers) {
  const render::Image a = gradient(20, 10);
  render::Image b = a;
  const render::Difference same = render::compare(a, b);
  EXPECT_EQ(same.max, (std::array<int, 4>{0, 0, 0, 0}));
  EXPECT_EQ(same.pixels_over, 0u);
  EXPECT_TRUE(same.within(render::default_tolerance));

  b.set(3, 4, {0, 0, 0, 255});  // one pixel far off
  auto p = b.at(5, 5);
  b.set(5, 5, {static_cast<std::uint8_t>(p.r + 2), p.g, p.b, 255});  // one pixel off by rounding
  const render::Difference d = render::compare(a, b, 10);
  EXPECT_EQ(d.pixels_over, 1u);
  EXPECT_EQ(d.pixel_count, 200u);
  EXPECT_EQ(d.max[0], a.at(3, 4).r);
  EXPECT_EQ(d.max[1], a.at(3, 4).g);
  EXPECT_EQ(d.max[3], 0);
  EXPECT_DOUBLE_EQ(d.mean[2], 77.0 / 200.0);
  EXPECT_FALSE(d.within({10, 0.004}));
  EXPECT_TRUE(d.within({10, 0.005}));
  EXPECT_EQ(d.image.at(3, 4).r, 128 + 102);  // red where it differs, brighter for more
  EXPECT_EQ(d.image.at(3, 4).g, 0);

  EXPECT_THROW(render::compare(a, gradient(20, 11)), UnsupportedError);
}
