#pragma once
// gzip files made of independent members (RFC 1952 allows a file to be several members one after
// the other; gzip, zlib's gzread, Python's gzip (nibabel), ITK and plastimatch read them as one
// stream): the input is cut at fixed offsets (`member_bytes`), never by the thread count, and each
// piece is compressed on its own by TBB's threads, so the bytes are the same at any thread count
// and the time is divided by the cores. Header: no time stamp, no name (the same bytes each run).
// The measurements that chose the default: BENCHMARKS.md, "Voxel outputs", "Files".
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <ostream>
#include <span>
#include <vector>

namespace pneuma::voxels {

enum class GzipLibrary { zlib, libdeflate };

struct GzipSettings {
  GzipLibrary library = GzipLibrary::libdeflate;
  int level = 1;  // zlib 1-9, libdeflate 1-12
  // Uncompressed bytes per member; 0: one member for the whole input (one thread).
  std::size_t member_bytes = std::size_t{4} << 20;
};

// What pneuma writes (.nii.gz): the default settings above.
inline constexpr GzipSettings kVoxelGzip{};

// `data` as a gzip file (one or more members). Throws ValueError for a level out of range.
std::vector<std::uint8_t> gzip_bytes(std::span<const std::uint8_t> data, const GzipSettings& settings = kVoxelGzip);

// `data` as one gzip member into `out` (its storage reused): a piece of a file that its caller cuts
// and compresses in parallel itself (nifti_write.h's pipeline).
void gzip_member(std::span<const std::uint8_t> data, std::vector<std::uint8_t>& out,
                 const GzipSettings& settings = kVoxelGzip);

// The members of `data` (cut every `member_bytes` from its start), compressed in parallel, written
// to `out` one after the other: a piece of a gzip file whose earlier pieces were whole multiples of
// `member_bytes` (a file written a batch at a time without holding it whole: nifti_write.h).
void write_gzip_members(std::ostream& out, std::span<const std::uint8_t> data,
                        const GzipSettings& settings = kVoxelGzip);

// `from` gzipped into `to`, read and compressed a batch of members at a time (memory bounded by
// the batch, not the file). Throws IoError when either cannot be read or written.
void gzip_file(const std::filesystem::path& from, const std::filesystem::path& to,
               const GzipSettings& settings = kVoxelGzip);

}  // namespace pneuma::voxels
