#include "pneuma/voxels/time_point.h"

#include "pneuma/core/error.h"
#include "pneuma/voxels/voxel_io.h"

namespace pneuma::voxels {

TimePoint compute_time_point(const Grid& grid, std::span<const LungMotion> lungs, const TimePointInputs& inputs) {
  TimePoint point;
  compute_time_point(grid, lungs, inputs, point);
  return point;
}

void compute_time_point(const Grid& grid, std::span<const LungMotion> lungs, const TimePointInputs& inputs,
                        TimePoint& point) {
  forward_dvf(grid, lungs, point.forward, inputs.forward_outside);
  pullback_dvf(grid, lungs, point.pullback, inputs.pullback_outside);
  point.jacobian = jacobian_stats(lungs);
  if (inputs.labels != nullptr) {
    if (!point.labels) point.labels.emplace();
    warp_labels(*inputs.labels, point.pullback, *point.labels, inputs.rest_lung);
  } else {
    point.labels.reset();
  }
  if (inputs.ct != nullptr) {
    if (!point.ct) point.ct.emplace();
    warp_image(*inputs.ct, point.pullback, *point.ct);
  } else {
    point.ct.reset();
  }
}

TimePointFiles write_time_point(const std::filesystem::path& folder, const std::string& tag, const TimePoint& point,
                                const std::string& extension) {
  if (extension != ".nii.gz" && extension != ".nii" && extension != ".mha") {
    throw ValueError("voxel file extension '" + extension + "': expected .nii.gz, .nii or .mha");
  }
  TimePointFiles files;
  files.forward = folder / ("dvf-forward-" + tag + extension);
  files.pullback = folder / ("dvf-pullback-" + tag + extension);
  write_dvf(files.forward, point.forward);
  write_dvf(files.pullback, point.pullback);
  if (point.labels) {
    files.labels = folder / ("labels-" + tag + extension);
    write_label_map(files.labels, *point.labels);
  }
  if (point.ct) {
    files.ct = folder / ("ct-" + tag + extension);
    write_image(files.ct, *point.ct);
  }
  return files;
}

}  // namespace pneuma::voxels
