#pragma once
// The rest lungs' mask (dvf.h, rest_lungs) kept between runs (#50). On the label map's own grid it
// is a rasterisation of every rest tet at that grid (70.8M voxels for a 512 x 512 x 270 CT, about
// 0.5 CPU-s): work a run into the same output folder need not do again while the grid and the
// rest meshes are the same. The mask is piecewise constant along i, so it is kept as runs.
//
// File: a keyed cache file (core/keyed_file.h) of kind `pneuma-rest-lungs 1` whose payload is
// each run's value (R bytes: 0, or 1 + the lung) then each run's length (R uint64, little
// endian); the lengths add up to the grid's voxels (docs/formats.md, "rest-lungs.cache").
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "pneuma/voxels/grid.h"
#include "pneuma/voxels/lung_motion.h"

namespace pneuma::voxels {

// A digest of everything rest_lungs(grid, lungs) depends on: the grid (size and transform), each
// lung's rest nodes and tets in order, and the rasterisation rule's version. 64 hex digits.
std::string rest_lungs_key(const Grid& grid, std::span<const LungMotion> lungs);

// The mask as runs of equal values along the voxels' order, and back.
struct MaskRuns {
  std::vector<std::uint8_t> values;
  std::vector<std::uint64_t> lengths;
};
MaskRuns mask_runs(std::span<const std::uint8_t> mask);
// Throws ValueError when the runs do not add up to `voxel_count` voxels.
std::vector<std::uint8_t> mask_of_runs(const MaskRuns& runs, std::size_t voxel_count);

// Writes the mask and its key to `path` atomically. Throws IoError when it cannot be written.
void save_rest_lungs(const std::filesystem::path& path, const std::string& key, std::span<const std::uint8_t> mask);

// The mask kept at `path` for `key` on `voxel_count` voxels; none where there is no file, or it
// holds another key (the grid or the meshes changed). A damaged file (cut, edited, not ours) is
// never used: none, with the one-line reason in `discarded` for a warning.
std::optional<std::vector<std::uint8_t>> load_rest_lungs(const std::filesystem::path& path, const std::string& key,
                                                         std::size_t voxel_count, std::string& discarded);

// Where a run looks for the kept mask (a previous run's output folder) and where it keeps it (its
// stage, moved into that folder at the end); both empty: no cache.
struct RestLungsCache {
  std::filesystem::path lookup;
  std::filesystem::path save_to;
};
struct RestLungsLookup {
  std::vector<std::uint8_t> mask;  // rest_lungs(grid, lungs)
  bool reused = false;             // read from cache.lookup (and copied to save_to)
  std::string discarded;           // why a file found there was not usable (else empty)
};
// rest_lungs(grid, lungs), read from cache.lookup where it holds them for this grid and these
// meshes, else rasterised; kept at cache.save_to either way (where given).
RestLungsLookup cached_rest_lungs(const Grid& grid, std::span<const LungMotion> lungs, const RestLungsCache& cache);

}  // namespace pneuma::voxels
