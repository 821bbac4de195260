#pragma once
// A run's time points as one file, written as they come (one time point in memory at a time):
//
// - 3D Slicer's volume sequence (`.seq.nrrd`, Slicer's Sequences module): one NRRD, gzip, with a
//   list axis after the three domain axes (`kinds: domain domain domain list`; DVFs `vector domain
//   domain domain list` with the identity measurement frame, `displacement field type` and
//   `intent_code:=1006`, as Slicer's transform sequences), `labels` naming the list axis (`time`
//   or `phase`), `units` its unit, `axis 3 index type:=numeric`, `axis 3 index values:=` one value
//   per item, and `DataNodeClassName:=` vtkMRMLLabelMapVolumeNode for label maps,
//   vtkMRMLScalarVolumeNode for images. The header is written first (the item count and index
//   values are known before the first item), then each item is appended to the gzip stream.
// - A 4D NIfTI-1 (`.nii.gz`): dim = (4, nx, ny, nz, nt) for scalars; DVFs dim = (5, nx, ny, nz, nt,
//   3) with intent 1007 and LPS components (ITK 5.2's vector layout, voxel_io.h; with `nifti_ras`
//   intent 1006 and RAS components, the standard's, as DvfConvention::nifti). NIfTI puts the
//   vector component slowest, so a DVF's three components go to three temporary files as the
//   items come and are joined at finish(); scalars stream straight into the gzip stream. The
//   geometry is the grid's in the sform (RAS+, mm; qform_code 0), pixdim[4] the index step when
//   the values are evenly spaced (else 1), `descrip` the index values' name and unit.
//
// Both are written under a temporary name (PendingFile: removed on failure, interruption or
// destruction without finish()) and renamed by finish().
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "pneuma/voxels/grid.h"

namespace pneuma::voxels {

enum class SequenceFormat { slicer_nrrd, nifti_4d };
enum class SequenceVoxel { uint8, int16, int32, float32, vector3 };

struct SequenceSpec {
  Grid grid;
  SequenceVoxel voxel = SequenceVoxel::float32;
  std::string index_name = "time";      // the list axis: "time" or "phase"
  std::string index_unit = "s";         // "s" or "%"
  std::vector<double> index_values;     // one per item
  bool label_map = false;               // Slicer's vtkMRMLLabelMapVolumeNode (else scalar volume)
  std::string displacement_field_type;  // DVFs: "resampling" (pull-back) or "modeling" (forward)
  bool nifti_ras = false;               // a 4D NIfTI DVF: RAS components, intent 1006 (the NIfTI standard)
};

// The smallest voxel type holding every value from `min` to `max` (label maps).
SequenceVoxel label_voxel(std::int32_t min, std::int32_t max);

class SequenceWriter {
 public:
  // Throws ValueError for an empty index or a DVF without its direction, IoError when the
  // temporary cannot be created.
  SequenceWriter(const std::filesystem::path& path, SequenceFormat format, SequenceSpec spec);
  ~SequenceWriter();
  SequenceWriter(const SequenceWriter&) = delete;
  SequenceWriter& operator=(const SequenceWriter&) = delete;

  // One item: the grid's voxels in pneuma's order (i fastest, then j, k; a DVF's 3 components per
  // voxel first), in the spec's voxel type. Throws ValueError for a wrong size or one item too many.
  void append(const void* values, std::size_t bytes);
  // After the last item: renames the file into place and returns its path. Throws ValueError
  // when items are missing, IoError when writing fails.
  std::filesystem::path finish();

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace pneuma::voxels
