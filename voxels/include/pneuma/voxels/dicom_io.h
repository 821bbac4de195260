#pragma once
// DICOM out (docs/formats.md, "DICOM"): one time point's CT as a CT Image Storage series, one
// file per slice, and its structures as an RT Structure Set on that series. DCMTK's dcmdata in
// dicom_write.cpp only. The UIDs are the caller's (outputs/ derives them from the run, so that a
// run written twice gives the same bytes); nothing here reads a clock or draws a random number.
#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include "pneuma/image/dicom.h"
#include "pneuma/image/label_map.h"
#include "pneuma/voxels/warp.h"

namespace pneuma::voxels {

struct CtSeriesSpec {
  image::DicomSource study;           // patient, study and frame of reference (their UIDs filled in)
  std::string series_instance_uid;    // this series'
  std::string sop_instance_uid_root;  // slice k's SOPInstanceUID is <root>.<k + 1>
  int series_number = 1;
  std::string series_description;           // "CT 20%"
  double respiratory_phase_percent = -1.0;  // >= 0: NominalPercentageOfRespiratoryPhase (0020,9245)
};

struct WrittenSeries {
  std::string series_instance_uid;
  std::vector<std::filesystem::path> files;    // ct-0001.dcm ... in slice order (k)
  std::vector<std::string> sop_instance_uids;  // the same order
};

// `ct` (Hounsfield units) as <folder>/ct-NNNN.dcm, slice k of the grid in file k + 1: int16
// pixels (HU rounded, clamped to -32768..32767), RescaleSlope 1, RescaleIntercept 0; the grid's
// i axis along the rows, j down the columns; ImagePositionPatient the centre of voxel (0, 0, k).
// Throws ValueError for a grid DICOM cannot hold (axes i and j not orthogonal, k not along their
// normal: a tilted stack) and IoError when a file cannot be written; each file is written atomically.
WrittenSeries write_ct_series(const std::filesystem::path& folder, const Image& ct, const CtSeriesSpec& spec);

// A structure: a label map's voxels holding any of `labels`, named and coloured.
struct Structure {
  std::string name;
  std::vector<int> labels;
  std::array<int, 3> colour{255, 0, 0};
};

struct RtStructSpec {
  image::DicomSource study;
  std::string series_instance_uid, sop_instance_uid;
  int series_number = 1;
  std::string series_description, label;  // StructureSetLabel (at most 16 characters)
};

// `map` (on the CT's grid) as an RT Structure Set: each structure as CLOSED_PLANAR contours on the
// series' slices (the outlines of its voxels' squares in each slice, traced on the pixel edges,
// holes as contours of their own), each contour referencing its slice's SOPInstanceUID; the
// referenced series and frame of reference are `series`'s and `spec.study`'s. Returns the
// number of contours written. Throws ValueError when the map is not on `ct_grid`.
std::size_t write_rt_struct(const std::filesystem::path& path, const image::LabelMap& map, const Grid& ct_grid,
                            const WrittenSeries& series, const std::vector<Structure>& structures,
                            const RtStructSpec& spec);

}  // namespace pneuma::voxels
