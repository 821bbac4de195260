// One time point of the voxel outputs on a CT-sized grid (256 x 256 x 200, 1.5 x 1.5 x 2 mm) with
// a lung-sized tet mesh (an ellipsoid of Kuhn-cut cubic cells, about 1M tets): the pull-back DVF
// and the label map warped through it (what a warped 4D label map costs per time point), with the
// forward DVF as the baseline of the same run (the same rasteriser over the rest tets). Results
// go in BENCHMARKS.md, never in tests.
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "pneuma/voxels/density.h"
#include "pneuma/voxels/dvf.h"
#include "pneuma/voxels/jacobian.h"
#include "pneuma/voxels/voxel_io.h"
#include "pneuma/voxels/warp.h"

using namespace pneuma;
using namespace pneuma::voxels;

namespace {

struct Scene {
  mesh::TetMesh mesh;
  std::vector<Eigen::Vector3d> u;
  Grid grid;
  image::LabelMap labels;

  Scene() {
    grid.size = {256, 256, 200};
    grid.ijk_to_lps.block<3, 3>(0, 0) = Eigen::Vector3d(1.5e-3, 1.5e-3, 2e-3).asDiagonal();
    const Eigen::Vector3d centre_m(191.25e-3, 191.25e-3, 199e-3);
    const Eigen::Vector3d axes_m(120e-3, 100e-3, 140e-3);
    const auto inside = [&](const Eigen::Vector3d& p) {
      return (p - centre_m).cwiseQuotient(axes_m).squaredNorm() < 1;
    };
    // Cubic cells of 3.6 mm over the ellipsoid's box, the cells whose centre is inside, 6 tets each.
    const double h = 3.6e-3;
    const Eigen::Vector3d corner = centre_m - axes_m;
    const std::array<int, 3> n{static_cast<int>(2 * axes_m.x() / h) + 1, static_cast<int>(2 * axes_m.y() / h) + 1,
                               static_cast<int>(2 * axes_m.z() / h) + 1};
    const int px = n[0] + 1, py = n[1] + 1, pz = n[2] + 1;
    for (int k = 0; k < pz; ++k)
      for (int j = 0; j < py; ++j)
        for (int i = 0; i < px; ++i) mesh.nodes.push_back(corner + h * Eigen::Vector3d(i, j, k));
    const auto node = [&](int i, int j, int k) { return static_cast<std::uint32_t>(i + px * (j + py * k)); };
    const std::array<std::array<int, 3>, 6> orders{{{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}}};
    for (int k = 0; k < n[2]; ++k)
      for (int j = 0; j < n[1]; ++j)
        for (int i = 0; i < n[0]; ++i) {
          if (!inside(corner + h * Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5))) continue;
          for (const auto& order : orders) {
            std::array<int, 3> at{i, j, k};
            mesh::Tetrahedron tet{node(i, j, k), 0, 0, 0};
            for (std::size_t s = 0; s < 3; ++s) {
              ++at[static_cast<std::size_t>(order[s])];
              tet[s + 1] = node(at[0], at[1], at[2]);
            }
            if (mesh::tet_volume6(mesh.nodes[tet[0]], mesh.nodes[tet[1]], mesh.nodes[tet[2]], mesh.nodes[tet[3]]) < 0) {
              std::swap(tet[2], tet[3]);
            }
            mesh.tets.push_back(tet);
          }
        }
    // Breathing-like: the base descends most (up to 15 mm), the sides move out a little.
    for (const Eigen::Vector3d& x : mesh.nodes) {
      const Eigen::Vector3d r = (x - centre_m).cwiseQuotient(axes_m);
      u.emplace_back(4e-3 * r.x(), -3e-3 * r.y(), -7.5e-3 * (1.0 - r.z()));
    }
    labels.size = grid.size;
    labels.ijk_to_lps = grid.ijk_to_lps;
    labels.labels.assign(grid.voxel_count(), 0);
    for (std::size_t k = 0; k < grid.size[2]; ++k)
      for (std::size_t j = 0; j < grid.size[1]; ++j)
        for (std::size_t i = 0; i < grid.size[0]; ++i) {
          const Eigen::Vector3d x = grid.centre_m(i, j, k);
          if (inside(x)) labels.labels[grid.index(i, j, k)] = x.x() < centre_m.x() ? 1 : 2;
        }
  }
  std::vector<LungMotion> lungs() const { return {LungMotion{mesh, u, 1.0}}; }
};

const Scene& scene() {
  static const Scene s;
  return s;
}

void BM_ForwardDvf(benchmark::State& state) {
  const Scene& s = scene();
  for (auto _ : state) benchmark::DoNotOptimize(forward_dvf(s.grid, s.lungs()).displacement_m.data());
  state.counters["tets"] = static_cast<double>(s.mesh.tet_count());
  state.counters["voxels"] = static_cast<double>(s.grid.voxel_count());
}

// The rest lungs' voxels alone (rest_lungs: VoxelScene's mask on the label map's grid, made once
// a run at that grid whatever the output's spacing), on the scene's grid (range 0) or on a grid
// of that many tenths of a millimetre over its extent: at 36 (the cells' 3.6 mm) a tet holds
// about a voxel, the per-tet set-up against the voxels (#50, "The 2 mm grid's fixed costs").
void BM_RestLungs(benchmark::State& state) {
  const Scene& s = scene();
  const Grid grid =
      state.range(0) == 0 ? s.grid : grid_with_spacing(s.grid, 1e-4 * static_cast<double>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(rest_lungs(grid, s.lungs()).data());
  state.counters["tets"] = static_cast<double>(s.mesh.tet_count());
  state.counters["voxels"] = static_cast<double>(grid.voxel_count());
}

void BM_PullbackDvfAndWarpedLabels(benchmark::State& state) {
  const Scene& s = scene();
  for (auto _ : state) {
    const DisplacementField pull = pullback_dvf(s.grid, s.lungs());
    benchmark::DoNotOptimize(warp_labels(s.labels, pull).labels.data());
  }
  state.counters["tets"] = static_cast<double>(s.mesh.tet_count());
}

// The same, as a run over many time points has it: the field and the label map reused.
void BM_PullbackDvfAndWarpedLabelsReused(benchmark::State& state) {
  const Scene& s = scene();
  DisplacementField pull;
  image::LabelMap warped;
  pullback_dvf(s.grid, s.lungs(), pull);  // the buffers' first touch, outside the timing
  warp_labels(s.labels, pull, warped);
  for (auto _ : state) {
    pullback_dvf(s.grid, s.lungs(), pull);
    warp_labels(s.labels, pull, warped);
    benchmark::DoNotOptimize(warped.labels.data());
  }
}

void BM_ForwardDvfReused(benchmark::State& state) {
  const Scene& s = scene();
  DisplacementField field;
  forward_dvf(s.grid, s.lungs(), field);  // the buffers' first touch, outside the timing
  for (auto _ : state) {
    forward_dvf(s.grid, s.lungs(), field);
    benchmark::DoNotOptimize(field.displacement_m.data());
  }
}

void BM_JacobianStats(benchmark::State& state) {
  const Scene& s = scene();
  for (auto _ : state) benchmark::DoNotOptimize(jacobian_stats(s.lungs()).min);
}

// The Jacobian image (the recovered gradient's inside the lung, differences outside) from the
// forward DVF, and the recovery's own pass over the tets (#45: what the image's recovery adds).
void BM_JacobianImage(benchmark::State& state) {
  const Scene& s = scene();
  const DisplacementField forward = forward_dvf(s.grid, s.lungs());
  Image image;
  jacobian_image(s.lungs(), forward, image);  // the buffer's first touch, outside the timing
  for (auto _ : state) {
    jacobian_image(s.lungs(), forward, image);
    benchmark::DoNotOptimize(image.values.data());
  }
}

void BM_RecoveredGradients(benchmark::State& state) {
  const Scene& s = scene();
  for (auto _ : state) benchmark::DoNotOptimize(recovered_gradients(s.lungs()[0]).data());
}

// Writing the pull-back DVF as .nii.gz (ITK writes the plain .nii, pneuma gzips it: voxels/gzip.h).
void BM_WritePullbackNiftiGz(benchmark::State& state) {
  const Scene& s = scene();
  const DisplacementField pull = pullback_dvf(s.grid, s.lungs());
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "pneuma-voxels-bench";
  for (auto _ : state) write_dvf(dir / "dvf-pullback.nii.gz", pull);
  std::filesystem::remove_all(dir);
}

// The external baseline: `plastimatch warp --interpolation nn` of the same label map through the
// same field, files read and written (.nii, uncompressed) included; skipped without plastimatch.
void BM_PlastimatchWarpLabels(benchmark::State& state) {
  if (!std::filesystem::exists("/usr/bin/plastimatch")) {
    state.SkipWithError("plastimatch is not installed");
    return;
  }
  const Scene& s = scene();
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "pneuma-voxels-bench";
  write_dvf(dir / "pull.nii", pullback_dvf(s.grid, s.lungs()));
  write_label_map(dir / "labels.nii", s.labels);
  const std::string command = "/usr/bin/plastimatch warp --input " + (dir / "labels.nii").string() + " --output-img " +
                              (dir / "out.nii").string() + " --xf " + (dir / "pull.nii").string() +
                              " --interpolation nn > /dev/null 2>&1";
  for (auto _ : state) {
    if (std::system(command.c_str()) != 0) state.SkipWithError("plastimatch failed");
  }
  std::filesystem::remove_all(dir);
}

}  // namespace

BENCHMARK(BM_ForwardDvf)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_PullbackDvfAndWarpedLabels)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_RestLungs)->Arg(0)->Arg(36)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK(BM_ForwardDvfReused)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_PullbackDvfAndWarpedLabelsReused)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_JacobianStats)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_JacobianImage)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK(BM_RecoveredGradients)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WritePullbackNiftiGz)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);
BENCHMARK(BM_PlastimatchWarpLabels)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);

BENCHMARK_MAIN();
