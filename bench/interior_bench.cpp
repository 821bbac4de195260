// The lung's inside (#31) on a real CT lung: case004's right lung (../shared/data/ct-lobes,
// CC BY 4.0: see its README.md; or PNEUMA_CT_LOBES), surface extracted at 2 mm. Per tetrahedron
// size: Mesh_3 (mesh::tetrahedralize) and the interior field (elastic and harmonic). Baseline in
// the same run: the surface field of the same lung with healthy-upright (model::compute_field_record),
// which every run pays. One iteration each (seconds). Results: BENCHMARKS.md, "Interior".
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>

#include "pneuma/field/interior.h"
#include "pneuma/mesh/geometry/surface_queries.h"
#include "pneuma/mesh/labels/labels.h"
#include "pneuma/mesh/volume/tetrahedralize.h"
#include "pneuma/model/field_cache.h"
#include "pneuma/scenario/tissue_config.h"

namespace {

using namespace pneuma;

std::filesystem::path data_dir() {
  if (const char* env = std::getenv("PNEUMA_CT_LOBES")) return env;
  return std::filesystem::path(PNEUMA_BENCH_SOURCE_DIR) / ".." / "shared" / "data" / "ct-lobes";
}

// The lung's surface and its field, made once.
struct Lung {
  mesh::TriangleMesh surface;
  std::vector<Eigen::Vector3d> unit_displacement;
};

const Lung* lung() {
  static std::unique_ptr<Lung> cached;
  if (cached) return cached.get();
  const auto file = data_dir() / "case004_lobes.nii.gz";
  if (!std::filesystem::exists(file)) return nullptr;
  cached = std::make_unique<Lung>();
  cached->surface = mesh::surface_from_labels(file, {3, 4, 5}).mesh;
  const auto tissue =
      scenario::load_tissue(std::filesystem::path(PNEUMA_BENCH_SOURCE_DIR) / "configs/tissue/healthy-upright.yaml");
  cached->unit_displacement = model::compute_field_record(cached->surface, tissue).unit_displacement;
  return cached.get();
}

const mesh::VolumeMesh& volume(double edge_m) {
  static std::map<double, mesh::VolumeMesh> meshes;
  auto it = meshes.find(edge_m);
  if (it == meshes.end())
    it = meshes.emplace(edge_m, mesh::tetrahedralize(lung()->surface, {.edge_length_m = edge_m})).first;
  return it->second;
}

void BM_SurfaceField(benchmark::State& state) {
  const Lung* l = lung();
  if (!l) return state.SkipWithError("no CT lobe maps (set PNEUMA_CT_LOBES)");
  const auto tissue =
      scenario::load_tissue(std::filesystem::path(PNEUMA_BENCH_SOURCE_DIR) / "configs/tissue/healthy-upright.yaml");
  for (auto _ : state) benchmark::DoNotOptimize(model::compute_field_record(l->surface, tissue));
  state.counters["vertices"] = static_cast<double>(l->surface.vertex_count());
}

void BM_Tetrahedralize(benchmark::State& state) {
  const Lung* l = lung();
  if (!l) return state.SkipWithError("no CT lobe maps (set PNEUMA_CT_LOBES)");
  const double edge = static_cast<double>(state.range(0)) * 1e-4;
  const double bound = static_cast<double>(state.range(1));
  std::size_t tets = 0;
  for (auto _ : state) {
    const auto v = mesh::tetrahedralize(l->surface, {.edge_length_m = edge, .sliver_bound_deg = bound});
    tets = v.mesh.tet_count();
    state.counters["min_dihedral_deg"] = v.min_dihedral_deg;
  }
  state.counters["tets"] = static_cast<double>(tets);
  state.SetLabel(bound > 0.0 ? "exuded" : "not exuded");
}

void BM_InteriorField(benchmark::State& state) {
  const Lung* l = lung();
  if (!l) return state.SkipWithError("no CT lobe maps (set PNEUMA_CT_LOBES)");
  const double edge = static_cast<double>(state.range(0)) * 1e-4;
  const auto model = state.range(1) == 0 ? field::InteriorModel::elastic : field::InteriorModel::harmonic;
  const mesh::VolumeMesh& v = volume(edge);
  std::vector<Eigen::Vector3d> points;
  for (const auto b : v.boundary_nodes) points.push_back(v.mesh.nodes[b]);
  const auto boundary = mesh::transfer_vertex_field(l->surface, l->unit_displacement, points);
  std::size_t iterations = 0;
  for (auto _ : state) {
    const auto s = field::solve_interior(v.mesh, v.boundary_nodes, boundary, {.model = model});
    iterations = s.report.iterations;
  }
  state.counters["tets"] = static_cast<double>(v.mesh.tet_count());
  state.counters["nodes"] = static_cast<double>(v.mesh.node_count());
  state.counters["cg_iterations"] = static_cast<double>(iterations);
  state.SetLabel(field::interior_model_name(model));
}

BENCHMARK(BM_SurfaceField)->Unit(benchmark::kSecond)->Iterations(1);
BENCHMARK(BM_Tetrahedralize)
    ->Args({50, 0})
    ->Args({50, 10})
    ->Args({40, 10})
    ->Args({30, 10})
    ->Unit(benchmark::kSecond)
    ->Iterations(1);
BENCHMARK(BM_InteriorField)
    ->Args({50, 0})
    ->Args({50, 1})
    ->Args({40, 0})
    ->Args({30, 0})
    ->Unit(benchmark::kSecond)
    ->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
