#include "pneuma/engine/frame.h"

#include "pneuma/core/error.h"

#ifdef __SSE2__
#include <emmintrin.h>

#include <cstdint>
#endif

namespace pneuma::engine {

// positions = rest + scale * u is bound by memory traffic, not arithmetic (bench/runner_bench.cpp,
// BENCHMARKS.md "Runner"). Ordinary stores first read every destination line into the cache
// (read-for-ownership) before overwriting it: 96 B of traffic per vertex for 72 B of data. With
// SSE2 the loop runs over the 3n doubles as one flat array (Vector3d is three packed doubles) and
// writes with non-temporal (streaming) stores, which skip that read. Every element is one
// multiply and one add in SSE2 instructions (no contraction into FMA whatever the flags), as in
// the plain loop, so the result is bit-for-bit the same. No allocation.
void displace(const BreathingModel& model, double scale, std::vector<Eigen::Vector3d>& positions) {
  const std::size_t n = model.rest.vertices.size();
#ifdef __SSE2__
  static_assert(sizeof(Eigen::Vector3d) == 3 * sizeof(double), "Vector3d must be three packed doubles");
  if (n == 0) return;
  const double* rest = model.rest.vertices.data()->data();
  const double* u = model.unit_displacement.data()->data();
  double* out = positions.data()->data();
  const std::size_t count = 3 * n;
  const __m128d s = _mm_set1_pd(scale);
  std::size_t i = 0;
  const auto one = [&](std::size_t k) {
    _mm_store_sd(out + k, _mm_add_sd(_mm_load_sd(rest + k), _mm_mul_sd(s, _mm_load_sd(u + k))));
  };
  if (reinterpret_cast<std::uintptr_t>(out) % 16 != 0) one(i++);  // streaming stores need 16-byte alignment
  for (; i + 2 <= count; i += 2) {
    _mm_stream_pd(out + i, _mm_add_pd(_mm_loadu_pd(rest + i), _mm_mul_pd(s, _mm_loadu_pd(u + i))));
  }
  if (i < count) one(i);
  _mm_sfence();  // the streamed stores are visible before anyone reads the frame
#else
  const Eigen::Vector3d* rest = model.rest.vertices.data();
  const Eigen::Vector3d* u = model.unit_displacement.data();
  Eigen::Vector3d* out = positions.data();
  for (std::size_t i = 0; i < n; ++i) out[i] = rest[i] + scale * u[i];
#endif
}

BreathingModel make_breathing_model(mesh::TriangleMesh rest, std::vector<Eigen::Vector3d> unit_displacement,
                                    double area_unit_m2, const mesh::BodyFrame& frame,
                                    const mesh::SurfaceRegions* known_regions) {
  if (known_regions) mesh::require_regions_of(*known_regions, rest, frame, "make_breathing_model");
  std::vector<Eigen::Vector3d> normals = mesh::vertex_normals(rest);
  VolumeScaleMap map(rest.vertices, unit_displacement, rest.triangles);
  const double area = mesh::surface_area(rest);
  mesh::RegionOptions region_options;
  region_options.frame = frame;
  mesh::SurfaceRegions regions = known_regions ? *known_regions : mesh::find_regions(rest, region_options);
  return BreathingModel{std::move(rest), std::move(unit_displacement), std::move(normals), area_unit_m2,
                        std::move(map), area, std::move(regions)};
}

Frame::Frame(const BreathingModel& model)
    : positions(model.rest.vertex_count()),
      surface(model.rest.vertices, model.unit_displacement, model.rest.triangles) {}

void advance(const BreathingModel& model, const FrameInput& input, Frame& frame) {
  frame.index = input.index;
  frame.time_s = input.time_s;
  frame.lung_volume_m3 = input.lung_volume_m3;
  frame.scale = input.scale;
  frame.area_m2 = frame.surface.update(frame.scale, frame.positions).area_m2;
  frame.mesh_volume_m3 = model.volume_map.volume(frame.scale);
}

}  // namespace pneuma::engine
