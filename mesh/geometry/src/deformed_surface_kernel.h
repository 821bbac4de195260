// No include guard and no includes: the including file includes <immintrin.h>, <cstddef>,
// <cstdint> and deformed_surface_internal.h first, then this file inside its own namespace.
// The chunk kernel of DeformedSurface (deformed_surface.h), compiled twice: in
// deformed_surface.cpp for the baseline instruction set (SSE2 on x86-64) and in
// deformed_surface_avx2.cpp with -mavx2. Each includes this file inside a namespace of its own.
// It uses no inline function from any other header (no Eigen, no std algorithms), so the two
// builds cannot be merged by the linker (one definition rule) into code the processor lacks.
//
// Arithmetic: IEEE multiplies, adds, subtracts and square roots in a fixed order, in 4 lanes
// (one AVX register, or two SSE2 registers), never FMA (the AVX2 unit is built without -mfma
// and with -ffp-contract=off): the same bits on either instruction set.
// Positions of chunk `k`'s vertex block, p = r + s u (one multiply and one add per coordinate),
// streamed to `out` (not read back soon: it bypasses the caches) and, when kScratch, also stored
// to `scratch` for the chunk's triangles.
template <bool kScratch>
inline void displace_block(const KernelData& d, std::size_t k, double s, double* out, double* scratch) {
  const std::size_t v0 = k * d.block;
  const std::size_t v1 = v0 + d.block < d.vertex_count ? v0 + d.block : d.vertex_count;
  const std::size_t m = 3 * (v1 - v0);
  const double* r = d.rest + 3 * v0;
  const double* u = d.u + 3 * v0;
  double* o = out + 3 * v0;
  double* S = scratch;
  std::size_t i = 0;
#if defined(__AVX__)
  constexpr std::uintptr_t align = 32;
#else
  constexpr std::uintptr_t align = 16;
#endif
  for (; i < m && reinterpret_cast<std::uintptr_t>(o + i) % align != 0; ++i) {
    const double p = r[i] + s * u[i];
    o[i] = p;
    if constexpr (kScratch) S[i] = p;
  }
#if defined(__AVX__)
  const __m256d sv = _mm256_set1_pd(s);
  for (; i + 4 <= m; i += 4) {
    const __m256d p = _mm256_add_pd(_mm256_loadu_pd(r + i), _mm256_mul_pd(sv, _mm256_loadu_pd(u + i)));
    _mm256_stream_pd(o + i, p);
    if constexpr (kScratch) _mm256_storeu_pd(S + i, p);
  }
#elif defined(__SSE2__)
  const __m128d sv = _mm_set1_pd(s);
  for (; i + 2 <= m; i += 2) {
    const __m128d p = _mm_add_pd(_mm_loadu_pd(r + i), _mm_mul_pd(sv, _mm_loadu_pd(u + i)));
    _mm_stream_pd(o + i, p);
    if constexpr (kScratch) _mm_storeu_pd(S + i, p);
  }
#endif
  for (; i < m; ++i) {
    const double p = r[i] + s * u[i];
    o[i] = p;
    if constexpr (kScratch) S[i] = p;
  }
#if defined(__SSE2__)
  _mm_sfence();  // this thread's streamed stores are ordered before it reports the chunk done
#endif
}

// Chunk `k`: positions of its vertex block (into `out` when not null, and into `scratch`), its
// halo vertices (into `scratch` after the block), then its triangles; sums[0] = 6 V, sums[1] = 2 A
// of its triangles.
inline void run_chunk(const KernelData& d, std::size_t k, double s, double* out, double* scratch, double* sums) {
  const std::size_t v0 = k * d.block;
  const std::size_t v1 = v0 + d.block < d.vertex_count ? v0 + d.block : d.vertex_count;
  const std::size_t m = 3 * (v1 - v0);
  double* S = scratch;
  // 1. The block.
  if (out) {
    displace_block<true>(d, k, s, out, S);
  } else {
    const double* r = d.rest + 3 * v0;
    const double* u = d.u + 3 * v0;
    for (std::size_t i = 0; i < m; ++i) S[i] = r[i] + s * u[i];
  }
  // 2. The halo: vertices of this chunk's triangles outside its block.
  {
    const std::uint32_t* h = d.halo + d.halo_begin[k];
    const std::size_t count = d.halo_begin[k + 1] - d.halo_begin[k];
    double* q = S + m;
    for (std::size_t j = 0; j < count; ++j, q += 3) {
      const std::size_t g = 3 * static_cast<std::size_t>(h[j]);
      q[0] = d.rest[g] + s * d.u[g];
      q[1] = d.rest[g + 1] + s * d.u[g + 1];
      q[2] = d.rest[g + 2] + s * d.u[g + 2];
    }
  }
  // 3. The triangles, 4 at a time (lane j takes triangles 4 i + j). Indices are offsets into
  // the scratch (3 x the local vertex), grouped by 4: a0 a1 a2 a3 b0 .. b3 c0 .. c3.
  const std::uint32_t* t = d.triangles + 3 * d.triangle_begin[k];
  const std::size_t groups = (d.triangle_begin[k + 1] - d.triangle_begin[k]) / 4;
#if defined(__AVX__)
  typedef double v4d __attribute__((vector_size(32)));
  const v4d ox = {d.origin[0], d.origin[0], d.origin[0], d.origin[0]};
  const v4d oy = {d.origin[1], d.origin[1], d.origin[1], d.origin[1]};
  const v4d oz = {d.origin[2], d.origin[2], d.origin[2], d.origin[2]};
  v4d volume = {0.0, 0.0, 0.0, 0.0};
  v4d area = {0.0, 0.0, 0.0, 0.0};
  for (std::size_t g = 0; g < groups; ++g, t += 12) {
    // Each corner as one 4-double load (x, y, z and the next vertex's x, unused; the scratch has
    // room after its last vertex), four corners transposed into x, y and z vectors.
    v4d ax, ay, az, bx, by, bz, cx, cy, cz;
    {
      const auto corners = [S](const std::uint32_t* q, v4d& x, v4d& y, v4d& z) {
        const __m256d r0 = _mm256_loadu_pd(S + q[0]), r1 = _mm256_loadu_pd(S + q[1]);
        const __m256d r2 = _mm256_loadu_pd(S + q[2]), r3 = _mm256_loadu_pd(S + q[3]);
        const __m256d t0 = _mm256_unpacklo_pd(r0, r1), t1 = _mm256_unpackhi_pd(r0, r1);  // x0 x1 z0 z1, y0 y1 . .
        const __m256d t2 = _mm256_unpacklo_pd(r2, r3), t3 = _mm256_unpackhi_pd(r2, r3);
        x = (v4d)_mm256_permute2f128_pd(t0, t2, 0x20);
        y = (v4d)_mm256_permute2f128_pd(t1, t3, 0x20);
        z = (v4d)_mm256_permute2f128_pd(t0, t2, 0x31);
      };
      corners(t, ax, ay, az);
      corners(t + 4, bx, by, bz);
      corners(t + 8, cx, cy, cz);
    }
    const v4d ex = bx - ax, ey = by - ay, ez = bz - az;
    const v4d fx = cx - ax, fy = cy - ay, fz = cz - az;
    const v4d nx = ey * fz - ez * fy;
    const v4d ny = ez * fx - ex * fz;
    const v4d nz = ex * fy - ey * fx;
    const v4d nn = (nx * nx + ny * ny) + nz * nz;
    area += (v4d)_mm256_sqrt_pd((__m256d)nn);
    volume += ((ax - ox) * nx + (ay - oy) * ny) + (az - oz) * nz;
  }
  sums[0] = (volume[0] + volume[1]) + (volume[2] + volume[3]);
  sums[1] = (area[0] + area[1]) + (area[2] + area[3]);
#else
  // Two SSE2 registers per 4 lanes: lanes 0-1 ("lo") and 2-3 ("hi"), the same operations in the
  // same order as the AVX2 code, so the same bits.
  typedef double v2d __attribute__((vector_size(16)));
  const v2d ox = {d.origin[0], d.origin[0]}, oy = {d.origin[1], d.origin[1]}, oz = {d.origin[2], d.origin[2]};
  v2d volume_lo = {0.0, 0.0}, volume_hi = {0.0, 0.0}, area_lo = {0.0, 0.0}, area_hi = {0.0, 0.0};
  const auto pair = [S, &ox, &oy, &oz](const std::uint32_t* q, v2d& volume, v2d& area) {
    const double *a0 = S + q[0], *a1 = S + q[1], *b0 = S + q[4], *b1 = S + q[5], *c0 = S + q[8], *c1 = S + q[9];
    const v2d ax = {a0[0], a1[0]}, ay = {a0[1], a1[1]}, az = {a0[2], a1[2]};
    const v2d bx = {b0[0], b1[0]}, by = {b0[1], b1[1]}, bz = {b0[2], b1[2]};
    const v2d cx = {c0[0], c1[0]}, cy = {c0[1], c1[1]}, cz = {c0[2], c1[2]};
    const v2d ex = bx - ax, ey = by - ay, ez = bz - az;
    const v2d fx = cx - ax, fy = cy - ay, fz = cz - az;
    const v2d nx = ey * fz - ez * fy;
    const v2d ny = ez * fx - ex * fz;
    const v2d nz = ex * fy - ey * fx;
    const v2d nn = (nx * nx + ny * ny) + nz * nz;
#if defined(__SSE2__)
    area += (v2d)_mm_sqrt_pd((__m128d)nn);
#else
    const v2d root = {__builtin_sqrt(nn[0]), __builtin_sqrt(nn[1])};
    area += root;
#endif
    volume += ((ax - ox) * nx + (ay - oy) * ny) + (az - oz) * nz;
  };
  for (std::size_t g = 0; g < groups; ++g, t += 12) {
    pair(t, volume_lo, area_lo);
    pair(t + 2, volume_hi, area_hi);
  }
  sums[0] = (volume_lo[0] + volume_lo[1]) + (volume_hi[0] + volume_hi[1]);
  sums[1] = (area_lo[0] + area_lo[1]) + (area_hi[0] + area_hi[1]);
#endif
}
