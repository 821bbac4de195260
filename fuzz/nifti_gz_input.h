#pragma once
// fuzz_nifti_gz's input: a NIfTI file's bytes that the harness compresses itself, so that the
// fuzzer's mutations reach the header and the voxels behind the gzip stream (mutating the stream
// itself would mostly break its CRC). The first byte chooses 1, 2 or 3 gzip members (pigz writes
// several); the rest is the file. Shared with the corpus replay test (tests/fuzz_corpus).
#include <zlib.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>

namespace pneuma::fuzz {

inline std::string nifti_gz_bytes(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return {};
  const std::size_t members = 1 + data[0] % 3;
  const std::uint8_t* file = data + 1;
  const std::size_t length = size - 1;
  const std::size_t part = (length + members - 1) / members;
  std::string out;
  for (std::size_t m = 0; m < members; ++m) {
    const std::size_t from = std::min(m * part, length);
    const std::size_t n = std::min(part, length - from);
    z_stream z{};
    if (deflateInit2(&z, 1, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) return out;
    std::string member(deflateBound(&z, static_cast<uLong>(n)) + 64, '\0');
    z.next_in = const_cast<Bytef*>(file + from);
    z.avail_in = static_cast<uInt>(n);
    z.next_out = reinterpret_cast<Bytef*>(member.data());
    z.avail_out = static_cast<uInt>(member.size());
    const int done = deflate(&z, Z_FINISH);
    member.resize(z.total_out);
    deflateEnd(&z);
    if (done != Z_STREAM_END) return out;
    out += member;
  }
  return out;
}

}  // namespace pneuma::fuzz
