// The fused per-frame kernel (deformed_surface.h): set-up, chunking, threading, dispatch. The
// arithmetic is in deformed_surface_kernel.h, built here for the baseline instruction set and in
// deformed_surface_avx2.cpp for AVX2.
//
// Why chunks: area and volume are sums over triangles, and each triangle reads three vertices.
// Going over the triangles after writing all positions reads them back from memory (at 1M vertices
// 24 MB, out of cache) with random access. Here the vertices are cut into blocks of kBlock (the
// chunk's positions fit in the first-level cache), each triangle belongs to the chunk of its
// smallest vertex index, and a chunk computes its block's positions into a small scratch array
// (and streams them to the output), then the few vertices outside its block its triangles use
// (its halo: the next ring of the mesh, computed again, the same bits), then its triangles, whose
// indices point into the scratch. Meshes numbered coherently (every mesh pneuma makes; any order
// still gives the right answer, only slower) have small halos.
#include "pneuma/mesh/geometry/deformed_surface.h"

#include <immintrin.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <optional>
#include <span>
#include <string>

#include "deformed_surface_internal.h"
#include "pneuma/core/chebyshev.h"
#include "pneuma/core/error.h"
#include "pneuma/core/tsan.h"

namespace pneuma::mesh {
namespace detail::baseline {
namespace kernel {
#include "deformed_surface_kernel.h"
}  // namespace kernel
}  // namespace detail::baseline

namespace {

// Vertices per chunk: 8192 x 24 B = 192 KiB of positions, plus the halo (the phantom: ~25 %). Part of the result's
// definition (it fixes the summation order): changing it changes the last bits of V and A.
constexpr std::size_t kBlock = 8192;

enum class Path { scalar_or_sse2, avx2 };

Path detect_path() {
#if defined(PNEUMA_HAVE_AVX2_KERNEL)
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx2")) return Path::avx2;
#endif
  return Path::scalar_or_sse2;
}

Path& active_path() {
  static Path path = detect_path();
  return path;
}

}  // namespace

struct DeformedSurface::Impl {
  std::size_t vertex_count = 0;
  std::size_t triangle_count = 0;
  std::size_t chunk_count = 0;
  std::vector<double> rest, u;
  std::vector<std::size_t> halo_begin, triangle_begin;
  std::vector<std::uint32_t> halo, triangles;
  std::size_t scratch_size = 0;  // doubles
  std::vector<double> sums;      // 2 per chunk
  tbb::enumerable_thread_specific<std::vector<double>> scratch;
  detail::KernelData data;
  std::optional<ChebyshevTable> measures;  // V and A by s, when tabulated

  SurfaceMeasures run(double s, double* out);
  void displace(double s, double* out);
};

DeformedSurface::DeformedSurface(const std::vector<Eigen::Vector3d>& rest, const std::vector<Eigen::Vector3d>& u,
                                 const std::vector<Triangle>& triangles)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  const std::size_t n = rest.size();
  if (u.size() != n) {
    throw InputError("deformed surface: " + std::to_string(u.size()) + " displacement vectors for " +
                     std::to_string(n) + " vertices");
  }
  if (n >= (std::size_t{1} << 31) / 3) throw InputError("deformed surface: too many vertices");
  m.vertex_count = n;
  m.triangle_count = triangles.size();
  m.rest.resize(3 * n);
  m.u.resize(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) {
      m.rest[3 * i + static_cast<std::size_t>(c)] = rest[i][c];
      m.u[3 * i + static_cast<std::size_t>(c)] = u[i][c];
    }
  }
  m.chunk_count = (n + kBlock - 1) / kBlock;
  const std::size_t chunks = m.chunk_count;

  // Triangles by chunk (their smallest vertex's block), in their given order within a chunk.
  std::vector<std::size_t> count(chunks + 1, 0);
  for (std::size_t f = 0; f < triangles.size(); ++f) {
    const Triangle& t = triangles[f];
    if (t[0] >= n || t[1] >= n || t[2] >= n) {
      throw InputError("deformed surface: triangle " + std::to_string(f) +
                       " has a vertex index >= " + std::to_string(n));
    }
    ++count[std::min({t[0], t[1], t[2]}) / kBlock + 1];
  }
  std::vector<std::size_t> first(chunks + 1, 0);
  for (std::size_t k = 0; k < chunks; ++k) first[k + 1] = first[k] + count[k + 1];
  std::vector<std::uint32_t> order(triangles.size());
  {
    std::vector<std::size_t> next(first.begin(), first.end() - 1);
    for (std::size_t f = 0; f < triangles.size(); ++f) {
      const Triangle& t = triangles[f];
      order[next[std::min({t[0], t[1], t[2]}) / kBlock]++] = static_cast<std::uint32_t>(f);
    }
  }

  // Per chunk: the halo (sorted, unique) and the triangles as scratch offsets, padded with
  // degenerate triangles (0, 0, 0: zero area, zero volume) to a multiple of 4.
  m.halo_begin.assign(chunks + 1, 0);
  m.triangle_begin.assign(chunks + 1, 0);
  std::vector<std::uint32_t> local;
  std::size_t max_local = 0;
  for (std::size_t k = 0; k < chunks; ++k) {
    const std::size_t v0 = k * kBlock, v1 = std::min(v0 + kBlock, n);
    local.clear();
    for (std::size_t j = first[k]; j < first[k + 1]; ++j) {
      for (std::uint32_t v : triangles[order[j]]) {
        if (v < v0 || v >= v1) local.push_back(v);
      }
    }
    std::sort(local.begin(), local.end());
    local.erase(std::unique(local.begin(), local.end()), local.end());
    m.halo.insert(m.halo.end(), local.begin(), local.end());
    m.halo_begin[k + 1] = m.halo.size();
    max_local = std::max(max_local, (v1 - v0) + local.size());

    const auto offset = [&](std::uint32_t v) -> std::uint32_t {
      const std::size_t l =
          (v >= v0 && v < v1)
              ? v - v0
              : (v1 - v0) + static_cast<std::size_t>(std::lower_bound(local.begin(), local.end(), v) - local.begin());
      return static_cast<std::uint32_t>(3 * l);
    };
    const std::size_t count_k = first[k + 1] - first[k];
    const std::size_t padded = (count_k + 3) / 4 * 4;
    const std::size_t base = m.triangles.size();
    m.triangles.resize(base + 3 * padded, 0);
    for (std::size_t j = 0; j < count_k; ++j) {
      const Triangle& t = triangles[order[first[k] + j]];
      const std::size_t group = base + 12 * (j / 4), lane = j % 4;
      for (std::size_t c = 0; c < 3; ++c) m.triangles[group + 4 * c + lane] = offset(t[c]);
    }
    m.triangle_begin[k + 1] = m.triangle_begin[k] + padded;
  }
  m.scratch_size = 3 * max_local + 4;  // + 4: the AVX2 kernel loads 4 doubles from the last vertex
  m.sums.assign(2 * chunks, 0.0);
  m.scratch = tbb::enumerable_thread_specific<std::vector<double>>(m.scratch_size, 0.0);

  const auto [low, high] = bounding_box(rest);
  m.data.vertex_count = n;
  m.data.block = kBlock;
  m.data.rest = m.rest.data();
  m.data.u = m.u.data();
  for (int c = 0; c < 3; ++c) m.data.origin[c] = n ? 0.5 * (low[c] + high[c]) : 0.0;
  m.data.halo_begin = m.halo_begin.data();
  m.data.halo = m.halo.data();
  m.data.triangle_begin = m.triangle_begin.data();
  m.data.triangles = m.triangles.data();
}

DeformedSurface::~DeformedSurface() = default;
DeformedSurface::DeformedSurface(DeformedSurface&&) noexcept = default;
DeformedSurface& DeformedSurface::operator=(DeformedSurface&&) noexcept = default;

SurfaceMeasures DeformedSurface::Impl::run(double s, double* out) {
  [[maybe_unused]] const bool avx2 = active_path() == Path::avx2;
  const auto chunk = [&](std::size_t k, double* scratch_data) {
#ifdef PNEUMA_HAVE_AVX2_KERNEL
    if (avx2) detail::avx2::run_chunk(data, k, s, out, scratch_data, &sums[2 * k]);
    else
#endif
      detail::baseline::kernel::run_chunk(data, k, s, out, scratch_data, &sums[2 * k]);
  };
  if (chunk_count == 1) {
    chunk(0, scratch.local().data());
  } else if (chunk_count > 1) {
    const tsan::Region region;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chunk_count),
                      region.wrap([&](const tbb::blocked_range<std::size_t>& range) {
                        double* scratch_data = scratch.local().data();
                        for (std::size_t k = range.begin(); k != range.end(); ++k) chunk(k, scratch_data);
                      }));
    region.join();
  }
#ifdef __SSE2__
  if (out) _mm_sfence();  // the streamed positions are visible before anyone reads them
#endif
  // The chunks' sums in chunk order: the same bits at any thread count.
  double six_volume = 0.0, two_area = 0.0;
  for (std::size_t k = 0; k < chunk_count; ++k) {
    six_volume += sums[2 * k];
    two_area += sums[2 * k + 1];
  }
  return {six_volume / 6.0, 0.5 * two_area};
}

void DeformedSurface::Impl::displace(double s, double* out) {
  if (!out) return;
  [[maybe_unused]] const bool avx2 = active_path() == Path::avx2;
  const tsan::Region region;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chunk_count),
                    region.wrap([&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t k = range.begin(); k != range.end(); ++k) {
#ifdef PNEUMA_HAVE_AVX2_KERNEL
                        if (avx2) detail::avx2::displace_block(data, k, s, out);
                        else
#endif
                          detail::baseline::kernel::displace_block<false>(data, k, s, out, nullptr);
                      }
                    }));
  region.join();
}

SurfaceMeasures DeformedSurface::update(double s, std::vector<Eigen::Vector3d>& positions) {
  static_assert(sizeof(Eigen::Vector3d) == 3 * sizeof(double), "Vector3d must be three packed doubles");
  if (positions.size() != impl_->vertex_count) positions.resize(impl_->vertex_count);
  double* out = impl_->vertex_count ? positions.data()->data() : nullptr;
  if (!tabulated(s)) return impl_->run(s, out);
  impl_->displace(s, out);
  std::array<double, 2> measures{};
  impl_->measures->evaluate(s, measures);
  return {measures[0], measures[1]};
}

void DeformedSurface::displace(double s, std::vector<Eigen::Vector3d>& positions) {
  if (positions.size() != impl_->vertex_count) positions.resize(impl_->vertex_count);
  impl_->displace(s, impl_->vertex_count ? positions.data()->data() : nullptr);
}

bool DeformedSurface::tabulate_measures(double s_lo, double s_hi, double relative_tolerance) {
  impl_->measures = ChebyshevTable::fit(
      [this](double s, std::span<double> values) {
        const SurfaceMeasures m = impl_->run(s, nullptr);
        values[0] = m.volume_m3;
        values[1] = m.area_m2;
      },
      2, s_lo, s_hi, relative_tolerance);
  return impl_->measures.has_value();
}

bool DeformedSurface::tabulated(double s) const { return impl_->measures && impl_->measures->covers(s); }

SurfaceMeasures DeformedSurface::measure(double s) { return impl_->run(s, nullptr); }

std::size_t DeformedSurface::vertex_count() const { return impl_->vertex_count; }
std::size_t DeformedSurface::triangle_count() const { return impl_->triangle_count; }
std::size_t DeformedSurface::chunk_count() const { return impl_->chunk_count; }

const char* DeformedSurface::instruction_set() {
  if (active_path() == Path::avx2) return "avx2";
#ifdef __SSE2__
  return "sse2";
#else
  return "scalar";
#endif
}

void DeformedSurface::limit_instruction_set(const std::string& name) {
  if (name == "avx2") active_path() = detect_path();
  else active_path() = Path::scalar_or_sse2;
}

}  // namespace pneuma::mesh
