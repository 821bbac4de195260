#pragma once
// Private to outputs/: the voxel output's DICOM part (`voxels: {dicom: true}`; docs/formats.md,
// "DICOM"): the run's study identity and UIDs, and each time point's CT series and RTSTRUCT.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "pneuma/image/dicom.h"
#include "pneuma/outputs/voxels_output.h"
#include "pneuma/scenario/scenario.h"
#include "pneuma/voxels/dicom_io.h"
#include "pneuma/voxels/time_point.h"

namespace pneuma::outputs {

// "2.25.<decimal>": the UID of a UUID made from the SHA-256 of `key` and `what` (RFC 9562
// version 8, a name-based UUID of pneuma's own), so that a run's UIDs are the same run after run
// and differ when what they name differs.
std::string derived_uid(const std::string& key, const std::string& what);

// The structures written per time point: each lung, then (where a lung has several labels, as
// lobes) each of its labels by its segment name, in lung order.
std::vector<voxels::Structure> dicom_structures(const model::Model& model, const VoxelScene& scene);

class DicomRun {
 public:
  // The study: the input series' when the CT was DICOM, else one made for the run (its UIDs
  // derived from the scenario file's bytes and the CT's voxels; patient name and ID the
  // scenario's name; patient position HFS).
  DicomRun(const scenario::Scenario& scenario, const voxels::Image& ct, const std::optional<image::DicomSource>& source,
           std::vector<voxels::Structure> structures);
  // <folder>/ct-<tag>/ct-NNNN.dcm and <folder>/rtstruct-<tag>.dcm for one time point (its CT and
  // warped labels); `number` the series number; `phase_percent` >= 0 for a phase bin.
  std::vector<std::filesystem::path> write(const std::filesystem::path& folder, const std::string& tag,
                                           double phase_percent, bool amplitude_bin, int number,
                                           const voxels::TimePoint& point) const;
  const image::DicomSource& study() const { return study_; }

 private:
  std::string key_;
  image::DicomSource study_;
  std::vector<voxels::Structure> structures_;
};

}  // namespace pneuma::outputs
