#include "overlay.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace pneuma::render::detail {

const unsigned char kViridis[kViridisSamples][3] = {{68, 1, 84},    {71, 45, 123},  {59, 82, 139},
                                                    {44, 114, 142}, {33, 145, 140}, {40, 174, 128},
                                                    {94, 201, 98},  {173, 220, 48}, {253, 231, 37}};

Rgba viridis(double t) {
  t = std::clamp(t, 0.0, 1.0) * (kViridisSamples - 1);
  const int i = std::min(static_cast<int>(t), kViridisSamples - 2);
  const double f = t - i;
  auto mix = [&](int c) {
    return static_cast<std::uint8_t>(std::lround((1.0 - f) * kViridis[i][c] + f * kViridis[i + 1][c]));
  };
  return {mix(0), mix(1), mix(2), 255};
}

std::string viridis_glsl() {
  std::string table;
  for (int i = 0; i < kViridisSamples; ++i) {
    table += fmt::format("{}vec3({:.6f}, {:.6f}, {:.6f})", i ? ", " : "", kViridis[i][0] / 255.0,
                         kViridis[i][1] / 255.0, kViridis[i][2] / 255.0);
  }
  return fmt::format("const vec3 viridis_table[{0}] = vec3[{0}]({1});\n"
                     "vec3 viridis_srgb(float t) {{\n"
                     "  float x = clamp(t, 0.0, 1.0) * {2}.0;\n"
                     "  int i = min(int(x), {3});\n"
                     "  return mix(viridis_table[i], viridis_table[i + 1], x - float(i));\n"
                     "}}\n",
                     kViridisSamples, table, kViridisSamples - 1, kViridisSamples - 2);
}

namespace {

// 5x7 glyphs, one byte per row, bit 4 = leftmost column.
struct Glyph {
  char c;
  unsigned char rows[7];
};
constexpr Glyph kFont[] = {
    {'0', {0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E}}, {'1', {0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E}},
    {'2', {0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F}}, {'3', {0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E}},
    {'4', {0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02}}, {'5', {0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E}},
    {'6', {0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E}}, {'7', {0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08}},
    {'8', {0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E}}, {'9', {0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C}},
    {'.', {0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C}}, {'-', {0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00}},
    {'m', {0x00, 0x00, 0x1A, 0x15, 0x15, 0x15, 0x15}}, {' ', {0, 0, 0, 0, 0, 0, 0}},
};
constexpr int kGlyphWidth = 5, kGlyphHeight = 7, kGlyphAdvance = 6;

const Glyph* find_glyph(char c) {
  for (const Glyph& g : kFont) {
    if (g.c == c) return &g;
  }
  return nullptr;
}

void fill_rect(Image& image, int x0, int y0, int x1, int y1, Rgba colour) {
  for (int y = std::max(0, y0); y < std::min(image.height, y1); ++y) {
    for (int x = std::max(0, x0); x < std::min(image.width, x1); ++x) image.set(x, y, colour);
  }
}

std::string millimetres(double m) {
  const double mm = m * 1e3;
  return mm < 10.0 ? fmt::format("{:.1f} mm", mm) : fmt::format("{:.0f} mm", mm);
}

}  // namespace

int text_width(const std::string& text, int scale) {
  return text.empty() ? 0 : (static_cast<int>(text.size()) * kGlyphAdvance - 1) * scale;
}

int draw_text(Image& image, int x, int y, const std::string& text, int scale, Rgba colour) {
  int pen = x;
  for (char c : text) {
    if (const Glyph* g = find_glyph(c)) {
      for (int row = 0; row < kGlyphHeight; ++row) {
        for (int col = 0; col < kGlyphWidth; ++col) {
          if (g->rows[row] & (0x10 >> col)) {
            fill_rect(image, pen + col * scale, y + row * scale, pen + (col + 1) * scale, y + (row + 1) * scale,
                      colour);
          }
        }
      }
    }
    pen += kGlyphAdvance * scale;
  }
  return pen - x;
}

void draw_legend(Image& image, double max_m) {
  if (image.width < 96 || image.height < 64) return;
  const int scale = std::max(1, image.height / 360);
  const int bar_width = std::max(6, image.width / 48);
  const int bar_height = image.height * 3 / 5;
  const int text_height = kGlyphHeight * scale;
  const std::string top = millimetres(max_m), bottom = "0 mm";
  const int margin = std::max(4, image.width / 64);
  const int x1 = image.width - margin - std::max(text_width(top, scale), text_width(bottom, scale)) - 2 * scale;
  const int x0 = x1 - bar_width;
  const int y0 = (image.height - bar_height) / 2, y1 = y0 + bar_height;
  const Rgba frame{200, 200, 205, 255}, ink{235, 235, 240, 255};
  fill_rect(image, x0 - 1, y0 - 1, x1 + 1, y1 + 1, frame);
  for (int y = y0; y < y1; ++y) {
    const double t = 1.0 - (y - y0 + 0.5) / bar_height;  // top = max
    fill_rect(image, x0, y, x1, y + 1, viridis(t));
  }
  draw_text(image, x1 + 2 * scale, y0 - text_height / 2, top, scale, ink);
  draw_text(image, x1 + 2 * scale, y1 - text_height / 2, bottom, scale, ink);
}

}  // namespace pneuma::render::detail
