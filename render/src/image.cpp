// PNG through libpng's simplified API (png_image_*): no setjmp/longjmp in C++ code.
#include "pneuma/render/image.h"

#include <png.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/core/paths.h"

namespace pneuma::render {

Image::Image(int width_px, int height_px, Rgba fill) : width(width_px), height(height_px) {
  rgba.resize(pixel_count() * 4);
  for (std::size_t i = 0; i < rgba.size(); i += 4) {
    rgba[i] = fill.r;
    rgba[i + 1] = fill.g;
    rgba[i + 2] = fill.b;
    rgba[i + 3] = fill.a;
  }
}

Rgba Image::at(int x, int y) const {
  const std::uint8_t* p = rgba.data() + offset(x, y);
  return {p[0], p[1], p[2], p[3]};
}

void Image::set(int x, int y, Rgba colour) {
  std::uint8_t* p = rgba.data() + offset(x, y);
  p[0] = colour.r;
  p[1] = colour.g;
  p[2] = colour.b;
  p[3] = colour.a;
}

namespace {

png_image png_header(const Image& image, const PngOptions& options, bool opaque) {
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  png.width = static_cast<png_uint_32>(image.width);
  png.height = static_cast<png_uint_32>(image.height);
  png.format = opaque ? PNG_FORMAT_RGB : PNG_FORMAT_RGBA;
  png.flags = options.fast ? PNG_IMAGE_FLAG_FAST : 0;
  return png;
}

// The image without its alpha channel when every pixel is opaque (every rendered frame: the
// background is opaque), so zlib compresses a quarter fewer bytes; empty otherwise.
std::vector<std::uint8_t> opaque_rgb(const Image& image) {
  const std::size_t n = image.pixel_count();
  for (std::size_t i = 0; i < n; ++i) {
    if (image.rgba[4 * i + 3] != 255) return {};
  }
  std::vector<std::uint8_t> rgb(3 * n);
  for (std::size_t i = 0; i < n; ++i) std::memcpy(&rgb[3 * i], &image.rgba[4 * i], 3);
  return rgb;
}

}  // namespace

std::vector<std::uint8_t> encode_png(const Image& image, const PngOptions& options) {
  PNEUMA_ASSERT(image.rgba.size() == image.pixel_count() * 4, "image buffer does not match its size");
  const std::vector<std::uint8_t> rgb = opaque_rgb(image);
  const void* pixels = rgb.empty() ? static_cast<const void*>(image.rgba.data()) : rgb.data();
  png_image png = png_header(image, options, !rgb.empty());
  // One pass into a buffer of libpng's bound for this image (measuring first would compress twice).
  png_alloc_size_t size = PNG_IMAGE_PNG_SIZE_MAX(png);
  std::vector<std::uint8_t> bytes(size);
  if (!png_image_write_to_memory(&png, bytes.data(), &size, 0, pixels, 0, nullptr)) {
    throw Error(ExitCode::failure, std::string("render: PNG encoding failed: ") + png.message);
  }
  bytes.resize(size);
  return bytes;
}

void write_png(const std::filesystem::path& path, const Image& image, const PngOptions& options) {
  const std::vector<std::uint8_t> bytes = encode_png(image, options);
  write_stream_atomically(path, true, [&](std::ostream& out) {
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  });
}

Image read_png(const std::filesystem::path& path) {
  const std::string bytes = read_file_bytes(path);
  static constexpr unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (bytes.size() < 8 || std::memcmp(bytes.data(), signature, 8) != 0) {
    throw InputError(path.string() + ": not a PNG image (no PNG signature)");
  }
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&png, bytes.data(), bytes.size())) {
    throw InputError(path.string() + ": not a PNG image (" + png.message + ")");
  }
  png.format = PNG_FORMAT_RGBA;
  Image image(static_cast<int>(png.width), static_cast<int>(png.height));
  if (!png_image_finish_read(&png, nullptr, image.rgba.data(), 0, nullptr)) {
    png_image_free(&png);
    throw InputError(path.string() + ": not a PNG image (" + png.message + ")");
  }
  return image;
}

}  // namespace pneuma::render
