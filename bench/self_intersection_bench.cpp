// The runner's once-per-run CGAL steps at 1M vertices: the self-intersection check
// (mesh::self_intersects, CGAL does_self_intersect) serial against parallel (x slabs tested by
// TBB tasks; the process_cpu_s counter is the work of every thread), and
// isotropic remeshing (CGAL, 3 iterations, same edge). Baseline in the same run: the fused frame
// kernel (one frame) on the same mesh.
// Mesh: the phantom, both lungs, 0.411 mm edges: 1,003,704 vertices, 2,007,400 triangles, no
// self-intersection (the worst case for the check: every candidate pair is tested).
// Results: BENCHMARKS.md, "Frame kernel".
#include <benchmark/benchmark.h>

#include <ctime>

#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/mesh/geometry/deformed_surface.h"
#include "pneuma/mesh/geometry/surface_queries.h"
#include "pneuma/mesh/repair/remesh.h"

namespace {

using namespace pneuma::mesh;

constexpr double kEdge = 0.411e-3;

const TriangleMesh& phantom() {
  static const TriangleMesh mesh = make_lung_phantom({.lung = kBothLungs, .edge_length_m = kEdge});
  return mesh;
}

void counters(benchmark::State& state) {
  state.counters["vertices"] = static_cast<double>(phantom().vertex_count());
  state.counters["triangles"] = static_cast<double>(phantom().triangle_count());
}

void BM_OneFrame(benchmark::State& state) {
  std::vector<Eigen::Vector3d> u = vertex_normals(phantom()), positions;
  for (auto& v : u) v *= 5e-3;
  DeformedSurface surface(phantom().vertices, u, phantom().triangles);
  for (auto _ : state) benchmark::DoNotOptimize(surface.update(0.5, positions));
  counters(state);
}

// CPU time of the whole process (every thread), in seconds: the total work.
double process_cpu_s() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + static_cast<double>(t.tv_nsec) * 1e-9;
}

void BM_SelfIntersects(benchmark::State& state) {
  const auto concurrency = state.range(0) ? Concurrency::parallel : Concurrency::serial;
  bool found = true;
  phantom();
  const double cpu_start = process_cpu_s();
  for (auto _ : state) found = self_intersects(phantom(), concurrency);
  state.counters["process_cpu_s"] = (process_cpu_s() - cpu_start) / static_cast<double>(state.iterations());
  state.SetLabel(found ? "intersects (unexpected)" : "no intersection");
  counters(state);
}

void BM_Remesh(benchmark::State& state) {
  for (auto _ : state) {
    RemeshResult r =
        remesh_isotropic(phantom(), {.target_edge_length_m = kEdge, .iterations = 3, .measure_deviation = false});
    state.counters["triangles_out"] = static_cast<double>(r.mesh.triangle_count());
  }
  counters(state);
}

}  // namespace

BENCHMARK(BM_OneFrame)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(10);
BENCHMARK(BM_SelfIntersects)->Arg(0)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1)->Repetitions(3);
BENCHMARK(BM_SelfIntersects)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1)->Repetitions(3);
BENCHMARK(BM_Remesh)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);
BENCHMARK_MAIN();
