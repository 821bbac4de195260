#pragma once
// Everything the voxel outputs give for one time point, and its files, for an output plugin:
// given the lungs at that time and a grid, the forward and pull-back DVFs, the Jacobian figures
// and image, and (when given) the label map and the CT pulled back onto the grid, the CT's lung
// parenchyma keeping its mass (density.h).
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "pneuma/image/label_map.h"
#include "pneuma/voxels/density.h"
#include "pneuma/voxels/dvf.h"
#include "pneuma/voxels/jacobian.h"
#include "pneuma/voxels/sequence_io.h"
#include "pneuma/voxels/voxel_io.h"
#include "pneuma/voxels/warp.h"
#include "pneuma/voxels/write_queue.h"

namespace pneuma::voxels {

struct TimePointInputs {
  const image::LabelMap* labels = nullptr;  // warped when given
  // Per voxel of `labels`: 1 + the lung whose rest mesh holds it, else 0 (warp_labels); may be null.
  const std::vector<std::uint8_t>* rest_lung = nullptr;
  // The label values that are lung in `labels`: with them, the CT's lung voxels (those the label
  // map calls lung) are interpolated from lung voxels only (warp_image's Tissue); empty: by side.
  std::span<const int> lung_labels;
  const Image* ct = nullptr;      // warped when given
  bool mass_preserving = true;    // the CT's lung parenchyma keeps its mass (density.h); false: its HU
  bool jacobian_map = true;       // the Jacobian image of the forward map (TimePoint::jacobian_map)
  OutsideField forward_outside;   // the forward field outside the lungs (empty: 0)
  OutsideField pullback_outside;  // the pull-back field outside the deformed lungs (empty: 0)
  // Whether to keep the rest tets' rasterisation for a later time point (TimePoint::rest_raster);
  // false for a run's last time point (a run of one keeps none: 0.33 GB at case004's own grid).
  bool keep_rest_raster = true;
};

struct TimePoint {
  DisplacementField forward, pullback;
  JacobianStats jacobian;
  std::optional<image::LabelMap> labels;
  std::optional<Image> ct;
  std::optional<Image> jacobian_map;  // det(I + grad u) of the forward map, on the grid (density.h)
  Image rest_ct;                      // scratch: the mass-preserving rest CT (reused between time points)
  std::vector<std::uint8_t> ct_lung;  // scratch: the rest lungs on a CT grid other than the time point's
  // scratch: the label map's lung tissue on the CT grid and in the warped label map
  std::vector<std::uint8_t> ct_tissue, warped_tissue;
  RestRaster rest_raster;  // scratch: the rest tets on the grid, replayed by the next time point (keep_rest_raster)
};

TimePoint compute_time_point(const Grid& grid, std::span<const LungMotion> lungs, const TimePointInputs& inputs = {});
// The same into `point`, its buffers reused (a run's later time points: no fresh pages, which
// cost more than the computation itself; BENCHMARKS.md, "Voxel outputs").
void compute_time_point(const Grid& grid, std::span<const LungMotion> lungs, const TimePointInputs& inputs,
                        TimePoint& point);

struct TimePointFiles {
  std::filesystem::path forward, pullback, labels, ct, jacobian;  // empty when not written
};

// compute_time_point and write_time_point in one: each file is queued on `writes` as soon as its
// buffer is final, so that it is compressed and written while the next one is computed (the
// forward DVF while the pull-back is, the pull-back while the labels, CT and Jacobian image are).
// The same files and bytes as the two calls. `point` must not change until writes.wait() has
// returned (the files exist then); the paths are returned at once.
TimePointFiles compute_and_write_time_point(const Grid& grid, std::span<const LungMotion> lungs,
                                            const TimePointInputs& inputs, TimePoint& point,
                                            const std::filesystem::path& folder, const std::string& tag,
                                            WriteQueue& writes, const std::string& extension = ".nii.gz",
                                            DvfConvention convention = DvfConvention::itk);

// dvf-forward-<tag>.nii.gz, dvf-pullback-<tag>.nii.gz, labels-<tag>.nii.gz, ct-<tag>.nii.gz and
// jacobian-<tag>.nii.gz in `folder` (the last three when the time point has them); `extension`
// ".nii.gz", ".nii", ".mha" or ".nrrd"; `convention` the NIfTI DVFs' (voxel_io.h).
TimePointFiles write_time_point(const std::filesystem::path& folder, const std::string& tag, const TimePoint& point,
                                const std::string& extension = ".nii.gz",
                                DvfConvention convention = DvfConvention::itk);

// A run's time points as sequences (sequence_io.h), appended one time point at a time: per format,
// labels, ct, jacobian (those the time points have), dvf-pullback and dvf-forward, named
// `<kind>.seq.nrrd` (3D Slicer) and `<kind>-4d.nii.gz` (4D NIfTI) in `folder`. Each writer is made
// at the first time point, on that time point's grid.
class TimePointSequences {
 public:
  // `index_values` one per time point to come; `labels` the voxel type of the warped label maps;
  // `convention` the 4D NIfTI DVFs' (the .seq.nrrd DVFs are LPS with the identity measurement frame).
  TimePointSequences(std::filesystem::path folder, std::vector<SequenceFormat> formats, std::string index_name,
                     std::string index_unit, std::vector<double> index_values, SequenceVoxel labels,
                     DvfConvention convention = DvfConvention::itk);
  void append(const TimePoint& point);
  // The files, after the last time point.
  std::vector<std::filesystem::path> finish();

 private:
  void append_item(const std::string& kind, const Grid& grid, SequenceVoxel voxel, const void* values,
                   std::size_t bytes, const std::string& field_type = {});
  std::filesystem::path folder_;
  std::vector<SequenceFormat> formats_;
  SequenceSpec base_;
  SequenceVoxel labels_;
  std::vector<std::pair<std::string, std::unique_ptr<SequenceWriter>>> writers_;  // kind + format, in order made
  std::vector<float> scratch_;
  std::vector<char> label_scratch_;
};

}  // namespace pneuma::voxels
