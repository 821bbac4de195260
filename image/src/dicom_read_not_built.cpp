// The phantom-only build's stand-in for dicom_read.cpp (DCMTK: a run of the built-in phantom
// reads no DICOM; core/not_built.h).
#include "dicom_series.h"
#include "pneuma/core/not_built.h"

namespace pneuma::image::detail {

ScalarImage read_dicom_series(const std::filesystem::path& /*folder*/, const std::string& /*series_uid*/) {
  throw_not_built("DICOM CT series (DCMTK)");
}

LabelMap read_dicom_structures(const std::filesystem::path& /*folder*/) {
  throw_not_built("DICOM RT structure sets (DCMTK)");
}

// A folder given as a label map: DICOM or TotalSegmentator's masks, neither of which this build reads.
bool holds_dicom(const std::filesystem::path& /*folder*/) { throw_not_built("label maps from a folder (DCMTK, ITK)"); }

}  // namespace pneuma::image::detail
