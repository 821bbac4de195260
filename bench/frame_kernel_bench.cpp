// The fused frame kernel (mesh::DeformedSurface::update: positions = rest + s u, enclosed volume
// and area in one threaded, vectorised pass) in vertices per second, against baselines measured in
// the same run:
//   copy (BM_Copy): std::copy of the rest positions into the frame buffer (24 B read + 24 B written
//     per vertex), the floor of any frame update;
//   the runner's update before the kernel (BM_DisplaceAndCgalArea): positions = rest + s u (plain
//     loop), then the area with mesh::AreaMeter (CGAL PMP::area), single-threaded.
// Also the kernel at one thread (tbb::global_control) and on the SSE2 path, and the update with V
// and A tabulated (positions only per frame; BM_TabulatedUpdate) with the table's one-off cost.
// bench/frame_vs_numpy.sh compares the updates with numpy's `rest + s*u` in the same session.
// Meshes: the phantom, both lungs, 1.30 mm edges (100,844 vertices) and 0.411 mm (1,003,704);
// synthetic field (rest normals x 5 mm: the cost does not depend on the values).
// Argument: 0 = ~100k vertices, 1 = ~1M vertices, 2 = ~240k (the issue #35 size). Results: BENCHMARKS.md, "Frame
// kernel".
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <map>
#include <memory>
#include <stdexcept>
#include <vector>

#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/mesh/geometry/deformed_surface.h"
#include "pneuma/mesh/geometry/surface_queries.h"

namespace {

using namespace pneuma;

constexpr double kEdge[] = {1.30e-3, 0.411e-3, 0.843e-3};

struct Case {
  mesh::TriangleMesh rest;
  std::vector<Eigen::Vector3d> u, positions;
  std::unique_ptr<mesh::DeformedSurface> surface;
  std::unique_ptr<mesh::DeformedSurface> tabulated;  // with V and A tabulated over s in [0.5, 1.0]
};

Case& test_case(std::int64_t size) {
  static std::map<std::int64_t, std::unique_ptr<Case>> cases;
  auto& slot = cases[size];
  if (!slot) {
    slot = std::make_unique<Case>();
    slot->rest =
        mesh::make_lung_phantom({.lung = mesh::kBothLungs, .edge_length_m = kEdge[static_cast<std::size_t>(size)]});
    slot->u = mesh::vertex_normals(slot->rest);
    for (auto& v : slot->u) v *= 5e-3;
    slot->positions.assign(slot->rest.vertex_count(), Eigen::Vector3d::Zero());
    slot->surface = std::make_unique<mesh::DeformedSurface>(slot->rest.vertices, slot->u, slot->rest.triangles);
    slot->tabulated = std::make_unique<mesh::DeformedSurface>(slot->rest.vertices, slot->u, slot->rest.triangles);
    if (!slot->tabulated->tabulate_measures(0.5, 1.0)) throw std::runtime_error("no table");
  }
  return *slot;
}

void report(benchmark::State& state, const Case& c) {
  const auto n = static_cast<std::int64_t>(c.rest.vertex_count());
  state.SetItemsProcessed(state.iterations() * n);  // items = vertices
  state.counters["vertices"] = static_cast<double>(n);
  state.counters["triangles"] = static_cast<double>(c.rest.triangle_count());
}

void BM_Copy(benchmark::State& state) {
  Case& c = test_case(state.range(0));
  for (auto _ : state) {
    std::copy(c.rest.vertices.begin(), c.rest.vertices.end(), c.positions.begin());
    benchmark::DoNotOptimize(c.positions.data());
    benchmark::ClobberMemory();
  }
  report(state, c);
}

void BM_DisplaceAndCgalArea(benchmark::State& state) {
  Case& c = test_case(state.range(0));
  mesh::AreaMeter meter(c.rest);
  double s = 0.5;
  for (auto _ : state) {
    for (std::size_t i = 0; i < c.positions.size(); ++i) c.positions[i] = c.rest.vertices[i] + s * c.u[i];
    benchmark::DoNotOptimize(meter.area(c.positions));
    s = s > 1.0 ? 0.5 : s + 1e-3;
  }
  report(state, c);
}

void kernel(benchmark::State& state, Case& c, mesh::DeformedSurface& surface) {
  double s = 0.5;
  for (auto _ : state) {
    benchmark::DoNotOptimize(surface.update(s, c.positions));
    benchmark::ClobberMemory();
    s = s > 1.0 ? 0.5 : s + 1e-3;
  }
  report(state, c);
  state.SetLabel(mesh::DeformedSurface::instruction_set());
}

void BM_FusedKernel(benchmark::State& state) {
  Case& c = test_case(state.range(0));
  kernel(state, c, *c.surface);
}

// What a run's frame update is since its scales are known up front: positions only, V and A from
// the table (the frame the runner advances; model::Frame with the run's ScaleRange).
void BM_TabulatedUpdate(benchmark::State& state) {
  Case& c = test_case(state.range(0));
  kernel(state, c, *c.tabulated);
}

// The table's cost, paid once per run and lung (33 or more exact measure() passes).
void BM_TabulateMeasures(benchmark::State& state) {
  Case& c = test_case(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(c.surface->tabulate_measures(0.5, 1.0));
  report(state, c);
}

void BM_FusedKernelOneThread(benchmark::State& state) {
  Case& c = test_case(state.range(0));
  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  kernel(state, c, *c.surface);
}

void BM_FusedKernelSse2(benchmark::State& state) {
  Case& c = test_case(state.range(0));
  mesh::DeformedSurface::limit_instruction_set("sse2");
  kernel(state, c, *c.surface);
  mesh::DeformedSurface::limit_instruction_set("avx2");
}

}  // namespace

#define PNEUMA_FRAME_BENCH(fn, size, reps) \
  BENCHMARK(fn)->Arg(size)->Unit(benchmark::kMicrosecond)->Repetitions(reps)->ReportAggregatesOnly(true)->UseRealTime()

PNEUMA_FRAME_BENCH(BM_Copy, 0, 5);
PNEUMA_FRAME_BENCH(BM_FusedKernel, 0, 5);
PNEUMA_FRAME_BENCH(BM_FusedKernelOneThread, 0, 5);
PNEUMA_FRAME_BENCH(BM_FusedKernelSse2, 0, 5);
PNEUMA_FRAME_BENCH(BM_DisplaceAndCgalArea, 0, 3);
PNEUMA_FRAME_BENCH(BM_TabulatedUpdate, 0, 5);
PNEUMA_FRAME_BENCH(BM_Copy, 2, 5);
PNEUMA_FRAME_BENCH(BM_FusedKernel, 2, 5);
PNEUMA_FRAME_BENCH(BM_TabulatedUpdate, 2, 5);
PNEUMA_FRAME_BENCH(BM_TabulateMeasures, 2, 3);
PNEUMA_FRAME_BENCH(BM_Copy, 1, 5);
PNEUMA_FRAME_BENCH(BM_FusedKernel, 1, 5);
PNEUMA_FRAME_BENCH(BM_TabulatedUpdate, 1, 5);
PNEUMA_FRAME_BENCH(BM_TabulateMeasures, 1, 3);
PNEUMA_FRAME_BENCH(BM_Copy, 1, 5);
PNEUMA_FRAME_BENCH(BM_FusedKernelOneThread, 1, 5);
PNEUMA_FRAME_BENCH(BM_FusedKernelSse2, 1, 5);
PNEUMA_FRAME_BENCH(BM_DisplaceAndCgalArea, 1, 3);
BENCHMARK_MAIN();
