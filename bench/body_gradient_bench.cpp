// How steep the body field is right up to the pleura (#45: the tear check at 2 mm voxels is a
// pointwise bound on the field's gradient): |grad u| (spectral norm, central differences over
// 0.2 mm, so the trilinear field's own gradient) and the forward and pull-back Jacobian at every
// voxel of a scenario's grid outside the rest lungs, binned by the distance to them, at each
// lung's lowest and highest scale of the run. Not a Google Benchmark: one pass, figures for
// docs/voxels.md.
// Usage: body_gradient_bench SCENARIO.yaml CACHE_FOLDER [SPACING_MM [X Y Z (mm, LPS)...]]: with
// points, also each point's pull-back at the highest scales: from the tets (in a deformed lung)
// or the body's inverse, and the body's inverse beside it.
#include <algorithm>
#include <array>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <limits>
#include <vector>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <fmt/core.h>

#include "pneuma/model/body_motion.h"
#include "pneuma/runner/output_registry.h"
#include "pneuma/runner/runner.h"
#include "pneuma/scenario/scenario.h"
#include "pneuma/voxels/dvf.h"
#include "pneuma/voxels/grid.h"

using namespace pneuma;

int main(int argc, char** argv) {
  if (argc < 3) {
    fmt::print(stderr, "usage: {} SCENARIO.yaml CACHE_FOLDER [SPACING_MM]\n", argv[0]);
    return 2;
  }
  const std::filesystem::path cache = argv[2];
  std::filesystem::create_directories(cache);
  const double spacing_m = argc > 3 ? std::atof(argv[3]) * 1e-3 : 2e-3;
  const scenario::Scenario s = runner::load_scenario(argv[1]);
  const auto drive = scenario::simulate_physiology(s, s.frame_rate_hz);
  const runner::Prepared c =
      runner::prepare(s, drive, {.auto_cache_file = cache / "field.h5", .interior = true, .drive = &drive});
  if (!c.model.body || !c.model.label_map) {
    fmt::print(stderr, "the scenario needs a label map and the body field\n");
    return 2;
  }
  const voxels::Grid grid = voxels::grid_with_spacing(voxels::grid_of(*c.model.label_map), spacing_m);
  std::vector<voxels::LungMotion> lungs;
  for (const auto& lung : c.model.lungs) lungs.push_back({lung.interior->mesh, lung.interior->unit_displacement, 0.0});
  const std::vector<std::uint8_t> rest = voxels::rest_lungs(grid, lungs);
  // The distance to the rest lungs in voxels along the grid's axes (a city-block ring count: a bin, not a measure).
  std::vector<int> ring(grid.voxel_count(), std::numeric_limits<int>::max());
  std::deque<std::size_t> queue;
  for (std::size_t v = 0; v < ring.size(); ++v)
    if (rest[v] != 0) {
      ring[v] = 0;
      queue.push_back(v);
    }
  const std::array<std::size_t, 3> n = grid.size;
  while (!queue.empty()) {
    const std::size_t v = queue.front();
    queue.pop_front();
    const std::size_t i = v % n[0], j = (v / n[0]) % n[1], k = v / (n[0] * n[1]);
    const std::array<std::ptrdiff_t, 6> step{-1,
                                             1,
                                             -static_cast<std::ptrdiff_t>(n[0]),
                                             static_cast<std::ptrdiff_t>(n[0]),
                                             -static_cast<std::ptrdiff_t>(n[0] * n[1]),
                                             static_cast<std::ptrdiff_t>(n[0] * n[1])};
    const std::array<bool, 6> can{i > 0, i + 1 < n[0], j > 0, j + 1 < n[1], k > 0, k + 1 < n[2]};
    for (std::size_t d = 0; d < 6; ++d) {
      if (!can[d]) continue;
      const auto w = static_cast<std::size_t>(static_cast<std::ptrdiff_t>(v) + step[d]);
      if (ring[w] > ring[v] + 1) {
        ring[w] = ring[v] + 1;
        queue.push_back(w);
      }
    }
  }
  for (int a = 4; a + 2 < argc; a += 3)
    for (const bool highest : {false, true}) {
      const Eigen::Vector3d x(std::atof(argv[a]) * 1e-3, std::atof(argv[a + 1]) * 1e-3, std::atof(argv[a + 2]) * 1e-3);
      voxels::Grid one = grid;
      one.size = {1, 1, 1};
      one.ijk_to_lps.block<3, 1>(0, 3) = x;
      std::vector<double> scales;
      std::vector<voxels::LungMotion> moving;
      for (std::size_t l = 0; l < c.model.lungs.size(); ++l) {
        scales.push_back(highest ? c.scales[l].max_scale : c.scales[l].min_scale);
        moving.push_back(
            {c.model.lungs[l].interior->mesh, c.model.lungs[l].interior->unit_displacement, scales.back()});
      }
      const model::BodyMotion::Frame frame = c.model.body->frame(scales);
      const voxels::DisplacementField tets = voxels::pullback_dvf(one, moving);
      const Eigen::Vector3d body = frame.inverse(x, -frame.displacement(x));
      fmt::print(
          "{} point ({:.1f}, {:.1f}, {:.1f}) mm: lung {}, pull-back ({:.2f}, {:.2f}, {:.2f}) mm; body's inverse ({:.2f}, "
          "{:.2f}, {:.2f}) mm; body u at the rest point ({:.2f}, {:.2f}, {:.2f})\n",
          highest ? "highest" : "lowest", x.x() * 1e3, x.y() * 1e3, x.z() * 1e3, tets.lung[0],
          tets.displacement_m[0].x() * 1e3, tets.displacement_m[0].y() * 1e3, tets.displacement_m[0].z() * 1e3,
          body.x() * 1e3, body.y() * 1e3, body.z() * 1e3, frame.displacement(x + body).x() * 1e3,
          frame.displacement(x + body).y() * 1e3, frame.displacement(x + body).z() * 1e3);
    }
  constexpr int kBins = 6;  // rings 1, 2, 3, 4-6, 7-12, beyond
  const auto bin_of = [](int r) { return r <= 3 ? r - 1 : r <= 6 ? 3 : r <= 12 ? 4 : 5; };
  const std::array<const char*, kBins> names{"1", "2", "3", "4-6", "7-12", ">12"};
  const double h = 2e-4;
  for (const bool highest : {false, true}) {
    std::vector<double> scales;
    for (const auto& sc : c.scales) scales.push_back(highest ? sc.max_scale : sc.min_scale);
    const model::BodyMotion::Frame frame = c.model.body->frame(scales);
    struct Bin {
      double steepest = 0.0, least_j = 1e9, most_pull = 0.0;
      std::size_t steep = 0, torn = 0, count = 0;
      Eigen::Vector3d where = Eigen::Vector3d::Zero();
    };
    std::array<Bin, kBins> bins{};
    for (std::size_t v = 0; v < ring.size(); ++v) {
      if (ring[v] == 0) continue;
      const std::size_t i = v % n[0], j = (v / n[0]) % n[1], k = v / (n[0] * n[1]);
      const Eigen::Vector3d x = grid.centre_m(i, j, k);
      if (frame.displacement(x).norm() < 1e-4) continue;  // where the body hardly moves
      Eigen::Matrix3d g;
      for (int a = 0; a < 3; ++a) {
        const Eigen::Vector3d e = h * Eigen::Vector3d::Unit(a);
        g.col(a) = (frame.displacement(x + e) - frame.displacement(x - e)) / (2.0 * h);
      }
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen;
      eigen.computeDirect(g.transpose() * g, Eigen::EigenvaluesOnly);
      const double norm = std::sqrt(std::max(0.0, eigen.eigenvalues()[2]));
      const double j_forward = (Eigen::Matrix3d::Identity() + g).determinant();
      Bin& b = bins[static_cast<std::size_t>(bin_of(ring[v]))];
      ++b.count;
      if (norm > b.steepest) {
        b.steepest = norm;
        b.where = x;
      }
      b.least_j = std::min(b.least_j, j_forward);
      b.most_pull = std::max(b.most_pull, 1.0 / j_forward);
      b.steep += norm >= 1.0 ? 1 : 0;
      b.torn += (j_forward < 0.5 || j_forward > 2.0) ? 1 : 0;
    }
    fmt::print("{} scales ({} mm voxels), |grad u| by rings of voxels from the rest lungs:\n",
               highest ? "highest" : "lowest", spacing_m * 1e3);
    for (int b = 0; b < kBins; ++b) {
      const Bin& x = bins[static_cast<std::size_t>(b)];
      fmt::print("  ring {:>5}: {:>8} voxels, steepest {:.2f} at ({:.1f}, {:.1f}, {:.1f}) mm, {} at >= 1, forward J >= "
                 "{:.2f}, {} outside [0.5, 2]\n",
                 names[static_cast<std::size_t>(b)], x.count, x.steepest, x.where.x() * 1e3, x.where.y() * 1e3,
                 x.where.z() * 1e3, x.steep, x.least_j, x.torn);
    }
  }
  return 0;
}
