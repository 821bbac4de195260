// Members compressed apart by zlib (deflate with the gzip wrapper) or libdeflate (whole-buffer,
// faster at the same ratio); see gzip.h.
#include "pneuma/voxels/gzip.h"

#include <libdeflate.h>
#include <tbb/parallel_for.h>
#include <zlib.h>

#include <algorithm>
#include <fstream>
#include <memory>
#include <string>

#include "pneuma/core/error.h"

namespace pneuma::voxels {
namespace {

void check_level(const GzipSettings& settings) {
  const int max = settings.library == GzipLibrary::zlib ? 9 : 12;
  if (settings.level < 1 || settings.level > max) {
    throw ValueError("gzip level " + std::to_string(settings.level) + ": expected 1 to " + std::to_string(max));
  }
}

// One gzip member of `data` (zlib's header: no time stamp, OS unix).
std::vector<std::uint8_t> zlib_member(std::span<const std::uint8_t> data, int level) {
  z_stream z{};
  if (deflateInit2(&z, level, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) throw IoError("zlib: out of memory");
  std::vector<std::uint8_t> out(deflateBound(&z, data.size()));
  // zlib's fields are 32-bit: feed at most 1 GiB at a time.
  constexpr std::size_t kStep = std::size_t{1} << 30;
  std::size_t done = 0;
  int status = Z_OK;
  z.next_out = out.data();
  while (status == Z_OK) {
    const std::size_t n = std::min(kStep, data.size() - done);
    z.next_in = const_cast<Bytef*>(data.data() + done);  // zlib's API is not const-correct
    z.avail_in = static_cast<uInt>(n);
    z.avail_out = static_cast<uInt>(std::min<std::size_t>(kStep, out.size() - z.total_out));
    const bool last = done + n == data.size();
    status = deflate(&z, last ? Z_FINISH : Z_NO_FLUSH);
    done += n - z.avail_in;
  }
  const std::size_t size = z.total_out;
  deflateEnd(&z);
  if (status != Z_STREAM_END) throw IoError("zlib: compression failed");
  out.resize(size);
  return out;
}

// libdeflate into `out`, its storage reused (no fresh pages per member).
void libdeflate_member_into(std::span<const std::uint8_t> data, int level, std::vector<std::uint8_t>& out) {
  const std::unique_ptr<libdeflate_compressor, void (*)(libdeflate_compressor*)> c(libdeflate_alloc_compressor(level),
                                                                                   libdeflate_free_compressor);
  if (!c) throw IoError("libdeflate: out of memory");
  out.resize(libdeflate_gzip_compress_bound(c.get(), data.size()));
  const std::size_t size = libdeflate_gzip_compress(c.get(), data.data(), data.size(), out.data(), out.size());
  if (size == 0) throw IoError("libdeflate: compression failed");
  out.resize(size);
}

std::vector<std::uint8_t> libdeflate_member(std::span<const std::uint8_t> data, int level) {
  std::vector<std::uint8_t> out;
  libdeflate_member_into(data, level, out);
  return out;
}

std::vector<std::uint8_t> member(std::span<const std::uint8_t> data, const GzipSettings& settings) {
  return settings.library == GzipLibrary::zlib ? zlib_member(data, settings.level)
                                               : libdeflate_member(data, settings.level);
}

// The members of `data` cut every `member_bytes` (the whole of it when 0), compressed in parallel.
std::vector<std::vector<std::uint8_t>> members(std::span<const std::uint8_t> data, const GzipSettings& settings) {
  const std::size_t step = settings.member_bytes == 0 ? std::max<std::size_t>(data.size(), 1) : settings.member_bytes;
  const std::size_t count = std::max<std::size_t>((data.size() + step - 1) / step, 1);
  std::vector<std::vector<std::uint8_t>> out(count);
  tbb::parallel_for(std::size_t{0}, count, [&](std::size_t m) {
    const std::size_t begin = m * step;
    out[m] = member(data.subspan(begin, std::min(step, data.size() - begin)), settings);
  });
  return out;
}

}  // namespace

std::vector<std::uint8_t> gzip_bytes(std::span<const std::uint8_t> data, const GzipSettings& settings) {
  check_level(settings);
  std::vector<std::uint8_t> out;
  for (const auto& m : members(data, settings)) out.insert(out.end(), m.begin(), m.end());
  return out;
}

void gzip_member(std::span<const std::uint8_t> data, std::vector<std::uint8_t>& out, const GzipSettings& settings) {
  check_level(settings);
  if (settings.library == GzipLibrary::zlib) {
    out = zlib_member(data, settings.level);
  } else {
    libdeflate_member_into(data, settings.level, out);
  }
}

void write_gzip_members(std::ostream& out, std::span<const std::uint8_t> data, const GzipSettings& settings) {
  check_level(settings);
  for (const auto& m : members(data, settings))
    out.write(reinterpret_cast<const char*>(m.data()), static_cast<std::streamsize>(m.size()));
}

void gzip_file(const std::filesystem::path& from, const std::filesystem::path& to, const GzipSettings& settings) {
  check_level(settings);
  std::ifstream in(from, std::ios::binary);
  std::ofstream out(to, std::ios::binary | std::ios::trunc);
  if (!in) throw IoError(from.string() + ": cannot read");
  if (!out) throw IoError(to.string() + ": cannot write");
  // A batch of 16 members at a time (64 MiB by default); one member: the whole file.
  const std::size_t batch = settings.member_bytes == 0 ? static_cast<std::size_t>(std::filesystem::file_size(from))
                                                       : 16 * settings.member_bytes;
  std::vector<std::uint8_t> buffer(std::max<std::size_t>(batch, 1));
  bool first = true;
  while (true) {
    in.read(reinterpret_cast<char*>(buffer.data()), static_cast<std::streamsize>(buffer.size()));
    const auto n = static_cast<std::size_t>(in.gcount());
    if (n == 0 && !first) break;  // an empty file is still one (empty) member
    first = false;
    write_gzip_members(out, std::span(buffer.data(), n), settings);
    if (n < buffer.size()) break;
  }
  if (in.bad()) throw IoError(from.string() + ": cannot read");
  out.close();
  if (!out) throw IoError(to.string() + ": cannot write (disk full?)");
}

}  // namespace pneuma::voxels
