// Label map -> surface on the six CT lobe maps (../shared/data/ct-lobes, CC BY 4.0: see its
// README.md; or PNEUMA_CT_LOBES). Baseline in the same run: reading and decompressing the NIfTI
// (read_label_map). One iteration each (seconds per case); peak memory: bench/labels_memory.sh.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "pneuma/mesh/labels/labels.h"

namespace {

std::filesystem::path data_dir() {
  if (const char* env = std::getenv("PNEUMA_CT_LOBES")) return env;
  return std::filesystem::path(PNEUMA_BENCH_SOURCE_DIR) / ".." / "shared" / "data" / "ct-lobes";
}

const char* const kCases[] = {"case004", "case005", "case006", "case007", "case008", "case009"};

std::filesystem::path file_of(int c) { return data_dir() / (std::string(kCases[c]) + "_lobes.nii.gz"); }

void BM_ReadLabelMap(benchmark::State& state) {
  const auto file = file_of(static_cast<int>(state.range(0)));
  if (!std::filesystem::exists(file)) return state.SkipWithError("no CT lobe maps (set PNEUMA_CT_LOBES)");
  for (auto _ : state) benchmark::DoNotOptimize(pneuma::image::read_label_map(file));
  state.SetLabel(kCases[state.range(0)]);
}

void BM_SurfaceFromLabels(benchmark::State& state) {
  const auto file = file_of(static_cast<int>(state.range(0)));
  if (!std::filesystem::exists(file)) return state.SkipWithError("no CT lobe maps (set PNEUMA_CT_LOBES)");
  const bool right = state.range(1) == 0;
  const std::vector<int> labels = right ? std::vector<int>{3, 4, 5} : std::vector<int>{1, 2};
  std::size_t triangles = 0;
  int attempts = 0;
  for (auto _ : state) {
    const auto s = pneuma::mesh::surface_from_labels(file, labels);
    triangles = s.mesh.triangle_count();
    attempts = s.report.attempts;
  }
  state.counters["triangles"] = static_cast<double>(triangles);
  state.counters["attempts"] = attempts;
  state.SetLabel(std::string(kCases[state.range(0)]) + (right ? " right" : " left"));
}

}  // namespace

BENCHMARK(BM_ReadLabelMap)->DenseRange(0, 5)->Iterations(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SurfaceFromLabels)
    ->ArgsProduct({{0, 1, 2, 3, 4, 5}, {0, 1}})
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
