#pragma once
// The per-frame kernel of a breathing surface: positions = rest + s * u for every vertex, and the
// enclosed volume and surface area of the deformed surface, in one fused, vectorised (SSE2, or
// AVX2 where the processor has it) and threaded (TBB) pass.
//
// Deterministic: the triangles are split into chunks once, at construction, by a rule that does
// not depend on the thread count (vertex blocks of a fixed size; a triangle goes with the block of
// its smallest vertex index); each chunk sums in 4 fixed lanes and the chunk sums are added in
// chunk order. So volume and area are the same bits at any thread count and on either instruction
// set (both do the same IEEE multiplies, adds and square roots, never FMA). The positions are
// bit-for-bit `rest[i] + s * u[i]` (one multiply, one add per coordinate), as model::displace.
//
// A run knows every frame's s before its first frame, so tabulate_measures() can take V and A out
// of the per-frame work: both are smooth in s (V is a cubic, A a sum of square roots of quartics),
// so a Chebyshev table of the exact sums over the run's range reproduces them to ~1e-15 of their
// size, and update() is then a positions-only pass (the same bits) plus an O(table) evaluation.
#include <Eigen/Core>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh {

struct SurfaceMeasures {
  double volume_m3 = 0.0;  // enclosed volume (signed tetrahedra; for a closed, outward surface > 0)
  double area_m2 = 0.0;    // total area
};

class DeformedSurface {
 public:
  // Copies what it needs (rest, u, and the triangles regrouped by chunk); the arguments may go
  // afterwards. `u` has one entry per rest vertex; every triangle index must be < rest.size().
  // Throws InputError when they do not match.
  DeformedSurface(const std::vector<Eigen::Vector3d>& rest, const std::vector<Eigen::Vector3d>& u,
                  const std::vector<Triangle>& triangles);
  ~DeformedSurface();
  DeformedSurface(DeformedSurface&&) noexcept;
  DeformedSurface& operator=(DeformedSurface&&) noexcept;

  // Writes positions[i] = rest[i] + s * u[i] (positions.size() must be vertex_count(): resized
  // if not, which allocates) and returns the volume and area of that surface. The volume is
  // taken about a fixed point (the centre of the rest bounding box): for a closed surface it is
  // the enclosed volume, whatever the origin. Allocates nothing after the first call. Not to be
  // called on the same object from two threads at once (it owns per-chunk scratch).
  SurfaceMeasures update(double s, std::vector<Eigen::Vector3d>& positions);
  // The same measures without writing positions.
  SurfaceMeasures measure(double s);
  // Only positions[i] = rest[i] + s * u[i] (the same bits as update()), threaded.
  void displace(double s, std::vector<Eigen::Vector3d>& positions);

  // Tabulates V(s) and A(s) on [s_lo, s_hi] from measure() at 17 to 257 Chebyshev points
  // (core/chebyshev.h), if that table predicts its own last refinement within
  // `relative_tolerance` of max V and max A. After that, update(s) for s in [s_lo, s_hi] is
  // displace(s) plus the table: V and A within the tolerance of the exact sums (no longer the same
  // bits), still the same at any thread count. Returns false, and leaves update() exact, when V or
  // A is not smooth enough there (a triangle collapsing in the range) or the range is not finite.
  bool tabulate_measures(double s_lo, double s_hi, double relative_tolerance = 1e-12);
  // Whether update(s) takes its measures from the table.
  bool tabulated(double s) const;

  std::size_t vertex_count() const;
  std::size_t triangle_count() const;
  // Chunks the work is split into (fixed at construction; for tests and benchmarks).
  std::size_t chunk_count() const;
  // "avx2" or "sse2" (or "scalar"): the code path update() takes on this processor.
  static const char* instruction_set();
  // "sse2": take the baseline path even where AVX2 is there; "avx2": back to the best available.
  // For tests and benchmarks (process-wide; not while another thread runs update()).
  static void limit_instruction_set(const std::string& name);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace pneuma::mesh
