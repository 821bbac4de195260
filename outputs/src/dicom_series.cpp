// The voxel output's DICOM part (dicom_series.h): UIDs, the study, the series per time point.
#include "dicom_series.h"

#include <fmt/format.h>

#include <array>
#include <fstream>
#include <memory>
#include <sstream>

#include "pneuma/core/error.h"
#include "pneuma/core/sha256.h"
#include "pneuma/model/model.h"

namespace pneuma::outputs {
namespace {

// The 16 bytes as one unsigned decimal number (no leading zeros), by long division.
std::string decimal(std::array<unsigned char, 16> bytes) {
  std::string digits;
  while (true) {
    bool zero = true;
    unsigned remainder = 0;
    for (unsigned char& byte : bytes) {
      const unsigned value = remainder * 256 + byte;
      byte = static_cast<unsigned char>(value / 10);
      remainder = value % 10;
      zero = zero && byte == 0;
    }
    digits.insert(digits.begin(), static_cast<char>('0' + remainder));
    if (zero) break;
  }
  return digits;
}

std::string file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// Colours of the structures, in order (lungs first, then lobes), as 3D Slicer's generic colours.
constexpr std::array<std::array<int, 3>, 8> kColours{{{128, 174, 128},
                                                      {241, 214, 145},
                                                      {177, 122, 101},
                                                      {111, 184, 210},
                                                      {216, 101, 79},
                                                      {221, 130, 101},
                                                      {144, 238, 144},
                                                      {192, 104, 88}}};

}  // namespace

std::string derived_uid(const std::string& key, const std::string& what) {
  const core::Sha256Digest digest =
      core::Sha256().update(key.data(), key.size()).update("\0", 1).update(what.data(), what.size()).finish();
  std::array<unsigned char, 16> uuid{};
  std::copy_n(digest.begin(), 16, uuid.begin());
  uuid[6] = static_cast<unsigned char>((uuid[6] & 0x0F) | 0x80);  // version 8
  uuid[8] = static_cast<unsigned char>((uuid[8] & 0x3F) | 0x80);  // variant RFC 9562
  return "2.25." + decimal(uuid);
}

std::vector<voxels::Structure> dicom_structures(const model::Model& model, const VoxelScene& scene) {
  std::vector<voxels::Structure> out;
  const image::LabelMap& map = scene.labels();
  const auto colour = [&]() { return kColours[out.size() % kColours.size()]; };
  std::vector<std::vector<int>> lung_values;
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    const model::LungModel& lung = model.lungs[i];
    std::vector<int> values = lung.label_values;
    if (values.empty()) values = {static_cast<int>(i) + 1};  // the rest tets' map: lung i + 1
    const std::string side = scenario::lung_name(lung.side);
    out.push_back({model.lungs.size() == 1 && side.empty() ? "lung" : "lung_" + side, values, colour()});
    lung_values.push_back(std::move(values));
  }
  for (const std::vector<int>& values : lung_values) {
    if (values.size() < 2) continue;
    for (const int v : values) {
      std::string name = fmt::format("label_{}", v);
      for (const image::Segment& segment : map.segments) {
        if (segment.label == v) name = segment.name;
      }
      out.push_back({name, {v}, colour()});
    }
  }
  return out;
}

DicomRun::DicomRun(const scenario::Scenario& scenario, const voxels::Image& ct,
                   const std::optional<image::DicomSource>& source, std::vector<voxels::Structure> structures)
    : structures_(std::move(structures)) {
  const std::string text = file_bytes(scenario.file);
  key_ = core::to_hex(core::Sha256()
                          .update(text.data(), text.size())
                          .update(scenario.name.data(), scenario.name.size())
                          .update(ct.grid.size.data(), sizeof(ct.grid.size))
                          .update(ct.grid.ijk_to_lps.data(), sizeof(double) * 16)
                          .update(ct.values.data(), ct.values.size() * sizeof(float))
                          .finish());
  if (source) {
    study_ = *source;
    key_ += source->study_instance_uid + source->frame_of_reference_uid + source->series_instance_uid;
  } else {
    study_.patient_name = scenario.name;
    study_.patient_id = scenario.name;
    study_.study_instance_uid = derived_uid(key_, "study");
    study_.frame_of_reference_uid = derived_uid(key_, "frame of reference");
    study_.study_id = "pneuma";
    study_.study_description = "pneuma 4D-CT";
  }
  if (study_.patient_position.empty()) study_.patient_position = "HFS";
}

std::vector<std::filesystem::path> DicomRun::write(const std::filesystem::path& folder, const std::string& tag,
                                                   double phase_percent, bool amplitude_bin, int number,
                                                   const voxels::TimePoint& point) const {
  if (!point.ct || !point.labels) throw Error(ExitCode::failure, "voxels: DICOM without a warped CT and labels");
  const voxels::Image& ct = *point.ct;
  // The series' content in its UIDs: the same phase written again gets the same UIDs, another
  // content others.
  const std::string content =
      core::to_hex(core::Sha256().update(ct.values.data(), ct.values.size() * sizeof(float)).finish());
  const std::string phase = phase_percent >= 0.0 ? fmt::format("{:g}%", phase_percent) : tag;
  voxels::CtSeriesSpec spec;
  spec.study = study_;
  spec.series_instance_uid = derived_uid(key_, "CT series " + tag + " " + content);
  spec.sop_instance_uid_root = spec.series_instance_uid;
  spec.series_number = number;
  // "CT 20%" (phase bins, 0 % end-inspiration), "CT 20% AMP" (amplitude bins), "CT end_inspiration".
  spec.series_description = "CT " + phase + (amplitude_bin ? " AMP" : "");
  spec.respiratory_phase_percent = amplitude_bin ? -1.0 : phase_percent;
  const voxels::WrittenSeries series = voxels::write_ct_series(folder / ("ct-" + tag), ct, spec);
  std::vector<std::filesystem::path> files = series.files;

  voxels::RtStructSpec rt;
  rt.study = study_;
  rt.series_instance_uid = derived_uid(key_, "RTSTRUCT series " + tag + " " + content);
  rt.sop_instance_uid = rt.series_instance_uid + ".1";
  rt.series_number = 100 + number;
  rt.series_description = "RTSTRUCT " + phase;
  rt.label = "pneuma " + phase;
  const std::filesystem::path path = folder / ("rtstruct-" + tag + ".dcm");
  voxels::write_rt_struct(path, *point.labels, ct.grid, series, structures_, rt);
  files.push_back(path);
  return files;
}

}  // namespace pneuma::outputs
