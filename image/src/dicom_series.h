#pragma once
// Private to image/: the DICOM CT series reader (dicom_read.cpp, the module's one DCMTK
// translation unit), called by read_scalar_image() for a folder.
#include <filesystem>
#include <string>

#include "pneuma/image/label_map.h"
#include "pneuma/image/scalar_image.h"

namespace pneuma::image::detail {

// The CT series in `folder` (every regular file in it must be DICOM; one series, or the one
// whose SeriesInstanceUID is `series_uid`), as a scalar image in Hounsfield units with the
// series' patient, study and frame of reference. Throws InputError, one line naming the file and
// the tag, for anything that is not an evenly spaced, untilted, uncompressed single-frame CT
// series with all its pixel data.
// RT Structure Sets (Modality RTSTRUCT) in the folder are passed over.
ScalarImage read_dicom_series(const std::filesystem::path& folder, const std::string& series_uid);

// The one RT Structure Set in `folder` as a label map on the grid of the CT series beside it
// (which must share its frame of reference): ROI n of the StructureSetROISequence is label n,
// its segment named by ROIName; each CLOSED_PLANAR contour filled on its slice (voxel centres
// inside, even-odd over a slice's contours: holes drawn as contours of their own or by keyholes);
// a voxel in several ROIs gets the smallest one's label.
LabelMap read_dicom_structures(const std::filesystem::path& folder);

// Whether `folder` holds DICOM files (a regular file with 'DICM' at byte 128).
bool holds_dicom(const std::filesystem::path& folder);

}  // namespace pneuma::image::detail
