// Mesh pipeline on a one-million-triangle phantom (both lungs, 0.58 mm edges): generate, write,
// load (assimp + merge), validate (with and without CGAL's self-intersection test), remesh
// (CGAL isotropic_remeshing to the same edge length, 3 iterations).
// Baseline in the same run: reading the same file's bytes into memory (the I/O floor of load).
// Peak memory: getrusage's maxrss after each step. Steps run from the lightest to the heaviest,
// so the counter is the peak of the process up to and including that step.
#include <benchmark/benchmark.h>
#include <sys/resource.h>

#include <filesystem>
#include <fstream>
#include <vector>

#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/mesh/geometry/validate.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "pneuma/mesh/repair/remesh.h"

namespace {

using namespace pneuma::mesh;

constexpr double kEdge = 0.58e-3;  // 4 A / (sqrt(3) h^2) = 1.0e6 triangles for both lungs

const std::filesystem::path& phantom_file() {
  static const std::filesystem::path path = [] {
    auto p = std::filesystem::temp_directory_path() / "pneuma-mesh-bench.ply";
    write_mesh(p, make_lung_phantom({.lung = kBothLungs, .edge_length_m = kEdge}));
    return p;
  }();
  return path;
}

const TriangleMesh& loaded() {
  static const TriangleMesh m = read_mesh(phantom_file());
  return m;
}

void peak_memory(benchmark::State& state) {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  state.counters["peak_rss_MiB"] = static_cast<double>(usage.ru_maxrss) / 1024.0;
}

void BM_Generate(benchmark::State& state) {
  for (auto _ : state) {
    TriangleMesh m = make_lung_phantom({.lung = kBothLungs, .edge_length_m = kEdge});
    benchmark::DoNotOptimize(m.vertices.data());
    state.counters["triangles"] = static_cast<double>(m.triangle_count());
  }
  peak_memory(state);
}

void BM_WriteBinaryPly(benchmark::State& state) {
  const TriangleMesh& m = loaded();  // loaded once, outside the timing
  const auto out = std::filesystem::temp_directory_path() / "pneuma-mesh-bench-out.ply";
  for (auto _ : state) write_mesh(out, m);
  state.counters["MiB"] = static_cast<double>(std::filesystem::file_size(out)) / (1 << 20);
  std::filesystem::remove(out);
  peak_memory(state);
}

void BM_ReadBytesBaseline(benchmark::State& state) {
  const auto& path = phantom_file();  // generated once, outside the timing
  std::vector<char> bytes(std::filesystem::file_size(path));
  for (auto _ : state) {
    std::ifstream in(path, std::ios::binary);
    in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    benchmark::DoNotOptimize(bytes.data());
  }
  peak_memory(state);
}

void BM_Load(benchmark::State& state) {
  phantom_file();
  for (auto _ : state) {
    TriangleMesh m = read_mesh(phantom_file());
    benchmark::DoNotOptimize(m.vertices.data());
  }
  peak_memory(state);
}

void BM_ValidateTopology(benchmark::State& state) {
  for (auto _ : state) {
    auto r = validate(loaded(), {.check_self_intersections = false});
    benchmark::DoNotOptimize(r.edge_count);
  }
  peak_memory(state);
}

void BM_ValidateWithSelfIntersections(benchmark::State& state) {
  for (auto _ : state) {
    auto r = validate(loaded());
    if (!r.valid()) state.SkipWithError(r.summary().c_str());
  }
  peak_memory(state);
}

void BM_Remesh(benchmark::State& state) {
  for (auto _ : state) {
    RemeshResult r =
        remesh_isotropic(loaded(), {.target_edge_length_m = kEdge, .iterations = 3, .measure_deviation = false});
    state.counters["triangles_out"] = static_cast<double>(r.mesh.triangle_count());
  }
  peak_memory(state);
}

}  // namespace

BENCHMARK(BM_ReadBytesBaseline)->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK(BM_Load)->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK(BM_WriteBinaryPly)->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK(BM_Generate)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_ValidateTopology)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_ValidateWithSelfIntersections)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_Remesh)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK_MAIN();
