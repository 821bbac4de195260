// The phantom-only build's stand-in for dicom_write.cpp (DCMTK: a run of the built-in phantom
// writes no DICOM; core/not_built.h).
#include "pneuma/core/not_built.h"
#include "pneuma/voxels/dicom_io.h"

namespace pneuma::voxels {

WrittenSeries write_ct_series(const std::filesystem::path& /*folder*/, const Image& /*ct*/,
                              const CtSeriesSpec& /*spec*/) {
  throw_not_built("DICOM CT series (DCMTK)");
}

std::size_t write_rt_struct(const std::filesystem::path& /*path*/, const image::LabelMap& /*map*/,
                            const Grid& /*ct_grid*/, const WrittenSeries& /*series*/,
                            const std::vector<Structure>& /*structures*/, const RtStructSpec& /*spec*/) {
  throw_not_built("DICOM RT structure sets (DCMTK)");
}

}  // namespace pneuma::voxels
