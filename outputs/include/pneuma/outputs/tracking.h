#pragma once
// Points and structures that follow the breath (voxels.points, voxels.structures; formats.md,
// "Points and structures").
//
// A point moves as the tissue it sits in: a point on a lung's rest surface (within
// kOnSurfaceM) with the surface frames (the closest point's barycentric motion on its triangle:
// rest + s u, the frames' own field); a point inside a lung's rest tetrahedra with that lung's
// interior field (barycentric in the rest tet: rest + s U, the forward DVF's own rule); any other
// point with the body's motion (model/body_motion.h; 0 where there is none).
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "pneuma/image/label_map.h"
#include "pneuma/model/model.h"
#include "pneuma/voxels/time_point.h"

namespace pneuma::outputs {

inline constexpr double kOnSurfaceM = 1e-5;  // 0.01 mm: a fiducial typed at a vertex

struct Fiducial {
  std::string name;
  Eigen::Vector3d rest_m;  // LPS metres
};

// A CSV with the header `name,x_mm,y_mm,z_mm` (LPS millimetres, as DICOM and ITK; 3D Slicer's
// markups are RAS: negate x and y), one point per line, names unique and not empty. Throws
// IoError when it cannot be read and InputError "<file>:<line>: <what was expected>".
std::vector<Fiducial> read_fiducials(const std::filesystem::path& csv);

// Where a point sits and how it moves.
struct PointMotion {
  enum class With { surface, interior, body } with = With::body;
  std::size_t lung = 0;                    // surface, interior: the model's lung
  std::array<std::uint32_t, 4> corners{};  // the triangle's vertices (3) or the tet's nodes (4)
  std::array<double, 4> weights{};         // barycentric
};
// "right surface", "left interior", "body" (a lung of a one-surface run: "lung").
std::string moves_with(const model::Model& model, const PointMotion& motion);

PointMotion locate(const model::Model& model, const Eigen::Vector3d& x_m);
// The point's position (LPS metres) at the lungs' scales (one per model lung).
Eigen::Vector3d moved_point(const model::Model& model, const Eigen::Vector3d& rest_m, const PointMotion& motion,
                            std::span<const double> scales);

// A structure: a label of the scenario's label map, or a mask file (any nonzero voxel).
struct StructureSpec {
  std::string name;
  std::int32_t label = 0;                       // when no mask
  std::shared_ptr<const image::LabelMap> mask;  // a file's
  std::filesystem::path mask_file;
};

// One structure over a run's time points: each time point's warped mask (the warped label map's
// voxels of the label, or the mask file pulled back, nearest voxel) written as
// `structure-<name>-<tag><extension>` (uint8 0/1), its volume and centroid; the ITV, the union of
// the masks of the time points added with a weight > 0 (the phase bins), voxel for voxel; the
// mid-ventilation time point, the weighted one whose centroid is closest to the weighted mean of
// the centroids (weights: each bin's share of the breathing time). An empty `folder` writes no
// file (the Python module: the masks as arrays, mask() after each add()).
class StructureTracker {
 public:
  StructureTracker(std::filesystem::path folder, std::string extension, StructureSpec spec);
  void add(const std::string& tag, const voxels::TimePoint& point, double weight);
  struct Row {
    std::string tag;
    double volume_m3 = 0.0;
    Eigen::Vector3d centroid_m = Eigen::Vector3d::Zero();  // NaN when the mask is empty
    double weight = 0.0;
  };
  const std::vector<Row>& rows() const { return rows_; }
  const StructureSpec& spec() const { return spec_; }
  // The last time point's mask (0/1 on its grid).
  const image::LabelMap& mask() const { return scratch_; }
  // Writes itv-<name><extension> when a time point had a weight; the files written.
  std::vector<std::filesystem::path> finish();
  double itv_volume_m3() const { return itv_volume_m3_; }
  // The ITV after finish() (null without a weighted time point), shared rather than copied.
  std::shared_ptr<const image::LabelMap> itv() const { return itv_shared_; }
  // The mid-ventilation row (index into rows()) and the weighted mean position; none without weights.
  std::optional<std::size_t> midventilation() const;
  Eigen::Vector3d mean_position_m() const;

 private:
  std::filesystem::path folder_;
  std::string extension_;
  StructureSpec spec_;
  std::vector<Row> rows_;
  std::vector<std::filesystem::path> files_;
  std::optional<image::LabelMap> itv_;
  std::shared_ptr<const image::LabelMap> itv_shared_;
  image::LabelMap scratch_;
  double itv_volume_m3_ = 0.0;
};

}  // namespace pneuma::outputs
