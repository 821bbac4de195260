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
    // Pulled back with the rest lungs on the CT's grid, so that nothing is blended across the
    // sliding pleura; the mass-preserving rule finds them on its way.
    if (inputs.mass_preserving) {
      mass_preserving_ct(*inputs.ct, lungs, point.rest_ct, point.ct_lung);
      warp_image(point.rest_ct, point.pullback, *point.ct, kOutsideHu, &point.ct_lung);
    } else {
      point.ct_lung = rest_lungs(inputs.ct->grid, lungs);
      warp_image(*inputs.ct, point.pullback, *point.ct, kOutsideHu, &point.ct_lung);
    }
  } else {
    point.ct.reset();
  }
  if (inputs.jacobian_map) {
    if (!point.jacobian_map) point.jacobian_map.emplace();
    jacobian_image(lungs, point.forward, *point.jacobian_map);
  } else {
    point.jacobian_map.reset();
  }
}

TimePointFiles write_time_point(const std::filesystem::path& folder, const std::string& tag, const TimePoint& point,
                                const std::string& extension, DvfConvention convention) {
  if (extension != ".nii.gz" && extension != ".nii" && extension != ".mha" && extension != ".nrrd") {
    throw ValueError("voxel file extension '" + extension + "': expected .nii.gz, .nii, .mha or .nrrd");
  }
  TimePointFiles files;
  files.forward = folder / ("dvf-forward-" + tag + extension);
  files.pullback = folder / ("dvf-pullback-" + tag + extension);
  write_dvf(files.forward, point.forward, DvfDirection::forward, convention);
  write_dvf(files.pullback, point.pullback, DvfDirection::pullback, convention);
  if (point.labels) {
    files.labels = folder / ("labels-" + tag + extension);
    write_label_map(files.labels, *point.labels);
  }
  if (point.ct) {
    files.ct = folder / ("ct-" + tag + extension);
    write_image(files.ct, *point.ct);
  }
  if (point.jacobian_map) {
    files.jacobian = folder / ("jacobian-" + tag + extension);
    write_image(files.jacobian, *point.jacobian_map);
  }
  return files;
}

}  // namespace pneuma::voxels
