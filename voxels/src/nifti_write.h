#pragma once
// NIfTI-1 files (.nii, .nii.gz) written straight from memory: the 348-byte header made by the
// NIfTI library that ITK's own writer uses (ITK 5.2's niftiio: the same qform, sform, units and
// codes), the data filled by the caller one batch at a time and, for .nii.gz, compressed as it
// comes in parallel gzip members (gzip.h). No whole-image copy (ITK's writer reorders a vector
// image's components into a second copy) and no temporary plain file gzipped afterwards
// (BENCHMARKS.md, "Voxel outputs", #50: the kernel's copies of that file were 9 % of a native
// time point).
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>

#include "pneuma/voxels/grid.h"

namespace pneuma::voxels {

enum class NiftiType { uint8, int16, int32, float32 };

struct NiftiSpec {
  Grid grid;
  NiftiType type = NiftiType::float32;
  unsigned components = 1;  // 3: a vector image, dim = (5, nx, ny, nz, 1, 3), components the slowest axis
  std::int16_t intent = 0;  // 0: none for a scalar image, NIFTI_INTENT_VECTOR (1007) for a vector one
  std::string description;  // descrip, its first 79 characters
};

// Fills `count` values from value number `first` on, in the file's order (i fastest, then j, k,
// then the component), into `out` (count values of the spec's type). Called in order, one call at a
// time, from a TBB pipeline's thread (it may start TBB tasks).
using NiftiFill = std::function<void(std::size_t first, std::size_t count, void* out)>;

// Writes `path` atomically (core/atomic_file.h), gzipped when the name ends in .nii.gz, holding at
// most 8 gzip members (4 MiB each, with their compressed copies) of data at a time: filled in order,
// compressed in parallel and written in order, all three at once. Throws ValueError for a grid side
// over 32767 voxels (NIfTI-1's int16) and IoError when the file cannot be written.
void write_nifti(const std::filesystem::path& path, const NiftiSpec& spec, const NiftiFill& fill);

}  // namespace pneuma::voxels
