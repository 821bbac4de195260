#pragma once
// The SHA-256 of each voxel file as it was written: the writer (nifti_write.h) hashes the bytes on
// their way to the disk, so that the run's manifest (outputs/manifest.h) need not read gigabytes
// back to hash them (BENCHMARKS.md, "Fifth round", #50: ten native phases' 20 GB read back cost
// 21 CPU-s of copies and 10 of hashing, on one core after the last time point).
#include <filesystem>
#include <optional>
#include <string>

namespace pneuma::voxels {

// The lower-case hexadecimal SHA-256 of `path` as this process wrote it, if it did and the file is
// still that one: the same file (device and inode: found after a rename, such as the staged
// output's), size and modification time. Otherwise none (hash the file itself).
std::optional<std::string> written_sha256(const std::filesystem::path& path);

}  // namespace pneuma::voxels
