#pragma once
// Shared by deformed_surface.cpp and its per-instruction-set kernels: plain data, no functions.
#include <cstddef>
#include <cstdint>

namespace pneuma::mesh::detail {

// Everything a chunk needs, as raw arrays owned by DeformedSurface::Impl.
struct KernelData {
  std::size_t vertex_count = 0;
  std::size_t block = 0;                        // vertices per chunk (the last chunk may have fewer)
  const double* rest = nullptr;                 // 3 per vertex
  const double* u = nullptr;                    // 3 per vertex
  double origin[3] = {0.0, 0.0, 0.0};           // the volume is summed about this point
  const std::size_t* halo_begin = nullptr;      // chunk_count + 1 offsets into halo
  const std::uint32_t* halo = nullptr;          // global vertex indices, ascending per chunk
  const std::size_t* triangle_begin = nullptr;  // chunk_count + 1 offsets, in triangles (multiples of 4)
  const std::uint32_t* triangles = nullptr;     // 3 scratch offsets per triangle, grouped by 4
};

namespace avx2 {
// In deformed_surface_avx2.cpp (built with -mavx2); call only where the processor has AVX2.
void run_chunk(const KernelData& d, std::size_t k, double s, double* out, double* scratch, double* sums);
// Only the positions of chunk k's vertex block, streamed to `out`.
void displace_block(const KernelData& d, std::size_t k, double s, double* out);
}  // namespace avx2

}  // namespace pneuma::mesh::detail
