#pragma once
// How a surface moves under x + s u, region by region, in body axes (docs/realism.md): the
// measurement behind the realism table, for the runner and the tests.
//
// Per region (by label): its rest area, the area-weighted mean and the max of the displacement
// s u along the body axes (caudal = -up, i.e. downward is positive; anterior; lateral = away
// from the midline, i.e. -medial) and of its length, and its share of the volume change.
// The volume change is split over triangles by the volume each triangle sweeps moving
// linearly from x to x + s u (exact; origin-free; the sum over triangles is V(s) - V(0)), a
// third to each corner, then summed per label.
#include <Eigen/Core>
#include <array>
#include <span>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/mesh/anatomy/regions.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh {

struct RegionMotion {
  double area_m2 = 0.0;
  double caudal_mean_m = 0.0, caudal_max_m = 0.0;  // along -up (downward > 0)
  double anterior_mean_m = 0.0, anterior_max_m = 0.0;
  double lateral_mean_m = 0.0, lateral_max_m = 0.0;  // along -medial
  double magnitude_mean_m = 0.0, magnitude_max_m = 0.0;
  double volume_change_m3 = 0.0;
  double volume_share = 0.0;  // of the whole surface's volume change
};

struct MotionSummary {
  std::array<RegionMotion, kRegionCount> region;  // indexed by Region
  double volume_change_m3 = 0.0;                  // V(s) - V(0)
  // The dome top: mean caudal displacement of the dome's vertices (diaphragmatic, smoothed
  // normal within 30 degrees of straight down) within `dome_top_depth_m` of the highest of them.
  double dome_top_caudal_m = 0.0;
  // Mean caudal displacement of all vertices in five equal height bands, apex (0) to base (4).
  std::array<double, 5> band_caudal_mean_m{};
};

// `displacement` per vertex (u), `scale` s. Throws ValueError when the sizes differ.
MotionSummary summarize_motion(const TriangleMesh& rest, std::span<const Eigen::Vector3d> displacement, double scale,
                               const SurfaceRegions& regions, double dome_top_depth_m = 0.01);

// The volume each triangle sweeps from x to x + d (signed, outward > 0); sums to V(x + d) - V(x).
std::vector<double> swept_volumes(const TriangleMesh& rest, std::span<const Eigen::Vector3d> displacement);

}  // namespace pneuma::mesh
