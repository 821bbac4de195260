// What the realistic tissue (healthy-upright) costs beyond the uniform field, stage by stage, on
// one mesh file (#50, BENCHMARKS.md "The realistic field at the speed of its solve").
// Usage: PNEUMA_BENCH_MESH=right.ply tissue_stages_bench [--benchmark_repetitions=5]
// The mesh is read once; each stage is timed alone (wall time, real_time).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

#include "pneuma/field/tissue.h"
#include "pneuma/mesh/anatomy/regions.h"
#include "pneuma/mesh/geometry/surface_hits.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "pneuma/scenario/tissue_config.h"

namespace {

using namespace pneuma;

const mesh::TriangleMesh& bench_mesh() {
  static const mesh::TriangleMesh m = [] {
    const char* path = std::getenv("PNEUMA_BENCH_MESH");
    if (!path) throw std::runtime_error("set PNEUMA_BENCH_MESH to a mesh file");
    return mesh::read_mesh(path);
  }();
  return m;
}

const field::Tissue& healthy() {
  static const field::Tissue t =
      scenario::load_tissue(std::string(PNEUMA_BENCH_SOURCE_DIR) + "/configs/tissue/healthy-upright.yaml");
  return t;
}

void BM_FindRegions(benchmark::State& state) {
  mesh::RegionOptions o;
  o.axes = field::body_axes(healthy());
  for (auto _ : state) benchmark::DoNotOptimize(mesh::find_regions(bench_mesh(), o));
}
void BM_SmoothedNormals10mm(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(mesh::smoothed_normals(bench_mesh(), 0.01));
}
void BM_SmoothedNormals20mm(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(mesh::smoothed_normals(bench_mesh(), 0.02));
}
void BM_SmoothedNormals3mm(benchmark::State& state) {
  bench_mesh();  // read before the clock starts
  for (auto _ : state) benchmark::DoNotOptimize(mesh::smoothed_normals(bench_mesh(), 0.003));
}
// The thin-lung bound's rays (field/thin_lung.cpp): inward along the 3 mm normals, 20 mm reach.
void BM_FirstHits20mm(benchmark::State& state) {
  std::vector<Eigen::Vector3d> inward = mesh::smoothed_normals(bench_mesh(), 0.003);
  for (auto& d : inward) d = -d;
  std::size_t found = 0;
  for (auto _ : state) {
    const auto hits = mesh::first_hits_from_vertices(bench_mesh(), inward, 0.02);
    found = static_cast<std::size_t>(std::count_if(hits.begin(), hits.end(), [](const auto& h) { return h.found; }));
  }
  state.counters["found"] = static_cast<double>(found);
}
void BM_BlurredInSpace3mm(benchmark::State& state) {
  const std::vector<double> value(bench_mesh().vertices.size(), 1.0);
  for (auto _ : state) benchmark::DoNotOptimize(mesh::blurred_in_space(bench_mesh(), value, 0.003));
}
void BM_HullProxy2mm(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(mesh::hull_proxy_points(bench_mesh().vertices, 2e-3));
}
void BM_HullDepth2000(benchmark::State& state) {
  const auto proxy = mesh::hull_proxy_points(bench_mesh().vertices, 2e-3);
  std::vector<Eigen::Vector3d> queries;
  const auto& v = bench_mesh().vertices;
  for (std::size_t i = 0; i < v.size(); i += std::max<std::size_t>(v.size() / 2000, 1)) queries.push_back(v[i]);
  for (auto _ : state) benchmark::DoNotOptimize(mesh::depth_below_convex_hull(proxy, queries));
}
void BM_HullDepth1(benchmark::State& state) {
  const auto proxy = mesh::hull_proxy_points(bench_mesh().vertices, 2e-3);
  state.counters["proxy"] = static_cast<double>(proxy.size());
  const std::vector<Eigen::Vector3d> queries{bench_mesh().vertices[0]};
  for (auto _ : state) benchmark::DoNotOptimize(mesh::depth_below_convex_hull(proxy, queries));
}
void BM_VertexAreas(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(mesh::vertex_areas(bench_mesh()));
}
void BM_TissueInputs(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(field::tissue_field_inputs(bench_mesh(), healthy()));
}
void BM_FieldHealthy(benchmark::State& state) {
  const auto inputs = field::tissue_field_inputs(bench_mesh(), healthy());
  for (auto _ : state) benchmark::DoNotOptimize(field::compute_field(bench_mesh(), inputs));
}

BENCHMARK(BM_FindRegions)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SmoothedNormals10mm)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SmoothedNormals20mm)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SmoothedNormals3mm)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FirstHits20mm)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_BlurredInSpace3mm)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_HullProxy2mm)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_HullDepth2000)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_HullDepth1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_VertexAreas)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_TissueInputs)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FieldHealthy)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

int main(int argc, char** argv) {
  if (std::getenv("SIDES")) {
    for (double cell : {2e-3, 3e-3, 4e-3})
      for (std::size_t n : {2000, 1000, 500}) {
        mesh::RegionOptions o;
        o.axes = field::body_axes(healthy());
        o.hull_proxy_cell_m = cell;
        o.side_sample = n;
        auto r = mesh::find_regions(bench_mesh(), o);
        double best = 1e9;
        for (int k = 0; k < 7; ++k) {
          const auto t0 = std::chrono::steady_clock::now();
          r = mesh::find_regions(bench_mesh(), o);
          best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        }
        std::printf("%.1f ms ", best * 1e3);
        std::printf("%s cell %.0f mm sample %zu: left %.3f right %.3f mm side %s\n", std::getenv("PNEUMA_BENCH_MESH"),
                    cell * 1e3, n, r.left_face_depth * 1e3, r.right_face_depth * 1e3,
                    r.side == mesh::Lung::right ? "right" : "left");
      }
    return 0;
  }
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
}
