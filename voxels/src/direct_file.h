#pragma once
// Private to voxels/: a file written past the page cache (O_DIRECT), for the voxel files of a
// run (gigabytes a time point at a label map's own grid). Through the page cache the kernel's
// copy of every byte cost more CPU than computing it (BENCHMARKS.md, "Fifth round", #50: 31 of
// 128 CPU-s of ten native phases in copy_folio_from_iter_atomic, buffered writes 0.86 GB/s
// against 2.6 GB/s direct on the project's VM); written direct, the disk's DMA reads the
// buffers and the CPU is free for the next time point.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>

#include "pneuma/core/sha256.h"

namespace pneuma::voxels::detail {

inline constexpr std::size_t kDirectAlign = 4096;  // O_DIRECT's address, offset and length unit

// `bytes` rounded up to kDirectAlign, allocated at an address aligned to it (not zeroed).
struct AlignedFree {
  void operator()(std::uint8_t* p) const;
};
using AlignedBytes = std::unique_ptr<std::uint8_t[], AlignedFree>;
AlignedBytes aligned_bytes(std::size_t bytes);

// A file written in order. Where the file system refuses O_DIRECT (tmpfs; or a write it will not
// take direct), the same bytes go through the page cache instead. Bytes at an aligned address in
// whole blocks, with nothing held back, are written from the caller's memory; the rest are
// gathered in a block-aligned buffer first. close() writes the last partial block padded, then
// truncates the file to its length. Every byte is hashed (SHA-256) on its way: close() records
// the digest for written_sha256 (written_digest.h). Throws IoError naming `name` on any failure
// (disk full).
class DirectFile {
 public:
  DirectFile(const std::filesystem::path& path, std::filesystem::path name);
  ~DirectFile();
  DirectFile(const DirectFile&) = delete;
  DirectFile& operator=(const DirectFile&) = delete;
  void write(const std::uint8_t* data, std::size_t size);
  void close();

 private:
  void write_at(const std::uint8_t* data, std::size_t size);  // whole blocks (or the padded tail)
  void flush_blocks();
  int fd_ = -1;
  std::filesystem::path name_;
  core::Sha256 hash_;
  std::size_t offset_ = 0;  // bytes on disk
  AlignedBytes held_;       // bytes not yet written (at most 4 MiB)
  std::size_t held_size_ = 0;
};

}  // namespace pneuma::voxels::detail
