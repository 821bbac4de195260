// How far the pull-back outside the lungs solved on a coarse lattice and interpolated
// (BodyMotion::Frame::inverse_field, what the voxel outputs use since #50) is from the exact
// per-voxel inverse (BodyMotion::Frame::inverse, what they used before), at every voxel of a
// scenario's voxel grid, at each lung's lowest and highest scale of the run. Not a Google
// Benchmark: one pass, figures for docs/voxels.md and BENCHMARKS.md.
// Usage: body_inverse_bench SCENARIO.yaml CACHE_FOLDER [SPACING_MM (0: the label map's own grid)] [REFINE...]
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <fmt/core.h>

#include "pneuma/model/body_motion.h"
#include "pneuma/runner/output_registry.h"
#include "pneuma/runner/runner.h"
#include "pneuma/scenario/scenario.h"
#include "pneuma/voxels/dvf.h"
#include "pneuma/voxels/grid.h"

using namespace pneuma;

namespace {

struct Worst {
  double all_m = 0.0, outside_m = 0.0, residual_m = 0.0, largest_m = 0.0;
  void add(const Worst& o) {
    all_m = std::max(all_m, o.all_m);
    outside_m = std::max(outside_m, o.outside_m);
    residual_m = std::max(residual_m, o.residual_m);
    largest_m = std::max(largest_m, o.largest_m);
  }
};

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    fmt::print(stderr, "usage: {} SCENARIO.yaml CACHE_FOLDER [SPACING_MM] [REFINE...]\n", argv[0]);
    return 2;
  }
  const std::filesystem::path cache = argv[2];
  std::filesystem::create_directories(cache);
  const double spacing_m = argc > 3 ? std::atof(argv[3]) * 1e-3 : 0.0;
  std::vector<std::size_t> refines;
  for (int a = 4; a < argc; ++a) refines.push_back(static_cast<std::size_t>(std::atoi(argv[a])));
  if (refines.empty()) refines = {2, 3};

  const scenario::Scenario s = runner::load_scenario(argv[1]);
  const auto drive = scenario::simulate_physiology(s, s.frame_rate_hz);
  const runner::Prepared c =
      runner::prepare(s, drive, {.auto_cache_file = cache / "field.h5", .interior = true, .drive = &drive});
  if (!c.model.body || !c.model.label_map) {
    fmt::print(stderr, "the scenario needs a label map and the body field\n");
    return 2;
  }
  voxels::Grid grid = voxels::grid_of(*c.model.label_map);
  if (spacing_m > 0.0) grid = voxels::grid_with_spacing(grid, spacing_m);
  fmt::print("grid {} x {} x {} ({:.1f} Mvoxels)\n", grid.size[0], grid.size[1], grid.size[2],
             static_cast<double>(grid.voxel_count()) * 1e-6);
  const auto [lo, hi] = grid.centres_box_m();

  for (const bool highest : {false, true}) {
    std::vector<double> scales;
    std::vector<voxels::LungMotion> lungs;
    for (std::size_t l = 0; l < c.model.lungs.size(); ++l) {
      scales.push_back(highest ? c.scales[l].max_scale : c.scales[l].min_scale);
      const model::LungInterior& inside = *c.model.lungs[l].interior;
      lungs.push_back({inside.mesh, inside.unit_displacement, scales.back()});
    }
    const model::BodyMotion::Frame frame = c.model.body->frame(scales);
    // Which voxels the deformed lungs hold (their pull-back comes from the tets, not the body).
    const voxels::DisplacementField in_lungs = voxels::pullback_dvf(grid, lungs);
    // The exact inverse per voxel, each row in order from the line through the two before (the
    // code the voxel outputs ran before #50).
    std::vector<Eigen::Vector3f> exact(grid.voxel_count());
    const auto t0 = std::chrono::steady_clock::now();
    const std::size_t rows = grid.size[1] * grid.size[2];
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rows), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t row = r.begin(); row != r.end(); ++row) {
        const std::size_t j = row % grid.size[1], k = row / grid.size[1];
        Eigen::Vector3d previous = Eigen::Vector3d::Zero(), before = previous;
        for (std::size_t i = 0; i < grid.size[0]; ++i) {
          const Eigen::Vector3d x = grid.centre_m(i, j, k);
          const Eigen::Vector3d guess = i >= 2   ? Eigen::Vector3d(2.0 * previous - before)
                                        : i == 1 ? previous
                                                 : Eigen::Vector3d(-frame.displacement(x));
          const Eigen::Vector3d v = frame.inverse(x, guess);
          exact[grid.index(i, j, k)] = v.cast<float>();
          before = previous;
          previous = v;
        }
      }
    });
    const double exact_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    fmt::print("scales {}: exact per-voxel inverse {:.2f} s wall\n", highest ? "highest" : "lowest", exact_s);
    for (const std::size_t refine : refines) {
      const auto t1 = std::chrono::steady_clock::now();
      const model::BodyMotion::Frame inverse = frame.inverse_field(lo, hi, refine);
      const double lattice_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
      const Worst worst = tbb::parallel_reduce(
          tbb::blocked_range<std::size_t>(0, rows), Worst{},
          [&](const tbb::blocked_range<std::size_t>& r, Worst w) {
            for (std::size_t row = r.begin(); row != r.end(); ++row) {
              const std::size_t j = row % grid.size[1], k = row / grid.size[1];
              for (std::size_t i = 0; i < grid.size[0]; ++i) {
                const std::size_t v = grid.index(i, j, k);
                const Eigen::Vector3d x = grid.centre_m(i, j, k);
                const Eigen::Vector3d approx = inverse.displacement(x);
                const double difference = (approx - exact[v].cast<double>()).norm();
                w.all_m = std::max(w.all_m, difference);
                if (in_lungs.lung[v] == 0) {
                  w.outside_m = std::max(w.outside_m, difference);
                  w.residual_m = std::max(w.residual_m, (approx + frame.displacement(x + approx)).norm());
                  w.largest_m = std::max(w.largest_m, static_cast<double>(exact[v].norm()));
                }
              }
            }
            return w;
          },
          [](Worst a, const Worst& b) {
            a.add(b);
            return a;
          });
      fmt::print("  lattice {:.2f} mm ({:.2f} s wall): outside the lungs largest |v| {:.2f} mm, largest "
                 "difference from the exact inverse {:.4f} mm (everywhere {:.4f} mm), largest residual |v + u(x + v)| "
                 "{:.4f} mm\n",
                 c.model.body->options().cell_m * 1e3 / static_cast<double>(refine), lattice_s, worst.largest_m * 1e3,
                 worst.outside_m * 1e3, worst.all_m * 1e3, worst.residual_m * 1e3);
    }
  }
  return 0;
}
