// The one translation unit of voxels/ that includes DCMTK (dcmdata): CT series and RT structure
// sets written (dicom_io.h). Every attribute written is listed in docs/formats.md, "DICOM".
// clang-format off
#include <dcmtk/config/osconfig.h>  // first: DCMTK's configuration
// clang-format on
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/oflog/oflog.h>
#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <mutex>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/voxels/dicom_io.h"

namespace pneuma::voxels {
namespace {

namespace fs = std::filesystem;

constexpr const char* kCtImageStorage = UID_CTImageStorage;                // 1.2.840.10008.5.1.4.1.1.2
constexpr const char* kRtStructureSetStorage = UID_RTStructureSetStorage;  // 1.2.840.10008.5.1.4.1.1.481.3
constexpr const char* kStudyComponentManagement =
    "1.2.840.10008.3.1.2.3.2";  // as RT planning systems reference a study

void quiet_dcmtk() {
  static std::once_flag once;
  std::call_once(once, [] { OFLog::configure(OFLogger::FATAL_LOG_LEVEL); });
}

void put(DcmItem& item, const DcmTagKey& key, const std::string& value) {
  if (item.putAndInsertString(key, value.c_str()).bad()) {
    throw ValueError(fmt::format("DICOM: cannot set ({:04X},{:04X}) to '{}'", key.getGroup(), key.getElement(), value));
  }
}
void put(DcmItem& item, const DcmTagKey& key, Uint16 value) {
  if (item.putAndInsertUint16(key, value).bad()) {
    throw ValueError(fmt::format("DICOM: cannot set ({:04X},{:04X})", key.getGroup(), key.getElement()));
  }
}
DcmItem& append_item(DcmItem& parent, const DcmTagKey& sequence) {
  DcmItem* item = nullptr;
  if (parent.findOrCreateSequenceItem(sequence, item, -2).bad() || item == nullptr) {
    throw ValueError(
        fmt::format("DICOM: cannot add an item to ({:04X},{:04X})", sequence.getGroup(), sequence.getElement()));
  }
  return *item;
}

// A decimal string (VR DS: at most 16 characters) of a coordinate in mm.
std::string ds(double value) {
  std::string text = fmt::format("{:.6f}", value);
  if (text.size() > 16) text = fmt::format("{:.6g}", value);
  if (text == "-0.000000") text = "0.000000";
  return text;
}

// Patient, General Study and General Equipment: the same in every file of the run.
void put_patient_and_study(DcmItem& data, const image::DicomSource& study) {
  // The input's character set (its names are copied byte for byte), else UTF-8 (the scenario's).
  put(data, DCM_SpecificCharacterSet,
      study.specific_character_set.empty() ? "ISO_IR 192" : study.specific_character_set);
  put(data, DCM_PatientName, study.patient_name);
  put(data, DCM_PatientID, study.patient_id);
  put(data, DCM_PatientBirthDate, study.patient_birth_date);
  put(data, DCM_PatientSex, study.patient_sex);
  put(data, DCM_StudyInstanceUID, study.study_instance_uid);
  put(data, DCM_StudyDate, study.study_date);
  put(data, DCM_StudyTime, study.study_time);
  put(data, DCM_StudyID, study.study_id);
  put(data, DCM_AccessionNumber, study.accession_number);
  put(data, DCM_ReferringPhysicianName, study.referring_physician_name);
  if (!study.study_description.empty()) put(data, DCM_StudyDescription, study.study_description);
  put(data, DCM_Manufacturer, "pneuma");
  put(data, DCM_ManufacturerModelName, "pneuma");
  put(data, DCM_SoftwareVersions, PNEUMA_VERSION);
}

void save(DcmFileFormat& file, const fs::path& path, E_TransferSyntax syntax) {
  write_atomically(path, [&](const fs::path& tmp) {
    const OFCondition status = file.saveFile(tmp.string().c_str(), syntax, EET_ExplicitLength, EGL_recalcGL,
                                             EPD_noChange, 0, 0, EWM_createNewMeta);
    if (status.bad()) throw IoError(fmt::format("{}: cannot write: {}", path.string(), status.text()));
  });
}

// The grid's slice frame in mm: row and column directions, spacings, and the check that the
// slices are stacked along the normal (what DICOM's Image Plane module can say).
struct SliceFrame {
  Eigen::Vector3d along_row, along_column;
  double column_spacing_mm = 0, row_spacing_mm = 0, slice_step_mm = 0;
};

SliceFrame slice_frame(const Grid& grid) {
  const Eigen::Matrix3d axes = grid.ijk_to_lps.block<3, 3>(0, 0) * 1e3;
  SliceFrame f;
  f.column_spacing_mm = axes.col(0).norm();
  f.row_spacing_mm = axes.col(1).norm();
  f.slice_step_mm = axes.col(2).norm();
  f.along_row = axes.col(0) / f.column_spacing_mm;
  f.along_column = axes.col(1) / f.row_spacing_mm;
  const Eigen::Vector3d normal = f.along_row.cross(f.along_column);
  if (std::abs(f.along_row.dot(f.along_column)) > 1e-6 ||
      std::abs(std::abs(normal.dot(axes.col(2) / f.slice_step_mm)) - 1.0) > 1e-6) {
    throw ValueError("DICOM: the grid's axes are not orthogonal: expected slices stacked along their normal");
  }
  return f;
}

}  // namespace

WrittenSeries write_ct_series(const fs::path& folder, const Image& ct, const CtSeriesSpec& spec) {
  quiet_dcmtk();
  const Grid& grid = ct.grid;
  const SliceFrame frame = slice_frame(grid);
  const std::size_t nx = grid.size[0], ny = grid.size[1], nz = grid.size[2];
  if (nx > 65535 || ny > 65535) throw ValueError("DICOM: a slice of more than 65535 rows or columns");
  const std::string orientation =
      fmt::format("{}\\{}\\{}\\{}\\{}\\{}", ds(frame.along_row.x()), ds(frame.along_row.y()), ds(frame.along_row.z()),
                  ds(frame.along_column.x()), ds(frame.along_column.y()), ds(frame.along_column.z()));
  std::vector<Sint16> pixels(nx * ny);
  WrittenSeries written;
  written.series_instance_uid = spec.series_instance_uid;
  fs::create_directories(folder);
  for (std::size_t k = 0; k < nz; ++k) {
    DcmFileFormat file;
    DcmDataset& data = *file.getDataset();
    const std::string sop_uid = fmt::format("{}.{}", spec.sop_instance_uid_root, k + 1);
    put(data, DCM_SOPClassUID, kCtImageStorage);
    put(data, DCM_SOPInstanceUID, sop_uid);
    put_patient_and_study(data, spec.study);
    // General Series, Frame of Reference
    put(data, DCM_Modality, "CT");
    put(data, DCM_SeriesInstanceUID, spec.series_instance_uid);
    put(data, DCM_SeriesNumber, std::to_string(spec.series_number));
    put(data, DCM_SeriesDescription, spec.series_description);
    put(data, DCM_PatientPosition, spec.study.patient_position);
    put(data, DCM_BodyPartExamined, "CHEST");
    put(data, DCM_FrameOfReferenceUID, spec.study.frame_of_reference_uid);
    put(data, DCM_PositionReferenceIndicator, spec.study.position_reference_indicator);
    // General Image, Image Plane
    put(data, DCM_InstanceNumber, std::to_string(k + 1));
    put(data, DCM_ImageType, "DERIVED\\SECONDARY\\AXIAL");
    put(data, DCM_DerivationDescription, "pneuma: the CT warped to the lungs at this phase");
    const Eigen::Vector3d position =
        (grid.ijk_to_lps * Eigen::Vector4d(0, 0, static_cast<double>(k), 1)).head<3>() * 1e3;
    put(data, DCM_ImagePositionPatient,
        fmt::format("{}\\{}\\{}", ds(position.x()), ds(position.y()), ds(position.z())));
    put(data, DCM_ImageOrientationPatient, orientation);
    put(data, DCM_PixelSpacing, fmt::format("{}\\{}", ds(frame.row_spacing_mm), ds(frame.column_spacing_mm)));
    put(data, DCM_SliceThickness, ds(frame.slice_step_mm));
    put(data, DCM_SliceLocation, ds(position.dot(frame.along_row.cross(frame.along_column))));
    // CT Image, Image Pixel: HU as signed 16-bit pixels, slope 1, intercept 0.
    put(data, DCM_SamplesPerPixel, Uint16{1});
    put(data, DCM_PhotometricInterpretation, "MONOCHROME2");
    put(data, DCM_Rows, static_cast<Uint16>(ny));
    put(data, DCM_Columns, static_cast<Uint16>(nx));
    put(data, DCM_BitsAllocated, Uint16{16});
    put(data, DCM_BitsStored, Uint16{16});
    put(data, DCM_HighBit, Uint16{15});
    put(data, DCM_PixelRepresentation, Uint16{1});
    put(data, DCM_RescaleIntercept, "0");
    put(data, DCM_RescaleSlope, "1");
    put(data, DCM_RescaleType, "HU");
    put(data, DCM_KVP, "");
    put(data, DCM_AcquisitionNumber, "");
    put(data, DCM_WindowCenter, "-600");
    put(data, DCM_WindowWidth, "1600");
    if (spec.respiratory_phase_percent >= 0.0) {
      // The respiratory phase as the enhanced CT's Respiratory Synchronization module says it.
      if (data.putAndInsertFloat32(DCM_NominalPercentageOfRespiratoryPhase,
                                   static_cast<Float32>(spec.respiratory_phase_percent))
              .bad()) {
        throw ValueError("DICOM: cannot set NominalPercentageOfRespiratoryPhase");
      }
    }
    const float* slice = ct.values.data() + k * nx * ny;
    for (std::size_t p = 0; p < nx * ny; ++p) {
      const double hu = std::round(static_cast<double>(slice[p]));
      pixels[p] = static_cast<Sint16>(std::clamp(std::isfinite(hu) ? hu : -1024.0, -32768.0, 32767.0));
    }
    if (data.putAndInsertUint16Array(DCM_PixelData, reinterpret_cast<const Uint16*>(pixels.data()),
                                     static_cast<unsigned long>(pixels.size()))
            .bad()) {
      throw ValueError("DICOM: cannot set the pixel data");
    }
    const fs::path path = folder / fmt::format("ct-{:04}.dcm", k + 1);
    save(file, path, EXS_LittleEndianExplicit);
    written.files.push_back(path);
    written.sop_instance_uids.push_back(sop_uid);
  }
  return written;
}

namespace {

// The outlines of a slice's mask along the pixel edges, as polygons of corner indices (x, y on
// the (nx + 1) x (ny + 1) corner lattice; corner (x, y) is the pixel corner at (x - 1/2, y - 1/2)).
// Each boundary edge has the mask on its left. Pixels touching only at a corner are apart (the
// mask 4-connected, the background 8-connected: at such a corner the trace turns left). A hole
// is joined to the boundary below it by a keyhole: a cut of zero width down a pixel edge line,
// walked down and up, so that each outer outline and its holes are one polygon and any reader
// (even-odd or union of contours alike: plastimatch unites them) fills the mask and no hole.
// Collinear corners are dropped.
std::vector<std::vector<std::array<int, 2>>> outlines(const std::vector<std::uint8_t>& mask, int nx, int ny) {
  const int cx = nx + 1;
  const auto at = [nx](int i, int j) {
    return static_cast<std::size_t>(i) + static_cast<std::size_t>(nx) * static_cast<std::size_t>(j);
  };
  const auto inside = [&](int i, int j) { return i >= 0 && j >= 0 && i < nx && j < ny && mask[at(i, j)] != 0; };
  // The outgoing edges of each corner: their end corners, -1 for none.
  std::vector<std::array<int, 4>> next(static_cast<std::size_t>(cx) * static_cast<std::size_t>(ny + 1),
                                       {-1, -1, -1, -1});
  const auto corner = [cx](int x, int y) { return x + cx * y; };
  const auto add = [&](int from, int to) {
    for (int& slot : next[static_cast<std::size_t>(from)]) {
      if (slot < 0) {
        slot = to;
        return;
      }
    }
  };
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      if (!inside(i, j)) continue;
      if (!inside(i, j - 1)) add(corner(i, j), corner(i + 1, j));
      if (!inside(i + 1, j)) add(corner(i + 1, j), corner(i + 1, j + 1));
      if (!inside(i, j + 1)) add(corner(i + 1, j + 1), corner(i, j + 1));
      if (!inside(i - 1, j)) add(corner(i, j + 1), corner(i, j));
    }
  }
  // Holes: the background not 8-connected to the slice's border. Each one's lowest, then leftmost
  // pixel (hx, hy) has mask below it and to its left; its corner (hx, hy) is cut down to the first
  // corner with background below (a boundary: the outline around it, or another hole's).
  std::vector<std::uint8_t> outside(mask.size(), 0);
  std::vector<std::array<int, 2>> stack;
  const auto flood = [&](std::vector<std::uint8_t>& seen, int i, int j) {
    if (i < 0 || j < 0 || i >= nx || j >= ny || seen[at(i, j)] || mask[at(i, j)]) return;
    seen[at(i, j)] = 1;
    stack.push_back({i, j});
  };
  const auto spread = [&](std::vector<std::uint8_t>& seen) {
    while (!stack.empty()) {
      const auto [i, j] = stack.back();
      stack.pop_back();
      for (int dj = -1; dj <= 1; ++dj) {
        for (int di = -1; di <= 1; ++di) flood(seen, i + di, j + dj);
      }
    }
  };
  for (int i = 0; i < nx; ++i) {
    flood(outside, i, 0);
    flood(outside, i, ny - 1);
  }
  for (int j = 0; j < ny; ++j) {
    flood(outside, 0, j);
    flood(outside, nx - 1, j);
  }
  spread(outside);
  for (int hy = 0; hy < ny; ++hy) {
    for (int hx = 0; hx < nx; ++hx) {
      if (mask[at(hx, hy)] || outside[at(hx, hy)]) continue;
      flood(outside, hx, hy);  // this hole, marked so that it is cut once
      spread(outside);
      for (int y = hy; y > 0 && inside(hx - 1, y - 1) && inside(hx, y - 1); --y) {
        add(corner(hx, y), corner(hx, y - 1));
        add(corner(hx, y - 1), corner(hx, y));
      }
    }
  }
  // Walk the edges: at a corner with several ways on, the left turn, then straight on, then the
  // right turn, a U-turn last (the keyholes' ends); a polygon ends when its first edge comes next.
  const auto score = [cx](int from, int to, int dx, int dy) {
    const int ax = to % cx - from % cx, ay = to / cx - from / cx;
    const int cross = dx * ay - dy * ax, dot = dx * ax + dy * ay;
    return cross > 0 ? 3 : cross < 0 ? 1 : dot > 0 ? 2 : 0;
  };
  std::vector<std::vector<std::array<int, 2>>> loops;
  for (int start = 0; start < static_cast<int>(next.size()); ++start) {
    while (true) {
      auto& first_slot = next[static_cast<std::size_t>(start)];
      const auto first = std::find_if(first_slot.begin(), first_slot.end(), [](int v) { return v >= 0; });
      if (first == first_slot.end()) break;
      const int first_to = *first;
      *first = -1;
      const int fdx = first_to % cx - start % cx, fdy = first_to / cx - start / cx;
      std::vector<std::array<int, 2>> loop{{start % cx, start / cx}};
      int from = first_to, dx = fdx, dy = fdy;
      while (true) {
        auto& slots = next[static_cast<std::size_t>(from)];
        int best = -1, best_score = -1;
        for (int s = 0; s < 4; ++s) {
          if (slots[static_cast<std::size_t>(s)] < 0) continue;
          const int sc = score(from, slots[static_cast<std::size_t>(s)], dx, dy);
          if (sc > best_score) {
            best_score = sc;
            best = s;
          }
        }
        if (from == start && (best < 0 || score(from, first_to, dx, dy) > best_score)) break;  // closed
        if (best < 0) break;  // cannot happen on a closed boundary
        const int to = slots[static_cast<std::size_t>(best)];
        slots[static_cast<std::size_t>(best)] = -1;
        const int ndx = to % cx - from % cx, ndy = to / cx - from / cx;
        if (ndx != dx || ndy != dy) loop.push_back({from % cx, from / cx});
        dx = ndx;
        dy = ndy;
        from = to;
      }
      // The start is a corner only if the last edge turns into the first.
      if (dx == fdx && dy == fdy) loop.erase(loop.begin());
      if (loop.size() >= 3) loops.push_back(std::move(loop));
    }
  }
  return loops;
}

}  // namespace

std::size_t write_rt_struct(const fs::path& path, const image::LabelMap& map, const Grid& ct_grid,
                            const WrittenSeries& series, const std::vector<Structure>& structures,
                            const RtStructSpec& spec) {
  quiet_dcmtk();
  if (map.size != ct_grid.size || !map.ijk_to_lps.isApprox(ct_grid.ijk_to_lps, 1e-12) ||
      series.sop_instance_uids.size() != ct_grid.size[2]) {
    throw ValueError("RTSTRUCT: the label map is not on the CT series' grid");
  }
  DcmFileFormat file;
  DcmDataset& data = *file.getDataset();
  put(data, DCM_SOPClassUID, kRtStructureSetStorage);
  put(data, DCM_SOPInstanceUID, spec.sop_instance_uid);
  put_patient_and_study(data, spec.study);
  // RT Series
  put(data, DCM_Modality, "RTSTRUCT");
  put(data, DCM_SeriesInstanceUID, spec.series_instance_uid);
  put(data, DCM_SeriesNumber, std::to_string(spec.series_number));
  put(data, DCM_SeriesDescription, spec.series_description);
  put(data, DCM_OperatorsName, "");
  put(data, DCM_InstanceNumber, "1");
  put(data, DCM_FrameOfReferenceUID, spec.study.frame_of_reference_uid);
  put(data, DCM_PositionReferenceIndicator, spec.study.position_reference_indicator);
  // Structure Set: the frame of reference, the study, the series and each of its slices.
  put(data, DCM_StructureSetLabel, spec.label.substr(0, 16));
  put(data, DCM_StructureSetDate, spec.study.study_date);
  put(data, DCM_StructureSetTime, spec.study.study_time);
  DcmItem& frame = append_item(data, DCM_ReferencedFrameOfReferenceSequence);
  put(frame, DCM_FrameOfReferenceUID, spec.study.frame_of_reference_uid);
  DcmItem& study = append_item(frame, DCM_RTReferencedStudySequence);
  put(study, DCM_ReferencedSOPClassUID, kStudyComponentManagement);
  put(study, DCM_ReferencedSOPInstanceUID, spec.study.study_instance_uid);
  DcmItem& referenced_series = append_item(study, DCM_RTReferencedSeriesSequence);
  put(referenced_series, DCM_SeriesInstanceUID, series.series_instance_uid);
  for (const std::string& uid : series.sop_instance_uids) {
    DcmItem& image = append_item(referenced_series, DCM_ContourImageSequence);
    put(image, DCM_ReferencedSOPClassUID, kCtImageStorage);
    put(image, DCM_ReferencedSOPInstanceUID, uid);
  }
  const int nx = static_cast<int>(map.size[0]), ny = static_cast<int>(map.size[1]);
  const auto nz = map.size[2];
  std::size_t contours = 0;
  std::vector<std::uint8_t> mask(static_cast<std::size_t>(nx * ny));
  for (std::size_t s = 0; s < structures.size(); ++s) {
    const Structure& structure = structures[s];
    const std::string number = std::to_string(s + 1);
    DcmItem& roi = append_item(data, DCM_StructureSetROISequence);
    put(roi, DCM_ROINumber, number);
    put(roi, DCM_ReferencedFrameOfReferenceUID, spec.study.frame_of_reference_uid);
    put(roi, DCM_ROIName, structure.name);
    put(roi, DCM_ROIGenerationAlgorithm, "AUTOMATIC");
    DcmItem& contour_roi = append_item(data, DCM_ROIContourSequence);
    put(contour_roi, DCM_ReferencedROINumber, number);
    put(contour_roi, DCM_ROIDisplayColor,
        fmt::format("{}\\{}\\{}", structure.colour[0], structure.colour[1], structure.colour[2]));
    DcmItem& observation = append_item(data, DCM_RTROIObservationsSequence);
    put(observation, DCM_ObservationNumber, number);
    put(observation, DCM_ReferencedROINumber, number);
    put(observation, DCM_RTROIInterpretedType, "ORGAN");
    put(observation, DCM_ROIInterpreter, "");
    std::size_t contour_number = 0;
    for (std::size_t k = 0; k < nz; ++k) {
      for (std::size_t p = 0; p < mask.size(); ++p) {
        const std::int32_t v = map.labels[p + mask.size() * k];
        mask[p] = std::find(structure.labels.begin(), structure.labels.end(), v) != structure.labels.end();
      }
      for (const auto& loop : outlines(mask, nx, ny)) {
        std::string points;
        for (const auto& corner : loop) {
          const Eigen::Vector3d x =
              (ct_grid.ijk_to_lps * Eigen::Vector4d(corner[0] - 0.5, corner[1] - 0.5, static_cast<double>(k), 1.0))
                  .head<3>() *
              1e3;
          points += fmt::format("{}{}\\{}\\{}", points.empty() ? "" : "\\", ds(x.x()), ds(x.y()), ds(x.z()));
        }
        DcmItem& contour = append_item(contour_roi, DCM_ContourSequence);
        DcmItem& image = append_item(contour, DCM_ContourImageSequence);
        put(image, DCM_ReferencedSOPClassUID, kCtImageStorage);
        put(image, DCM_ReferencedSOPInstanceUID, series.sop_instance_uids[k]);
        put(contour, DCM_ContourGeometricType, "CLOSED_PLANAR");
        put(contour, DCM_NumberOfContourPoints, std::to_string(loop.size()));
        put(contour, DCM_ContourNumber, std::to_string(++contour_number));
        put(contour, DCM_ContourData, points);
        ++contours;
      }
    }
  }
  fs::create_directories(path.parent_path());
  // Implicit VR: a long contour's ContourData may pass the 64 kB an explicit-VR DS can hold.
  save(file, path, EXS_LittleEndianImplicit);
  return contours;
}

}  // namespace pneuma::voxels
