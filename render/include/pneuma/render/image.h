#pragma once
// An 8-bit RGBA image (sRGB, top row first) and its PNG input/output.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <vector>

namespace pneuma::render {

struct Rgba {
  std::uint8_t r = 0, g = 0, b = 0, a = 255;
  friend bool operator==(const Rgba&, const Rgba&) = default;
};

struct Image {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgba;  // width * height * 4 bytes, row-major, top row first

  Image() = default;
  Image(int width_px, int height_px, Rgba fill = {});

  std::size_t pixel_count() const { return static_cast<std::size_t>(width) * static_cast<std::size_t>(height); }
  std::size_t offset(int x, int y) const {
    return (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)) * 4;
  }
  Rgba at(int x, int y) const;
  void set(int x, int y, Rgba colour);
};

struct PngOptions {
  // Favour encoding speed over file size (zlib level 1-ish); about 3x faster, files ~30% larger.
  bool fast = false;
};
inline constexpr PngOptions default_png_options{};

// Encodes `image` as a PNG file in memory, 8 bits per channel: RGB when every pixel is opaque,
// RGBA otherwise.
std::vector<std::uint8_t> encode_png(const Image& image, const PngOptions& options = default_png_options);

// Writes a PNG atomically (temporary name, then rename). Throws IoError.
void write_png(const std::filesystem::path& path, const Image& image, const PngOptions& options = default_png_options);

// Reads any PNG (grey, palette, 16-bit, with or without alpha) into 8-bit RGBA.
// Throws IoError when the file cannot be opened ("<path>: cannot open file") and InputError
// when it is not a PNG image ("<path>: not a PNG image (...)").
Image read_png(const std::filesystem::path& path);

}  // namespace pneuma::render
