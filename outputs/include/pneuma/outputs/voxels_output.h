#pragma once
// Voxel outputs (#31; docs/voxels.md, formats.md "Voxel outputs"): at chosen time points, the
// forward and pull-back DVFs of the whole chest (the lungs' interior field inside them, the body
// motion below them, 0 elsewhere), the label map and the CT pulled back, and per time point the
// Jacobian of the forward map inside the lungs and the warped lungs' volume (voxels/voxels.csv).
//
//   outputs:
//     voxels:                          # off by default
//       at: [end_expiration, end_inspiration, 2.4 s, phases]   # the frames of the lowest and
//                                      # highest volume, the frame nearest to a time (the default:
//                                      # the first two), and each bin of outputs.phases (10 phase
//                                      # bins when that is off) at its mean volume
//       spacing: 2 mm                  # a grid of this spacing over the label map's extent (default:
//                                      # the label map's own grid; lungs without one: 2 mm over their box)
//       image: ct.nii.gz               # a CT on the label map's geometry (or its own) to pull back
//       format: nii.gz                 # nii.gz | nii | mha | nrrd (NRRD DVFs as 3D Slicer reads them)
//       sequences: [seq.nrrd, nii.gz]  # the time points (the phase bins when `phases` is in `at`) as one
//                                      # 3D Slicer sequence and one 4D NIfTI per kind (default: none)
//       points: fiducials.csv          # name,x_mm,y_mm,z_mm (LPS) -> voxels/trajectories.csv
//       structures: {gtv: 7, target: target.nii.gz}   # a label or a mask -> structure-<name>-<t>,
//                                      # itv-<name>, structures.csv, structures-summary.csv
//       dvf_convention: itk            # NIfTI DVFs: itk (LPS components, intent 1007: ITK <= 5.2,
//                                      # plastimatch, elastix) | nifti (RAS, intent 1006: ITK >= 5.3, nibabel)
//
// Files (voxels/): dvf-forward-<t>, dvf-pullback-<t>, labels-<t> and ct-<t> with <t> the frame's
// time ("2.400s") or the bin ("bin_03"), and voxels.csv (a bin's frame and time are empty). Label-map lungs warp the
// label map; other lungs (the phantom, surface files) warp a label map of their rest tetrahedra (1 right or the only
// lung, 2 left).
#include <array>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <variant>
#include <vector>

#include "pneuma/image/dicom.h"
#include "pneuma/outputs/output.h"
#include "pneuma/outputs/report.h"
#include "pneuma/outputs/tracking.h"

#include "pneuma/voxels/rest_lungs_cache.h"
#include "pneuma/voxels/time_point.h"

namespace pneuma::outputs {

// A time point: the frame of the run's lowest or highest volume, or the frame nearest to a time.
enum class VoxelMoment { end_expiration, end_inspiration };
using VoxelTime = std::variant<VoxelMoment, double>;

struct VoxelsSpec {
  std::vector<VoxelTime> at{VoxelMoment::end_expiration, VoxelMoment::end_inspiration};
  bool phase_bins = false;  // `phases` in `at`: every respiratory bin of outputs.phases at its mean volume
  double spacing_m = 0.0;   // 0: the label map's grid (2 mm where there is none)
  std::shared_ptr<const voxels::Image> image;
  std::filesystem::path image_file;
  std::string image_where;      // "file:l:c: outputs.voxels.image", for the check against the lungs
  bool mass_preserving = true;  // `density: mass_preserving` (default) | `unchanged`: the CT's lung parenchyma
  bool jacobian = true;         // `jacobian: true|false`: jacobian-<t> files (the forward map's Jacobian)
  std::string extension = ".nii.gz";
  voxels::DvfConvention dvf_convention = voxels::DvfConvention::itk;
  std::vector<voxels::SequenceFormat> sequences;  // `sequences`: none by default
  std::vector<Fiducial> points;                   // `points: fiducials.csv` -> trajectories.csv
  std::vector<StructureSpec> structures;          // `structures: {gtv: 7, target: mask.nii.gz}`
  // `dicom: true`: each time point's CT as a DICOM CT series and its structures as an RTSTRUCT
  // (dicom/; docs/formats.md, "DICOM"); needs `image`. The CT's patient, study and frame of
  // reference when it was a DICOM series (`image_series`: which one of a folder's).
  bool dicom = false;
  std::optional<image::DicomSource> image_dicom;
};

// The part of a lung's inside that reaches a grid (VoxelScene::parts_reaching): its tetrahedra in
// their order, their nodes renumbered in order of first use, each node's unit displacement.
struct InsidePart {
  mesh::TetMesh mesh;
  std::vector<Eigen::Vector3d> unit_displacement;
};

// A run's voxel setting, made once from the compiled model (with the lungs' inside): the grid,
// the label map to warp (the scenario's, or one of the rest tetrahedra), each lung's rest voxels
// on it and the body's motion outside the lungs. `pneuma run` (the plugin) and the Python module
// compute their time points through it, so they give the same arrays.
class VoxelScene {
 public:
  // Throws Error(failure) when the model has no lungs' inside (compiled without it), InputError
  // when the spec's CT does not cover the lungs at rest. With `cache`, the rest lungs' mask on
  // the label map's grid is read from cache.lookup where a run kept it for this grid and these
  // rest meshes, else rasterised, and kept at cache.save_to (rest_lungs_cache.h).
  VoxelScene(const model::Model& model, const scenario::Scenario& scenario, const VoxelsSpec& spec,
             const voxels::RestLungsCache& cache = {});

  const voxels::Grid& grid() const { return grid_; }
  const image::LabelMap& labels() const { return *labels_; }  // at rest, on its own grid
  // The label values that are lung (the scenario's lungs, or 1 and 2 for the rest tets' map).
  const std::vector<int>& lung_labels() const { return lung_labels_; }
  // Per voxel of labels(): 0, or 1 + the lung whose rest tets hold its centre (voxels::rest_lungs).
  const std::vector<std::uint8_t>& rest_lungs() const { return rest_lung_; }
  // Whether rest_lungs() was read from the cache, and why a file found there was not used.
  bool rest_lungs_reused() const { return rest_lungs_reused_; }
  const std::string& rest_lungs_discarded() const { return rest_lungs_discarded_; }
  // The volume of the lung labels in `map` (m^3).
  double lung_volume_m3(const image::LabelMap& map) const;
  // The DVFs, the Jacobian, the warped label map (and CT) at the lungs' scales (one per model lung).
  void compute(std::span<const double> scales, voxels::TimePoint& point) const;
  // compute(), each of the time point's files (voxels::write_time_point's, in the spec's format)
  // queued on `writes` as soon as its buffer is final, so that it is written while the next is
  // computed; `point` must not change until writes.wait() has returned. `more_to_come`: whether
  // a later time point will reuse `point` (the rest tets' rasterisation is kept for it only then).
  voxels::TimePointFiles compute_and_write(std::span<const double> scales, voxels::TimePoint& point,
                                           const std::filesystem::path& folder, const std::string& tag,
                                           voxels::WriteQueue& writes, bool more_to_come = true) const;
  // The same on another grid (a plane for report.html's slices), the CT only if `with_image`.
  // The Jacobian image is made when the spec asks for it or `with_jacobian`.
  // With `parts` (one per lung, parts_reaching(grid, ...)), only their tetrahedra are rasterised.
  // With `image`, that CT (a crop of the spec's: ct_reached()) is pulled back instead of the spec's.
  void compute_on(const voxels::Grid& grid, std::span<const double> scales, voxels::TimePoint& point,
                  bool with_image = true, bool with_jacobian = false, const std::vector<InsidePart>* parts = nullptr,
                  const voxels::Image* image = nullptr) const;
  // Each lung's tetrahedra that can hold a voxel of `grid` at rest or at any scale between
  // `scale_ranges[lung]` (lowest, highest): their boxes over that range of `rest + s u` (linear
  // in s, so the ends bound it) meet the grid's box grown by a voxel. A voxel's tet is the lowest
  // that holds it and the parts keep the order, so on a one-voxel plane (report.html's slices)
  // the DVFs, the warped labels and the Jacobian image are those of the whole inside, from a few
  // per cent of its tetrahedra. Not for the CT: its rest lungs are rasterised on the CT's grid.
  std::vector<InsidePart> parts_reaching(const voxels::Grid& grid,
                                         std::span<const std::array<double, 2>> scale_ranges) const;

 private:
  // The lungs at `scales` (their `parts` when given) and the inputs compute_time_point takes on
  // `grid` (the CT `image` in place of the spec's when given), handed to `compute`.
  void with_inputs(
      const voxels::Grid& grid, std::span<const double> scales, bool with_image, bool with_jacobian,
      const std::vector<InsidePart>* parts, const voxels::Image* image,
      const std::function<void(std::span<const voxels::LungMotion>, const voxels::TimePointInputs&)>& compute) const;
  const model::Model& model_;
  const VoxelsSpec& spec_;
  std::shared_ptr<const image::LabelMap> labels_;  // the model's (read once by compile), or made here
  std::vector<int> lung_labels_;
  voxels::Grid grid_;
  std::vector<std::uint8_t> rest_lung_;
  bool rest_lungs_reused_ = false;
  std::string rest_lungs_discarded_;
};

// The rest lungs' mask's file in a run's output folder (rest_lungs_cache.h).
inline constexpr const char* kRestLungsCacheFile = "rest-lungs.cache";

// The key of the voxel outputs under `outputs:`.
inline constexpr const char* kVoxelsKey = "voxels";

// The scenario's `outputs.voxels` settings, or null when that output is off.
const VoxelsSpec* requested_voxels(const scenario::Scenario& scenario);

// The run's VoxelScene (RunRecord::shared), built on first use from the scenario's
// `outputs.voxels` settings. Throws Error(failure) when that output is off or the model has no
// lungs' inside.
const VoxelScene& run_voxel_scene(const model::Model& model, const RunRecord& run);

// The voxel time points' quality figures, shared by the voxel output (RunRecord::shared) for
// report.html, which finishes after it.
struct VoxelFigures {
  std::vector<VoxelPointFigures> points;
};
// The structures' figures and ITVs (in the order of voxels.structures), shared the same way.
struct VoxelStructures {
  std::vector<StructureFacts> facts;
  std::vector<std::shared_ptr<const image::LabelMap>> itvs;  // null without one
};
// The points' trajectories (trajectories.csv's frame rows), shared the same way.
struct VoxelTracks {
  std::vector<double> times_s;  // per frame
  std::vector<PointTrack> points;
};

// report.html's slices of the warped label map (voxel outputs on; empty otherwise): a coronal
// plane through the middle of the lungs and a sagittal one through the middle of the first, with
// pixels of 2 mm (coarser for a chest wider than 40 cm), at up to `max_times` frames spread
// evenly over the run; beside them, at up to `max_channel_times` of those frames, the warped CT
// (when given), |forward DVF| and the forward map's Jacobian; each voxels.structures structure's
// mask on the plane at every slice time and its ITV (shared by the voxel output, VoxelStructures)
// sampled at the pixels. `lung_labels` gets the label values that are lung.
std::vector<LabelSlice> report_label_slices(const model::Model& model, const RunRecord& run,
                                            std::vector<int>& lung_labels, std::size_t max_times = 32,
                                            std::size_t max_channel_times = 8);

OutputPlugin voxels_output();

}  // namespace pneuma::outputs
