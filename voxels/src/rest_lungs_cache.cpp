// The rest lungs' mask kept between runs (rest_lungs_cache.h).
#include "pneuma/voxels/rest_lungs_cache.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <string_view>

#include "pneuma/core/error.h"
#include "pneuma/core/keyed_file.h"
#include "pneuma/core/sha256.h"
#include "pneuma/voxels/dvf.h"

namespace pneuma::voxels {
namespace {

constexpr std::string_view kKind = "pneuma-rest-lungs 1";
// Part of the key: a mask kept by a pneuma whose rasterisation rule (rasterize.h: which voxel
// centres a tet holds, and which set wins) differs must not be read back. Raise it with the rule.
constexpr std::string_view kRule = "rasterize: closed simplex, barycentric tolerance, first set wins; 1";

void put_length(std::string& out, std::uint64_t n) {
  for (int b = 0; b < 8; ++b) out.push_back(static_cast<char>((n >> (8 * b)) & 0xffu));
}
std::uint64_t get_length(std::string_view bytes, std::size_t at) {
  std::uint64_t n = 0;
  for (int b = 7; b >= 0; --b) n = (n << 8) | static_cast<unsigned char>(bytes[at + static_cast<std::size_t>(b)]);
  return n;
}

}  // namespace

std::string rest_lungs_key(const Grid& grid, std::span<const LungMotion> lungs) {
  core::Sha256 h;
  h.update(kKind.data(), kKind.size()).update(kRule.data(), kRule.size());
  for (const std::size_t n : grid.size) {
    const auto n64 = static_cast<std::uint64_t>(n);
    h.update(&n64, sizeof n64);
  }
  h.update(grid.ijk_to_lps.data(), 16 * sizeof(double));
  const auto count = static_cast<std::uint64_t>(lungs.size());
  h.update(&count, sizeof count);
  for (const LungMotion& lung : lungs) {
    const std::array<std::uint64_t, 2> sizes{lung.mesh.nodes.size(), lung.mesh.tets.size()};
    h.update(sizes.data(), sizeof sizes);
    h.update(lung.mesh.nodes.data(), lung.mesh.nodes.size() * sizeof(Eigen::Vector3d));
    h.update(lung.mesh.tets.data(), lung.mesh.tets.size() * sizeof(mesh::Tetrahedron));
  }
  return core::to_hex(h.finish());
}

MaskRuns mask_runs(std::span<const std::uint8_t> mask) {
  MaskRuns runs;
  for (std::size_t at = 0; at < mask.size();) {
    const std::uint8_t value = mask[at];
    const auto end = static_cast<std::size_t>(std::find_if(mask.begin() + static_cast<std::ptrdiff_t>(at), mask.end(),
                                                           [value](std::uint8_t v) { return v != value; }) -
                                              mask.begin());
    runs.values.push_back(value);
    runs.lengths.push_back(end - at);
    at = end;
  }
  return runs;
}

std::vector<std::uint8_t> mask_of_runs(const MaskRuns& runs, std::size_t voxel_count) {
  if (runs.values.size() != runs.lengths.size())
    throw ValueError(fmt::format("mask_of_runs: {} values for {} runs", runs.values.size(), runs.lengths.size()));
  std::uint64_t total = 0;
  for (const std::uint64_t n : runs.lengths) {
    if (n > voxel_count - total) {
      throw ValueError(fmt::format("mask_of_runs: the runs hold more than {} voxels", voxel_count));
    }
    total += n;
  }
  if (total != voxel_count)
    throw ValueError(fmt::format("mask_of_runs: the runs hold {} voxels, expected {}", total, voxel_count));
  std::vector<std::uint8_t> mask;
  mask.reserve(voxel_count);  // each page first touched by its run's fill, not zeroed before
  for (std::size_t r = 0; r < runs.values.size(); ++r) mask.insert(mask.end(), runs.lengths[r], runs.values[r]);
  return mask;
}

void save_rest_lungs(const std::filesystem::path& path, const std::string& key, std::span<const std::uint8_t> mask) {
  const MaskRuns runs = mask_runs(mask);
  std::string payload(runs.values.begin(), runs.values.end());
  payload.reserve(runs.values.size() * 9);
  for (const std::uint64_t n : runs.lengths) put_length(payload, n);
  core::save_keyed_file(path, kKind, key, payload);
}

std::optional<std::vector<std::uint8_t>> load_rest_lungs(const std::filesystem::path& path, const std::string& key,
                                                         std::size_t voxel_count, std::string& discarded) {
  const std::optional<std::string> payload = core::load_keyed_file(path, kKind, key, discarded);
  if (!payload) return std::nullopt;
  const auto refuse = [&](const std::string& why) {
    discarded = fmt::format("{}: not a {} file: {}", path.string(), kKind, why);
    return std::nullopt;
  };
  if (payload->size() % 9 != 0) return refuse(fmt::format("{} bytes of runs, not 9 a run", payload->size()));
  const std::size_t count = payload->size() / 9;
  MaskRuns runs;
  runs.values.assign(payload->begin(), payload->begin() + static_cast<std::ptrdiff_t>(count));
  runs.lengths.resize(count);
  for (std::size_t r = 0; r < count; ++r) runs.lengths[r] = get_length(*payload, count + 8 * r);
  try {
    return mask_of_runs(runs, voxel_count);
  } catch (const ValueError& e) {
    return refuse(e.what());
  }
}

RestLungsLookup cached_rest_lungs(const Grid& grid, std::span<const LungMotion> lungs, const RestLungsCache& cache) {
  RestLungsLookup out;
  if (cache.lookup.empty() && cache.save_to.empty()) {
    out.mask = rest_lungs(grid, lungs);
    return out;
  }
  const std::string key = rest_lungs_key(grid, lungs);
  if (!cache.lookup.empty()) {
    if (auto kept = load_rest_lungs(cache.lookup, key, grid.voxel_count(), out.discarded)) {
      out.mask = std::move(*kept);
      out.reused = true;
      if (!cache.save_to.empty() && cache.save_to != cache.lookup) {
        std::error_code ec;
        std::filesystem::create_directories(cache.save_to.parent_path(), ec);
        if (!ec)
          std::filesystem::copy_file(cache.lookup, cache.save_to, std::filesystem::copy_options::overwrite_existing,
                                     ec);
        if (ec) throw IoError(fmt::format("{}: cannot write: {}", cache.save_to.string(), ec.message()));
      }
      return out;
    }
  }
  out.mask = rest_lungs(grid, lungs);
  if (!cache.save_to.empty()) save_rest_lungs(cache.save_to, key, out.mask);
  return out;
}

}  // namespace pneuma::voxels
