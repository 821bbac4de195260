// The lung's inside (#31) on a real CT lung: case004's right lung (../shared/data/ct-lobes,
// CC BY 4.0: see its README.md; or PNEUMA_CT_LOBES), surface extracted at 2 mm (and at 1 mm for
// the whole inside). Per tetrahedron size and mesher (0 delaunay, 1 lattice): the tets
// (mesh::tetrahedralize), the interior field (elastic and harmonic), and the whole inside as a run
// makes it (model::compute_interior: tets, boundary values, solve, unfolding). Baseline in the
// same run: the surface field of the same lung with healthy-upright (model::compute_field_record),
// which every run pays. One iteration each (seconds). Results: BENCHMARKS.md, "Interior".
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "pneuma/field/interior.h"
#include "pneuma/mesh/geometry/surface_queries.h"
#include "pneuma/mesh/labels/labels.h"
#include "pneuma/mesh/volume/tetrahedralize.h"
#include "pneuma/model/field_cache.h"
#include "pneuma/model/model.h"
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

const Lung* lung(double surface_edge_m = 2e-3, const std::string& tissue_name = "healthy-upright") {
  static std::map<std::pair<double, std::string>, std::unique_ptr<Lung>> lungs;
  auto& cached = lungs[{surface_edge_m, tissue_name}];
  if (cached) return cached.get();
  const auto file = data_dir() / "case004_lobes.nii.gz";
  if (!std::filesystem::exists(file)) return nullptr;
  cached = std::make_unique<Lung>();
  cached->surface = mesh::surface_from_labels(file, {3, 4, 5}, {.edge_length_m = surface_edge_m}).mesh;
  const auto tissue = scenario::load_tissue(std::filesystem::path(PNEUMA_BENCH_SOURCE_DIR) / "configs/tissue" /
                                            (tissue_name + ".yaml"));
  cached->unit_displacement = model::compute_field_record(cached->surface, tissue).unit_displacement;
  return cached.get();
}

mesh::TetMesher mesher_of(std::int64_t arg) { return arg == 0 ? mesh::TetMesher::delaunay : mesh::TetMesher::lattice; }

const mesh::VolumeMesh& volume(double edge_m, mesh::TetMesher mesher) {
  static std::map<std::pair<double, mesh::TetMesher>, mesh::VolumeMesh> meshes;
  const auto key = std::make_pair(edge_m, mesher);
  auto it = meshes.find(key);
  if (it == meshes.end())
    it = meshes.emplace(key, mesh::tetrahedralize(lung()->surface, {.mesher = mesher, .edge_length_m = edge_m})).first;
  return it->second;
}

// Arg: the surface's edge (0.1 mm).
void BM_SurfaceField(benchmark::State& state) {
  const Lung* l = lung(static_cast<double>(state.range(0)) * 1e-4);
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
  const mesh::TetMesher mesher = mesher_of(state.range(2));
  std::size_t tets = 0;
  for (auto _ : state) {
    const auto v =
        mesh::tetrahedralize(l->surface, {.mesher = mesher, .edge_length_m = edge, .sliver_bound_deg = bound});
    tets = v.mesh.tet_count();
    state.counters["min_dihedral_deg"] = v.min_dihedral_deg;
  }
  state.counters["tets"] = static_cast<double>(tets);
  state.SetLabel(mesher == mesh::TetMesher::lattice ? "lattice"
                 : bound > 0.0                      ? "delaunay, exuded"
                                                    : "delaunay, not exuded");
}

void BM_InteriorField(benchmark::State& state) {
  const Lung* l = lung();
  if (!l) return state.SkipWithError("no CT lobe maps (set PNEUMA_CT_LOBES)");
  const double edge = static_cast<double>(state.range(0)) * 1e-4;
  const auto model = state.range(1) == 0 ? field::InteriorModel::elastic : field::InteriorModel::harmonic;
  const mesh::VolumeMesh& v = volume(edge, mesher_of(state.range(2)));
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
  state.SetLabel(field::interior_model_name(model) + ", " + mesh::tet_mesher_name(mesher_of(state.range(2))));
}

// The whole inside of the lung's 1 mm surface, as a run computes it; args: tet edge (0.1 mm),
// mesher, unfolding (1: the default, 0: none), tissue (0: healthy-upright, 1: healthy-supine-slide).
void BM_WholeInterior(benchmark::State& state) {
  const Lung* l = lung(1e-3, state.range(3) == 0 ? "healthy-upright" : "healthy-supine-slide");
  if (!l) return state.SkipWithError("no CT lobe maps (set PNEUMA_CT_LOBES)");
  const double edge = static_cast<double>(state.range(0)) * 1e-4;
  const mesh::TetMesher mesher = mesher_of(state.range(1));
  field::InteriorOptions options;
  if (state.range(2) == 0) options.unfold_volume_m3 = 0.0;
  std::shared_ptr<model::LungInterior> interior;
  for (auto _ : state) interior = model::compute_interior(l->surface, l->unit_displacement, edge, options, mesher);
  state.counters["unfolded_nodes"] = static_cast<double>(interior->report.unfolded_nodes);
  state.counters["tets"] = static_cast<double>(interior->mesh.tet_count());
  state.counters["nodes"] = static_cast<double>(interior->mesh.node_count());
  state.counters["cg_iterations"] = static_cast<double>(interior->report.iterations);
  state.counters["surface_vertices"] = static_cast<double>(l->surface.vertex_count());
  state.SetLabel(mesh::tet_mesher_name(mesher));
}

BENCHMARK(BM_SurfaceField)->Arg(20)->Arg(10)->Unit(benchmark::kSecond)->Iterations(1);
BENCHMARK(BM_Tetrahedralize)
    ->Args({50, 0, 0})
    ->Args({50, 10, 0})
    ->Args({40, 10, 0})
    ->Args({30, 10, 0})
    ->Args({50, 0, 1})
    ->Args({40, 0, 1})
    ->Args({30, 0, 1})
    ->Args({25, 0, 1})
    ->Args({20, 0, 1})
    ->Unit(benchmark::kSecond)
    ->Iterations(1);
BENCHMARK(BM_InteriorField)
    ->Args({50, 0, 0})
    ->Args({50, 1, 0})
    ->Args({40, 0, 0})
    ->Args({30, 0, 0})
    ->Args({50, 0, 1})
    ->Args({40, 0, 1})
    ->Args({30, 0, 1})
    ->Unit(benchmark::kSecond)
    ->Iterations(1);
BENCHMARK(BM_WholeInterior)
    ->Args({25, 1, 1, 0})
    ->Args({25, 1, 0, 0})
    ->Args({20, 1, 1, 0})
    ->Args({25, 1, 1, 1})
    ->Args({25, 1, 0, 1})
    ->Unit(benchmark::kSecond)
    ->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
