#pragma once
// Private to image/: the DICOM CT series reader (dicom_read.cpp, the module's one DCMTK
// translation unit), called by read_scalar_image() for a folder.
#include <filesystem>
#include <string>

#include "pneuma/image/scalar_image.h"

namespace pneuma::image::detail {

// The CT series in `folder` (every regular file in it must be DICOM; one series, or the one
// whose SeriesInstanceUID is `series_uid`), as a scalar image in Hounsfield units with the
// series' patient, study and frame of reference. Throws InputError, one line naming the file and
// the tag, for anything that is not an evenly spaced, untilted, uncompressed single-frame CT
// series with all its pixel data.
ScalarImage read_dicom_series(const std::filesystem::path& folder, const std::string& series_uid);

}  // namespace pneuma::image::detail
