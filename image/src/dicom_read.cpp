// The one translation unit of image/ that includes DCMTK (dcmdata): a folder of single-frame CT
// slices to one scalar image. Every header is read (pixel data left on disk) and checked before
// any voxel is allocated; each failure is one line naming the file and the DICOM tag.
// clang-format off
#include <dcmtk/config/osconfig.h>  // first: DCMTK's configuration
// clang-format on
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcxfer.h>
#include <dcmtk/oflog/oflog.h>
#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <optional>

#include "dicom_series.h"
#include "itk_image.h"
#include "pneuma/core/error.h"
#include "pneuma/core/paths.h"

namespace pneuma::image::detail {
namespace {

namespace fs = std::filesystem;

// DCMTK logs warnings on stderr; pneuma says one line of its own instead.
void quiet_dcmtk() {
  static std::once_flag once;
  std::call_once(once, [] { OFLog::configure(OFLogger::FATAL_LOG_LEVEL); });
}

std::string tag_text(const DcmTagKey& key) {
  DcmTag tag(key);
  return fmt::format("({:04X},{:04X}) {}", key.getGroup(), key.getElement(), tag.getTagName());
}

// One slice's header, as read before its pixels.
struct Slice {
  fs::path file;
  std::unique_ptr<DcmFileFormat> format;
  std::string series_uid;
  Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();  // ImagePositionPatient
  std::array<double, 6> orientation{};                    // ImageOrientationPatient
  double along_normal_mm = 0.0;
};

class SliceReader {
 public:
  SliceReader(const fs::path& file, DcmDataset& data) : name_(file.string()), data_(data) {}

  [[noreturn]] void fail(const DcmTagKey& key, const std::string& what) const {
    throw InputError(fmt::format("{}: {}: {}", name_, tag_text(key), what));
  }
  std::string text(const DcmTagKey& key, bool required) const {
    OFString value;
    if (data_.findAndGetOFStringArray(key, value).bad()) {
      if (required) fail(key, "missing: expected it in every slice of a CT series");
      return {};
    }
    return value.c_str();
  }
  double number(const DcmTagKey& key, unsigned long at, std::optional<double> fallback = std::nullopt) const {
    Float64 value = 0.0;
    if (data_.findAndGetFloat64(key, value, at).bad()) {
      if (fallback) return *fallback;
      fail(key, fmt::format("missing or not a number (value {}): expected it in every slice of a CT series", at + 1));
    }
    if (!std::isfinite(value) || std::abs(value) > 1e6)
      fail(key, fmt::format("value {} is {}: expected a finite number of magnitude at most 1e6", at + 1, value));
    return value;
  }
  unsigned integer(const DcmTagKey& key) const {
    Uint16 value = 0;
    if (data_.findAndGetUint16(key, value).bad()) fail(key, "missing: expected it in every slice of a CT series");
    return value;
  }

 private:
  std::string name_;
  DcmDataset& data_;
};

bool is_hidden(const fs::path& file) { return file.filename().string().starts_with("."); }

}  // namespace

namespace {

// The CT series of `folder` (series_uid: as read_dicom_series); the RT Structure Sets beside it
// are listed in `structure_sets`, not read.
ScalarImage read_series(const fs::path& folder, const std::string& series_uid, std::vector<fs::path>& structure_sets) {
  quiet_dcmtk();
  const std::string folder_name = folder.string();
  std::vector<fs::path> files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    if (entry.is_regular_file() && !is_hidden(entry.path())) files.push_back(entry.path());
  }
  if (ec) throw IoError(folder_name + ": cannot list the folder: " + ec.message());
  std::sort(files.begin(), files.end());  // the same order, and messages, on every machine
  if (files.empty()) throw InputError(folder_name + ": no files: expected the DICOM files of one CT series");

  // Every header, the pixel data left in the file (DCMTK loads values over 4 kB on demand).
  std::vector<Slice> slices;
  std::map<std::string, fs::path> series_seen;
  for (const fs::path& file : files) {
    const std::string name = file.string();
    require_readable_file(file);
    auto format = std::make_unique<DcmFileFormat>();
    const OFCondition status = format->loadFile(name.c_str(), EXS_Unknown, EGL_noChange, 4096, ERM_autoDetect);
    if (status.bad()) {
      // A file that ends early: name the element it ends in (DCMTK keeps what it had read).
      DcmDataset* partial = format->getDataset();
      if (partial != nullptr && partial->card() > 0 &&
          (status == EC_StreamNotifyClient || status == EC_InvalidStream)) {
        const DcmTagKey last = partial->getElement(partial->card() - 1)->getTag();
        throw InputError(
            fmt::format("{}: {}: truncated (the file ends inside it): expected the whole slice", name, tag_text(last)));
      }
      throw InputError(fmt::format("{}: not a readable DICOM file ({}): expected only the DICOM files of one CT series",
                                   name, status.text()));
    }
    DcmDataset& data = *format->getDataset();
    const SliceReader read(file, data);
    if (read.text(DCM_Modality, false) == "RTSTRUCT") {
      structure_sets.push_back(file);
      continue;
    }
    Slice slice;
    slice.file = file;
    slice.series_uid = read.text(DCM_SeriesInstanceUID, true);
    series_seen.emplace(slice.series_uid, file);
    if (!series_uid.empty() && slice.series_uid != series_uid) continue;
    slice.format = std::move(format);
    slices.push_back(std::move(slice));
  }
  if (series_seen.empty()) {
    throw InputError(folder_name + ": no CT slices (only RT Structure Sets): expected the CT series they are drawn on");
  }
  if (slices.empty()) {
    std::string list;
    for (const auto& [uid, file] : series_seen) list += (list.empty() ? "" : ", ") + uid;
    throw InputError(fmt::format("{}: (0020,000E) SeriesInstanceUID: no series {} here: expected one of {}",
                                 folder_name, series_uid, list));
  }
  if (series_seen.size() > 1 && series_uid.empty()) {
    const auto first = series_seen.begin(), second = std::next(first);
    throw InputError(fmt::format(
        "{}: (0020,000E) SeriesInstanceUID: {} series in one folder ({} in {}, {} in {}): expected one, or the "
        "series picked by its SeriesInstanceUID",
        folder_name, series_seen.size(), first->first, first->second.filename().string(), second->first,
        second->second.filename().string()));
  }

  // The header rules, slice by slice: a single-frame CT of 16-bit grey pixels, uncompressed.
  unsigned rows = 0, columns = 0;
  double row_spacing = 0.0, column_spacing = 0.0;
  for (Slice& slice : slices) {
    DcmDataset& data = *slice.format->getDataset();
    const SliceReader read(slice.file, data);
    const std::string modality = read.text(DCM_Modality, true);
    if (modality != "CT") read.fail(DCM_Modality, fmt::format("'{}': expected a CT series (Modality CT)", modality));
    const DcmXfer xfer(data.getOriginalXfer());
    if (xfer.isEncapsulated()) {
      read.fail(
          DCM_TransferSyntaxUID,
          fmt::format("'{}' (compressed): expected uncompressed pixel data (Implicit or Explicit VR Little Endian)",
                      xfer.getXferName()));
    }
    const std::string frames = read.text(DCM_NumberOfFrames, false);
    if (!frames.empty() && frames != "1")
      read.fail(DCM_NumberOfFrames, "'" + frames + "': expected one frame per file");
    if (read.integer(DCM_SamplesPerPixel) != 1) read.fail(DCM_SamplesPerPixel, "expected 1 (grey pixels)");
    if (read.integer(DCM_BitsAllocated) != 16) read.fail(DCM_BitsAllocated, "expected 16 (a CT's pixels)");
    const unsigned stored = read.integer(DCM_BitsStored);
    if (stored < 1 || stored > 16) read.fail(DCM_BitsStored, fmt::format("{}: expected 1 to 16", stored));
    const unsigned slice_rows = read.integer(DCM_Rows), slice_columns = read.integer(DCM_Columns);
    if (slice_rows == 0 || slice_columns == 0) read.fail(DCM_Rows, "an empty slice: expected rows and columns");
    const double dr = read.number(DCM_PixelSpacing, 0), dc = read.number(DCM_PixelSpacing, 1);
    if (!(dr > 1e-3) || !(dc > 1e-3)) read.fail(DCM_PixelSpacing, "expected two positive spacings in mm");
    if (rows == 0) {
      rows = slice_rows;
      columns = slice_columns;
      row_spacing = dr;
      column_spacing = dc;
    } else if (slice_rows != rows || slice_columns != columns) {
      read.fail(DCM_Rows, fmt::format("{} x {} pixels: expected {} x {} as in {}", slice_columns, slice_rows, columns,
                                      rows, slices.front().file.filename().string()));
    } else if (std::abs(dr - row_spacing) > 1e-4 || std::abs(dc - column_spacing) > 1e-4) {
      read.fail(DCM_PixelSpacing, fmt::format("{}\\{}: expected {}\\{} as in {}", dr, dc, row_spacing, column_spacing,
                                              slices.front().file.filename().string()));
    }
    // The pixel data the header declares, before anything is allocated for it.
    DcmElement* pixel_data = nullptr;
    if (data.findAndGetElement(DCM_PixelData, pixel_data).bad() || pixel_data == nullptr) {
      read.fail(DCM_PixelData, "missing: expected the slice's pixels");
    }
    const std::size_t slice_bytes = std::size_t{2} * slice_rows * slice_columns;
    if (pixel_data->getLength() < slice_bytes) {
      read.fail(DCM_PixelData, fmt::format("{} bytes: expected {} x {} pixels of 16 bits ({} bytes)",
                                           pixel_data->getLength(), slice_columns, slice_rows, slice_bytes));
    }
    const double tilt = read.number(DCM_GantryDetectorTilt, 0, 0.0);
    if (std::abs(tilt) > 1e-6) {
      read.fail(DCM_GantryDetectorTilt,
                fmt::format("{} degrees: expected 0 (a tilted gantry's slices are sheared; resample the series first)",
                            tilt));
    }
    for (int a = 0; a < 3; ++a) slice.position_mm[a] = read.number(DCM_ImagePositionPatient, a);
    for (int a = 0; a < 6; ++a) slice.orientation[a] = read.number(DCM_ImageOrientationPatient, a);
  }

  // The slice plane: the first slice's axes, which every slice shares.
  const std::array<double, 6>& o = slices.front().orientation;
  const Eigen::Vector3d along_row(o[0], o[1], o[2]), along_column(o[3], o[4], o[5]);
  if (std::abs(along_row.norm() - 1.0) > 1e-3 || std::abs(along_column.norm() - 1.0) > 1e-3 ||
      std::abs(along_row.dot(along_column)) > 1e-3) {
    SliceReader(slices.front().file, *slices.front().format->getDataset())
        .fail(DCM_ImageOrientationPatient, "expected two orthogonal unit vectors");
  }
  const Eigen::Vector3d normal = along_row.cross(along_column).normalized();
  for (Slice& slice : slices) {
    for (int a = 0; a < 6; ++a) {
      if (std::abs(slice.orientation[a] - o[a]) > 1e-4) {
        SliceReader(slice.file, *slice.format->getDataset())
            .fail(DCM_ImageOrientationPatient, fmt::format("differs from {}'s: expected one orientation for the series",
                                                           slices.front().file.filename().string()));
      }
    }
    slice.along_normal_mm = slice.position_mm.dot(normal);
  }
  std::stable_sort(slices.begin(), slices.end(),
                   [](const Slice& a, const Slice& b) { return a.along_normal_mm < b.along_normal_mm; });
  if (slices.size() < 2) {
    throw InputError(folder_name + ": one slice: expected a CT series of at least two slices");
  }
  // Even steps along the normal, no step sideways (a tilted gantry's slices slide across).
  // The series' step: the median gap (a missing slice or a shifted one stands out against it).
  std::vector<double> gaps;
  for (std::size_t k = 1; k < slices.size(); ++k)
    gaps.push_back(slices[k].along_normal_mm - slices[k - 1].along_normal_mm);
  std::nth_element(gaps.begin(), gaps.begin() + static_cast<std::ptrdiff_t>(gaps.size() / 2), gaps.end());
  const double step = gaps[gaps.size() / 2];
  const double tolerance = std::max(1e-2, 1e-3 * step);
  for (std::size_t k = 1; k < slices.size(); ++k) {
    const Slice& slice = slices[k];
    const SliceReader read(slice.file, *slice.format->getDataset());
    const double gap = slice.along_normal_mm - slices[k - 1].along_normal_mm;
    const std::string previous = slices[k - 1].file.filename().string();
    if (gap < tolerance) {
      read.fail(DCM_ImagePositionPatient,
                fmt::format("the same slice position as {}: expected one slice per position", previous));
    }
    if (std::abs(gap - step) > tolerance) {
      const double ratio = gap / step;
      read.fail(DCM_ImagePositionPatient,
                ratio > 1.5 ? fmt::format("{:.4g} mm from {} where the series steps {:.4g} mm: a missing slice; "
                                          "expected evenly spaced slices",
                                          gap, previous, step)
                            : fmt::format("{:.4g} mm from {} where the series steps {:.4g} mm: expected evenly spaced "
                                          "slices",
                                          gap, previous, step));
    }
    const Eigen::Vector3d sideways = slice.position_mm - slices.front().position_mm -
                                     (slice.along_normal_mm - slices.front().along_normal_mm) * normal;
    if (sideways.norm() > tolerance) {
      read.fail(DCM_ImagePositionPatient,
                fmt::format("moves {:.4g} mm across the slice plane from {}: a tilted gantry; expected slices "
                            "stacked along the normal of ImageOrientationPatient",
                            sideways.norm(), slices.front().file.filename().string()));
    }
  }

  ScalarImage image;
  image.size = {columns, rows, slices.size()};
  image.transform_source = "ImagePositionPatient";
  Eigen::Matrix4d& m = image.ijk_to_lps;
  m.setIdentity();
  // i runs along a row (the first direction cosines, the column spacing), j down the columns.
  m.block<3, 1>(0, 0) = along_row * column_spacing * 1e-3;
  m.block<3, 1>(0, 1) = along_column * row_spacing * 1e-3;
  m.block<3, 1>(0, 2) = normal * step * 1e-3;
  m.block<3, 1>(0, 3) = slices.front().position_mm * 1e-3;

  // The identity the outputs keep (the first slice's; a series shares it).
  {
    const SliceReader read(slices.front().file, *slices.front().format->getDataset());
    DicomSource source;
    source.patient_name = read.text(DCM_PatientName, false);
    source.patient_id = read.text(DCM_PatientID, false);
    source.patient_birth_date = read.text(DCM_PatientBirthDate, false);
    source.patient_sex = read.text(DCM_PatientSex, false);
    source.study_instance_uid = read.text(DCM_StudyInstanceUID, true);
    source.study_date = read.text(DCM_StudyDate, false);
    source.study_time = read.text(DCM_StudyTime, false);
    source.study_id = read.text(DCM_StudyID, false);
    source.accession_number = read.text(DCM_AccessionNumber, false);
    source.referring_physician_name = read.text(DCM_ReferringPhysicianName, false);
    source.study_description = read.text(DCM_StudyDescription, false);
    source.frame_of_reference_uid = read.text(DCM_FrameOfReferenceUID, true);
    source.position_reference_indicator = read.text(DCM_PositionReferenceIndicator, false);
    source.series_instance_uid = read.text(DCM_SeriesInstanceUID, true);
    source.series_description = read.text(DCM_SeriesDescription, false);
    source.patient_position = read.text(DCM_PatientPosition, false);
    source.specific_character_set = read.text(DCM_SpecificCharacterSet, false);
    image.dicom = std::move(source);
  }

  // The pixels, slice by slice, in Hounsfield units.
  const std::size_t per_slice = static_cast<std::size_t>(rows) * columns;
  check_voxel_count(folder_name, image.size, 1);
  image.values.resize(per_slice * slices.size());
  for (std::size_t k = 0; k < slices.size(); ++k) {
    DcmDataset& data = *slices[k].format->getDataset();
    const SliceReader read(slices[k].file, data);
    const double slope = read.number(DCM_RescaleSlope, 0, 1.0), intercept = read.number(DCM_RescaleIntercept, 0, 0.0);
    const bool is_signed = read.integer(DCM_PixelRepresentation) == 1;
    const unsigned bits = read.integer(DCM_BitsStored);
    DcmElement* element = nullptr;
    if (data.findAndGetElement(DCM_PixelData, element).bad() || element == nullptr) {
      read.fail(DCM_PixelData, "missing: expected the slice's pixels");
    }
    const Uint32 expected_bytes = static_cast<Uint32>(per_slice * 2);
    if (element->getLength() < expected_bytes) {
      read.fail(DCM_PixelData, fmt::format("{} bytes: expected {} x {} pixels of 16 bits ({} bytes)",
                                           element->getLength(), columns, rows, expected_bytes));
    }
    const Uint16* pixels = nullptr;
    const OFCondition loaded = element->getUint16Array(const_cast<Uint16*&>(pixels));
    if (loaded.bad() || pixels == nullptr) {
      read.fail(DCM_PixelData, fmt::format("truncated or unreadable ({}): expected {} bytes of pixels", loaded.text(),
                                           expected_bytes));
    }
    const std::uint32_t mask = bits == 16 ? 0xFFFFu : (1u << bits) - 1u;
    const std::uint32_t sign = 1u << (bits - 1);
    float* out = image.values.data() + k * per_slice;
    for (std::size_t p = 0; p < per_slice; ++p) {
      const std::uint32_t raw = pixels[p] & mask;
      const double value = is_signed && (raw & sign) ? static_cast<double>(raw) - static_cast<double>(mask) - 1.0
                                                     : static_cast<double>(raw);
      out[p] = static_cast<float>(slope * value + intercept);
    }
    slices[k].format.reset();  // its pixels are copied: free them
  }

  return image;
}

// A DS or FD value of a sequence item, or a one-line refusal.
double item_number(DcmItem& item, const DcmTagKey& key, unsigned long at, const std::string& name,
                   const std::string& where) {
  Float64 value = 0.0;
  if (item.findAndGetFloat64(key, value, at).bad() || !std::isfinite(value)) {
    throw InputError(fmt::format("{}: {} {}: value {} missing or not a number", name, where, tag_text(key), at + 1));
  }
  return value;
}

// Fills the pixels whose centres a closed polygon (in continuous pixel indices) holds, by the
// even-odd rule, toggling them in `slice` (so that a hole drawn as a contour of its own, and a
// structure drawn twice, cancel: the XOR of the contours).
void toggle_polygon(const std::vector<Eigen::Vector2d>& polygon, std::size_t nx, std::size_t ny,
                    std::vector<std::uint8_t>& slice) {
  std::vector<double> crossings;
  for (std::size_t j = 0; j < ny; ++j) {
    const double y = static_cast<double>(j);
    crossings.clear();
    for (std::size_t e = 0; e < polygon.size(); ++e) {
      const Eigen::Vector2d& a = polygon[e];
      const Eigen::Vector2d& b = polygon[(e + 1) % polygon.size()];
      if ((a.y() <= y) == (b.y() <= y)) continue;  // half-open: a vertex on the row counts once
      crossings.push_back(a.x() + (y - a.y()) * (b.x() - a.x()) / (b.y() - a.y()));
    }
    std::sort(crossings.begin(), crossings.end());
    for (std::size_t c = 0; c + 1 < crossings.size(); c += 2) {
      const double from = std::max(0.0, std::ceil(crossings[c])),
                   to = std::min(static_cast<double>(nx), std::ceil(crossings[c + 1]));
      for (double i = from; i < to; ++i) slice[static_cast<std::size_t>(i) + nx * j] ^= 1;
    }
  }
}

}  // namespace

ScalarImage read_dicom_series(const fs::path& folder, const std::string& series_uid) {
  std::vector<fs::path> structure_sets;
  return read_series(folder, series_uid, structure_sets);
}

LabelMap read_dicom_structures(const fs::path& folder) {
  std::vector<fs::path> structure_sets;
  const ScalarImage ct = read_series(folder, "", structure_sets);
  const std::string folder_name = folder.string();
  if (structure_sets.size() != 1) {
    throw InputError(fmt::format("{}: {} RT Structure Sets (Modality RTSTRUCT): expected one beside the CT series",
                                 folder_name, structure_sets.size()));
  }
  const fs::path& file = structure_sets.front();
  const std::string name = file.string();
  DcmFileFormat format;
  if (format.loadFile(name.c_str()).bad()) throw InputError(name + ": not a readable DICOM file");
  DcmDataset& data = *format.getDataset();
  const SliceReader read(file, data);
  // The frame of reference must be the CT's: contours in another frame would land anywhere.
  DcmItem* frame = nullptr;
  if (data.findAndGetSequenceItem(DCM_ReferencedFrameOfReferenceSequence, frame, 0).good() && frame != nullptr) {
    OFString uid;
    frame->findAndGetOFString(DCM_FrameOfReferenceUID, uid);
    if (uid.c_str() != ct.dicom->frame_of_reference_uid) {
      read.fail(DCM_FrameOfReferenceUID, fmt::format("{} in ReferencedFrameOfReferenceSequence: expected the CT "
                                                     "series' {}",
                                                     uid.c_str(), ct.dicom->frame_of_reference_uid));
    }
  }
  // The ROIs by number, in the file's order.
  std::vector<std::pair<Sint32, std::string>> rois;
  DcmSequenceOfItems* roi_sequence = nullptr;
  if (data.findAndGetSequence(DCM_StructureSetROISequence, roi_sequence).bad() || roi_sequence == nullptr ||
      roi_sequence->card() == 0) {
    read.fail(DCM_StructureSetROISequence, "missing or empty: expected the structures");
  }
  for (unsigned long r = 0; r < roi_sequence->card(); ++r) {
    DcmItem& item = *roi_sequence->getItem(r);
    Sint32 number = 0;
    OFString roi_name;
    if (item.findAndGetSint32(DCM_ROINumber, number).bad() || item.findAndGetOFString(DCM_ROIName, roi_name).bad()) {
      read.fail(DCM_StructureSetROISequence, fmt::format("item {}: expected ROINumber and ROIName", r + 1));
    }
    rois.emplace_back(number, roi_name.c_str());
  }
  // Each ROI's voxels: its contours filled on their slices (even-odd over the contours of a slice).
  const std::size_t nx = ct.size[0], ny = ct.size[1], nz = ct.size[2], per_slice = nx * ny;
  const Eigen::Matrix4d to_ijk = ct.ijk_to_lps.inverse();
  std::vector<std::vector<std::uint8_t>> masks(rois.size());
  DcmSequenceOfItems* contour_sequence = nullptr;
  if (data.findAndGetSequence(DCM_ROIContourSequence, contour_sequence).bad() || contour_sequence == nullptr) {
    read.fail(DCM_ROIContourSequence, "missing: expected the structures' contours");
  }
  for (unsigned long r = 0; r < contour_sequence->card(); ++r) {
    DcmItem& item = *contour_sequence->getItem(r);
    Sint32 number = 0;
    if (item.findAndGetSint32(DCM_ReferencedROINumber, number).bad()) {
      read.fail(DCM_ReferencedROINumber, fmt::format("missing in ROIContourSequence item {}", r + 1));
    }
    const auto roi = std::find_if(rois.begin(), rois.end(), [number](const auto& x) { return x.first == number; });
    if (roi == rois.end()) {
      read.fail(DCM_ReferencedROINumber,
                fmt::format("{}: expected the ROINumber of a StructureSetROISequence item", number));
    }
    std::vector<std::uint8_t>& mask = masks[static_cast<std::size_t>(roi - rois.begin())];
    mask.resize(per_slice * nz, 0);
    DcmSequenceOfItems* contours = nullptr;
    if (item.findAndGetSequence(DCM_ContourSequence, contours).bad() || contours == nullptr) continue;  // empty ROI
    for (unsigned long c = 0; c < contours->card(); ++c) {
      DcmItem& contour = *contours->getItem(c);
      const std::string where = fmt::format("ROI '{}' contour {}", roi->second, c + 1);
      OFString type;
      contour.findAndGetOFString(DCM_ContourGeometricType, type);
      if (type != "CLOSED_PLANAR") {
        if (type == "POINT" || type == "OPEN_PLANAR" || type == "OPEN_NONPLANAR") continue;  // no inside
        throw InputError(fmt::format("{}: {} (3006,0042) ContourGeometricType '{}': expected CLOSED_PLANAR", name,
                                     where, type.c_str()));
      }
      DcmElement* points = nullptr;
      if (contour.findAndGetElement(DCM_ContourData, points).bad() || points == nullptr || points->getVM() < 9 ||
          points->getVM() % 3 != 0) {
        throw InputError(
            fmt::format("{}: {} (3006,0050) ContourData: expected at least three points (x\\y\\z ...)", name, where));
      }
      std::vector<Eigen::Vector2d> polygon;
      double slice_index = 0.0;
      for (unsigned long p = 0; p < points->getVM() / 3; ++p) {
        Eigen::Vector4d x(0, 0, 0, 1);
        for (int a = 0; a < 3; ++a)
          x[a] = item_number(contour, DCM_ContourData, 3 * p + static_cast<unsigned long>(a), name, where) * 1e-3;
        const Eigen::Vector3d ijk = (to_ijk * x).head<3>();
        if (p == 0) slice_index = ijk.z();
        if (std::abs(ijk.z() - slice_index) > 0.01 || std::abs(ijk.z() - std::round(ijk.z())) > 0.1) {
          throw InputError(fmt::format("{}: {} (3006,0050) ContourData: point {} lies between the CT's slices "
                                       "(slice index {:.3f}): expected each contour on one slice of the series",
                                       name, where, p + 1, ijk.z()));
        }
        polygon.emplace_back(ijk.x(), ijk.y());
      }
      const double k = std::round(slice_index);
      if (k < 0 || k >= static_cast<double>(nz)) {
        throw InputError(fmt::format("{}: {} (3006,0050) ContourData: on slice {:.0f}, outside the CT's {} slices",
                                     name, where, k, nz));
      }
      std::vector<std::uint8_t> slice(per_slice, 0);
      toggle_polygon(polygon, nx, ny, slice);
      std::uint8_t* target = mask.data() + static_cast<std::size_t>(k) * per_slice;
      for (std::size_t v = 0; v < per_slice; ++v) target[v] ^= slice[v];
    }
  }
  // One label per voxel: ROI n (file order) is label n; a voxel in several ROIs takes the
  // smallest of them (a lobe over its lung, a tumour over its lobe), so that each name keeps
  // what is most its own.
  std::vector<std::size_t> order(rois.size()), voxels(rois.size(), 0);
  for (std::size_t r = 0; r < rois.size(); ++r) {
    order[r] = r;
    for (const std::uint8_t m : masks[r]) voxels[r] += m;
  }
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return voxels[a] > voxels[b]; });
  LabelMap map;
  map.size = ct.size;
  map.ijk_to_lps = ct.ijk_to_lps;
  map.transform_source = "RTSTRUCT on ImagePositionPatient";
  map.labels.assign(per_slice * nz, 0);
  for (const std::size_t r : order) {
    if (masks[r].empty()) continue;
    for (std::size_t v = 0; v < map.labels.size(); ++v) {
      if (masks[r][v]) map.labels[v] = static_cast<std::int32_t>(r + 1);
    }
  }
  for (std::size_t r = 0; r < rois.size(); ++r)
    map.segments.push_back({rois[r].second, static_cast<std::int32_t>(r + 1)});
  return map;
}

}  // namespace pneuma::image::detail

namespace pneuma::image::detail {

bool holds_dicom(const std::filesystem::path& folder) {
  std::vector<std::filesystem::path> files;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(folder, ec)) {
    if (entry.is_regular_file() && !is_hidden(entry.path())) files.push_back(entry.path());
  }
  return std::any_of(files.begin(), files.end(), [](const std::filesystem::path& file) {
    std::ifstream in(file, std::ios::binary);
    std::array<char, 132> head{};
    in.read(head.data(), head.size());
    return in.gcount() == 132 && std::string(head.data() + 128, 4) == "DICM";
  });
}

}  // namespace pneuma::image::detail
