// Points that follow the breath (tracking.h).
#include "pneuma/outputs/tracking.h"

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include "pneuma/core/error.h"
#include "pneuma/core/units.h"
#include "pneuma/model/body_motion.h"
#include "pneuma/scenario/scenario.h"
#include "pneuma/voxels/grid.h"
#include "pneuma/voxels/voxel_io.h"
#include "pneuma/voxels/warp.h"

namespace pneuma::outputs {
namespace {

// The closest point of triangle (a, b, c) to p, as barycentric weights (Ericson, Real-Time
// Collision Detection, 5.1.5).
Eigen::Vector3d closest_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return {1 - v, v, 0};
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return {1 - w, 0, w};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - w, w};
  }
  const double denom = 1 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  return {1 - v - w, v, w};
}

// Barycentric coordinates of p in tet (a, b, c, d).
Eigen::Vector4d tet_weights(const Eigen::Vector3d& p, const std::array<Eigen::Vector3d, 4>& x) {
  Eigen::Matrix3d m;
  m << x[1] - x[0], x[2] - x[0], x[3] - x[0];
  const Eigen::Vector3d l = m.partialPivLu().solve(p - x[0]);
  return {1 - l.sum(), l[0], l[1], l[2]};
}

}  // namespace

std::vector<Fiducial> read_fiducials(const std::filesystem::path& csv) {
  std::ifstream in(csv);
  if (!in) throw IoError(csv.string() + ": cannot read");
  std::string line;
  std::vector<Fiducial> points;
  std::set<std::string> names;
  int number = 0;
  const auto fail = [&](const std::string& what) {
    throw InputError(fmt::format("{}:{}: {}", csv.string(), number, what));
  };
  while (std::getline(in, line)) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (number == 1) {
      if (line != "name,x_mm,y_mm,z_mm") fail("expected the header 'name,x_mm,y_mm,z_mm' (LPS millimetres)");
      continue;
    }
    if (line.empty()) continue;
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
    if (cells.size() != 4) fail(fmt::format("{} columns; expected 4: name,x_mm,y_mm,z_mm", cells.size()));
    if (cells[0].empty()) fail("an empty name; expected a point's name");
    if (!names.insert(cells[0]).second) fail(fmt::format("'{}' named twice; expected unique names", cells[0]));
    Fiducial f{cells[0], {}};
    for (int a = 0; a < 3; ++a) {
      const std::string& text = cells[static_cast<std::size_t>(a) + 1];
      std::size_t used = 0;
      double v = std::numeric_limits<double>::quiet_NaN();
      try {
        v = std::stod(text, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != text.size() || text.empty() || !std::isfinite(v) || std::abs(v) > 1e4)
        fail(fmt::format("'{}' in column {}; expected a coordinate in mm (within 10 m)", text, a + 2));
      f.rest_m[a] = v * 1e-3;
    }
    points.push_back(std::move(f));
  }
  if (points.empty()) fail("no points; expected one line per point after the header");
  return points;
}

std::string moves_with(const model::Model& model, const PointMotion& motion) {
  if (motion.with == PointMotion::With::body) return "body";
  return fmt::format("{} {}", scenario::lung_name(model.lungs[motion.lung].side),
                     motion.with == PointMotion::With::surface ? "surface" : "interior");
}

PointMotion locate(const model::Model& model, const Eigen::Vector3d& x) {
  PointMotion motion;
  // On a rest surface: the closest point of every triangle (a few points, tens of thousands of
  // triangles: brute force).
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    const mesh::TriangleMesh& rest = model.lungs[i].rest;
    for (const auto& t : rest.triangles) {
      const Eigen::Vector3d w = closest_on_triangle(x, rest.vertices[t[0]], rest.vertices[t[1]], rest.vertices[t[2]]);
      const Eigen::Vector3d q = w[0] * rest.vertices[t[0]] + w[1] * rest.vertices[t[1]] + w[2] * rest.vertices[t[2]];
      if ((q - x).norm() <= kOnSurfaceM) {
        motion.with = PointMotion::With::surface;
        motion.lung = i;
        motion.corners = {t[0], t[1], t[2], 0};
        motion.weights = {w[0], w[1], w[2], 0};
        return motion;
      }
    }
  }
  // Inside a rest tet: the first lung, the lowest tet (the forward DVF's rule).
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    if (!model.lungs[i].interior) continue;
    const mesh::TetMesh& mesh = model.lungs[i].interior->mesh;
    for (const auto& q : mesh.tets) {
      const std::array<Eigen::Vector3d, 4> corners{mesh.nodes[q[0]], mesh.nodes[q[1]], mesh.nodes[q[2]],
                                                   mesh.nodes[q[3]]};
      const Eigen::Vector3d lo = corners[0].cwiseMin(corners[1]).cwiseMin(corners[2]).cwiseMin(corners[3]);
      const Eigen::Vector3d hi = corners[0].cwiseMax(corners[1]).cwiseMax(corners[2]).cwiseMax(corners[3]);
      if ((x.array() < lo.array() - 1e-12).any() || (x.array() > hi.array() + 1e-12).any()) continue;
      const Eigen::Vector4d w = tet_weights(x, corners);
      if (w.minCoeff() >= -1e-10) {
        motion.with = PointMotion::With::interior;
        motion.lung = i;
        motion.corners = q;
        motion.weights = {w[0], w[1], w[2], w[3]};
        return motion;
      }
    }
  }
  return motion;
}

Eigen::Vector3d moved_point(const model::Model& model, const Eigen::Vector3d& rest_m, const PointMotion& motion,
                            std::span<const double> scales) {
  switch (motion.with) {
    case PointMotion::With::surface: {
      const model::LungModel& lung = model.lungs[motion.lung];
      Eigen::Vector3d x = Eigen::Vector3d::Zero();
      // The frames' own vertices (rest + s u), interpolated.
      for (std::size_t c = 0; c < 3; ++c)
        x += motion.weights[c] *
             (lung.rest.vertices[motion.corners[c]] + scales[motion.lung] * lung.unit_displacement[motion.corners[c]]);
      return x + (rest_m - (motion.weights[0] * lung.rest.vertices[motion.corners[0]] +
                            motion.weights[1] * lung.rest.vertices[motion.corners[1]] +
                            motion.weights[2] * lung.rest.vertices[motion.corners[2]]));
    }
    case PointMotion::With::interior: {
      const model::LungInterior& inside = *model.lungs[motion.lung].interior;
      Eigen::Vector3d u = Eigen::Vector3d::Zero();
      for (std::size_t c = 0; c < 4; ++c) u += motion.weights[c] * inside.unit_displacement[motion.corners[c]];
      return rest_m + scales[motion.lung] * u;
    }
    case PointMotion::With::body: break;
  }
  return model.body ? Eigen::Vector3d(rest_m + model.body->displacement(rest_m, scales)) : rest_m;
}

StructureTracker::StructureTracker(std::filesystem::path folder, std::string extension, StructureSpec spec)
    : folder_(std::move(folder)), extension_(std::move(extension)), spec_(std::move(spec)) {}

void StructureTracker::add(const std::string& tag, const voxels::TimePoint& point, double weight) {
  // The mask on its grid: the warped label map's, or the mask file pulled back.
  if (spec_.mask) {
    voxels::warp_labels(*spec_.mask, point.pullback, scratch_);
    for (std::int32_t& v : scratch_.labels) v = v != 0;
  } else {
    if (!point.labels) throw Error(ExitCode::failure, "structures: a time point without its warped label map");
    scratch_.size = point.labels->size;
    scratch_.ijk_to_lps = point.labels->ijk_to_lps;
    scratch_.labels.resize(point.labels->labels.size());
    for (std::size_t v = 0; v < scratch_.labels.size(); ++v)
      scratch_.labels[v] = point.labels->labels[v] == spec_.label;
  }
  scratch_.segments = {{spec_.name, 1}};
  scratch_.transform_source = "pneuma";
  const voxels::Grid grid = voxels::grid_of(scratch_);
  Row row{tag, 0.0, Eigen::Vector3d::Zero(), weight};
  std::size_t count = 0;
  for (std::size_t k = 0; k < grid.size[2]; ++k)
    for (std::size_t j = 0; j < grid.size[1]; ++j)
      for (std::size_t i = 0; i < grid.size[0]; ++i)
        if (scratch_.labels[grid.index(i, j, k)] != 0) {
          row.centroid_m += grid.centre_m(i, j, k);
          ++count;
        }
  row.volume_m3 = static_cast<double>(count) * scratch_.voxel_volume_m3();
  row.centroid_m = count > 0 ? Eigen::Vector3d(row.centroid_m / static_cast<double>(count))
                             : Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  if (!folder_.empty()) {
    const std::filesystem::path file = folder_ / ("structure-" + spec_.name + "-" + tag + extension_);
    voxels::write_label_map(file, scratch_);
    files_.push_back(file);
  }
  if (weight > 0.0) {
    if (!itv_) {
      itv_ = scratch_;
    } else {
      for (std::size_t v = 0; v < scratch_.labels.size(); ++v) itv_->labels[v] |= scratch_.labels[v];
    }
  }
  rows_.push_back(row);
}

std::vector<std::filesystem::path> StructureTracker::finish() {
  if (itv_) {
    std::size_t count = 0;
    for (const std::int32_t v : itv_->labels) count += v != 0;
    itv_volume_m3_ = static_cast<double>(count) * itv_->voxel_volume_m3();
    if (!folder_.empty()) {
      const std::filesystem::path file = folder_ / ("itv-" + spec_.name + extension_);
      voxels::write_label_map(file, *itv_);
      files_.push_back(file);
    }
    itv_shared_ = std::make_shared<const image::LabelMap>(std::move(*itv_));
    itv_.reset();
  }
  return files_;
}

Eigen::Vector3d StructureTracker::mean_position_m() const {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double weights = 0.0;
  for (const Row& row : rows_) {
    if (row.weight > 0.0 && row.volume_m3 > 0.0) {
      sum += row.weight * row.centroid_m;
      weights += row.weight;
    }
  }
  return weights > 0.0 ? Eigen::Vector3d(sum / weights)
                       : Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
}

std::optional<std::size_t> StructureTracker::midventilation() const {
  const Eigen::Vector3d mean = mean_position_m();
  std::optional<std::size_t> best;
  double best_distance = std::numeric_limits<double>::infinity();
  for (std::size_t r = 0; r < rows_.size(); ++r) {
    if (!(rows_[r].weight > 0.0) || !(rows_[r].volume_m3 > 0.0)) continue;
    const double d = (rows_[r].centroid_m - mean).norm();
    if (d < best_distance) {
      best_distance = d;
      best = r;
    }
  }
  return best;
}

}  // namespace pneuma::outputs
