// The voxel outputs (voxels_output.h): a plugin over voxels/ at the run's end.
#include "pneuma/outputs/voxels_output.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <optional>

#include "dicom_series.h"
#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/image/label_map.h"
#include "pneuma/image/scalar_image.h"
#include "pneuma/mesh/volume/tetrahedralize.h"
#include "pneuma/model/body_motion.h"
#include "pneuma/model/compile.h"
#include "pneuma/outputs/phases.h"
#include "pneuma/voxels/grid.h"
#include "pneuma/voxels/time_point.h"
#include "pneuma/voxels/voxel_io.h"
#include "pneuma/voxels/warp.h"

namespace pneuma::outputs {
namespace {

namespace kind = units::kind;

// The pull-back outside the lungs is solved on a lattice this many times finer than the body
// field's 6 mm cells (BodyMotion::Frame::inverse_field) and interpolated at the voxels.
constexpr std::size_t kInverseRefine = 2;

constexpr const char* kAtExpected =
    "expected end_expiration, end_inspiration, phases or a time >= 0 with its unit, such as '2.4 s'";

std::any read_spec(const scenario::Node* options, const scenario::Scenario& run) {
  VoxelsSpec spec;
  if (!options) return spec;
  if (options->has("at")) {
    spec.at.clear();
    for (const scenario::Node& item : options->sequence("at")) {
      const std::string text = item.as_scalar(kAtExpected);
      if (text == "end_expiration") {
        spec.at.emplace_back(VoxelMoment::end_expiration);
      } else if (text == "end_inspiration") {
        spec.at.emplace_back(VoxelMoment::end_inspiration);
      } else if (text == "phases") {
        spec.phase_bins = true;
      } else {
        double t = -1.0;
        try {
          t = units::parse(text, kind::duration);
        } catch (const Error&) {
          item.fail(kAtExpected);
        }
        if (!(t >= 0.0) || !std::isfinite(t)) item.fail(kAtExpected);
        // A time after the end would silently become the last frame.
        if (t > run.duration_s)
          item.fail(fmt::format("{:.6g} s is after the run's end ({:.6g} s); expected a time from 0 to {:.6g} s", t,
                                run.duration_s, run.duration_s));
        spec.at.emplace_back(t);
      }
    }
    if (spec.at.empty() && !spec.phase_bins)
      options->fail_at("at", "expected at least one time point, such as '[end_inspiration]'");
  }
  if (options->has("spacing")) {
    spec.spacing_m = options->positive_quantity("spacing", kind::length);
    if (spec.spacing_m < 0.25e-3 || spec.spacing_m > 20e-3) {
      options->fail_at("spacing", "expected a voxel size between 0.25 mm and 20 mm, such as '2 mm'");
    }
  }
  if (options->has("format"))
    spec.extension = fmt::format(".{}", options->choice("format", {"nii.gz", "nii", "mha", "nrrd"}));
  if (options->has("dvf_convention")) {
    if (options->choice("dvf_convention", {"itk", "nifti"}) == "nifti") {
      // Only NIfTI has the two conventions: MetaImage and NRRD hold LPS components.
      if (spec.extension != ".nii.gz" && spec.extension != ".nii")
        options->fail_at("dvf_convention", fmt::format("nifti is NIfTI's convention, and format is {}; expected "
                                                       "format nii.gz or nii, or dvf_convention: itk",
                                                       spec.extension.substr(1)));
      spec.dvf_convention = voxels::DvfConvention::nifti;
    }
  }
  if (options->has("sequences")) {
    constexpr const char* kExpected = "expected seq.nrrd (a 3D Slicer sequence) or nii.gz (a 4D NIfTI)";
    for (const scenario::Node& item : options->sequence("sequences")) {
      const std::string text = item.as_scalar(kExpected);
      const voxels::SequenceFormat format = text == "seq.nrrd" ? voxels::SequenceFormat::slicer_nrrd
                                            : text == "nii.gz" ? voxels::SequenceFormat::nifti_4d
                                                               : (item.fail(kExpected), voxels::SequenceFormat{});
      if (std::find(spec.sequences.begin(), spec.sequences.end(), format) == spec.sequences.end())
        spec.sequences.push_back(format);
    }
  }
  if (options->has("points")) {
    const std::filesystem::path file = options->directory("points") / options->string("points");
    try {
      spec.points = read_fiducials(file);
    } catch (const Error& e) {
      options->fail_at("points", e.what());
    }
  }
  if (options->has("structures")) {
    const scenario::Node structures = options->map("structures");
    for (const std::string& name : structures.keys()) {
      StructureSpec structure{name, 0, nullptr, {}};
      const std::string text = structures.string(name);
      constexpr const char* kExpected = "expected a label of the label map (1 to 65535) or a mask file";
      if (!name.empty() && text.find_first_not_of("0123456789") == std::string::npos) {
        structure.label = static_cast<std::int32_t>(structures.integer(name, 0, 1, 65535));
        if (run.mesh.labels_file.empty())
          structures.fail_at(name, "a label needs the scenario's label map (mesh.labels); expected a mask file");
      } else {
        structure.mask_file = structures.directory(name) / text;
        try {
          structure.mask = std::make_shared<const image::LabelMap>(image::read_label_map(structure.mask_file));
        } catch (const Error& e) {
          structures.fail_at(name, std::string(e.what()) + "; " + kExpected);
        }
      }
      if (name.find_first_of("/\\ ") != std::string::npos || name.empty())
        structures.fail_at(name, "expected a name without spaces or slashes (it names files)");
      spec.structures.push_back(std::move(structure));
    }
  }
  image::ScalarImageOptions image_options;
  if (options->has("image_series")) {
    if (!options->has("image")) options->fail_at("image_series", "expected `image` (a DICOM folder) beside it");
    image_options.series_instance_uid = options->string("image_series");
  }
  if (options->has("image")) {
    spec.image_file = options->directory("image") / options->string("image");
    try {
      image::ScalarImage read = image::read_scalar_image(spec.image_file, image_options);
      spec.image_dicom = std::move(read.dicom);
      spec.image = std::make_shared<const voxels::Image>(
          voxels::Image{voxels::Grid{read.size, read.ijk_to_lps}, std::move(read.values)});
    } catch (const Error& e) {
      options->fail_at("image", e.what());
    }
    // A slice (a 2D image read as one voxel thick) cannot hold a chest: every voxel would be air.
    const auto& size = spec.image->grid.size;
    if (std::min({size[0], size[1], size[2]}) < 2) {
      options->fail_at("image", fmt::format("{}: {} x {} x {} voxels; expected a 3D CT around the lungs",
                                            spec.image_file.string(), size[0], size[1], size[2]));
    }
    spec.image_where = options->value_where("image");
  }
  if (options->has("density"))
    spec.mass_preserving = options->choice("density", {"mass_preserving", "unchanged"}) == "mass_preserving";
  spec.jacobian = options->boolean("jacobian", spec.jacobian);
  spec.dicom = options->boolean("dicom", spec.dicom);
  if (spec.dicom && !spec.image) {
    options->fail_at("dicom", "expected `image` (the CT written per time point as a DICOM series) beside it");
  }
  options->finish();
  return spec;
}

// The grid of the run: the label map's (or a coarser one over its extent), else a box around
// the lungs and the body below them.
voxels::Grid run_grid(const model::Model& model, const image::LabelMap* labels, double spacing_m) {
  if (labels) {
    const voxels::Grid grid = voxels::grid_of(*labels);
    return spacing_m > 0.0 ? voxels::grid_with_spacing(grid, spacing_m) : grid;
  }
  const double h = spacing_m > 0.0 ? spacing_m : 2e-3;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const model::LungModel& lung : model.lungs) {
    for (const auto& v : lung.rest.vertices) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
  }
  lo -= Eigen::Vector3d(0.03, 0.03, 0.08);  // room below the diaphragm for the abdomen's motion
  hi += Eigen::Vector3d::Constant(0.03);
  voxels::Grid grid;
  for (int a = 0; a < 3; ++a)
    grid.size[static_cast<std::size_t>(a)] = static_cast<std::size_t>(std::ceil((hi[a] - lo[a]) / h)) + 1;
  grid.ijk_to_lps = Eigen::Matrix4d::Identity();
  grid.ijk_to_lps.block<3, 3>(0, 0) *= h;
  grid.ijk_to_lps.block<3, 1>(0, 3) = lo;
  return grid;
}

// Refuses a CT (`voxels.image`) that leaves part of a lung at rest outside it: the warped CT
// would show air (kOutsideHu) there, and nothing would say so. Checked before any voxel work.
void check_image_covers_lungs(const model::Model& model, const VoxelsSpec& spec) {
  if (!spec.image) return;
  const voxels::Grid& grid = spec.image->grid;
  const Eigen::Matrix4d to_ijk = grid.lps_to_ijk();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  bool inside = true;
  for (const model::LungModel& lung : model.lungs) {
    for (const auto& v : lung.rest.vertices) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
      const Eigen::Vector3d ijk = (to_ijk * v.homogeneous()).head<3>();
      for (int a = 0; a < 3; ++a) {
        // Inside the voxels' outer faces (centres at integers), to a thousandth of a voxel.
        const double n = static_cast<double>(grid.size[static_cast<std::size_t>(a)]);
        inside = inside && ijk[a] >= -0.501 && ijk[a] <= n - 0.499;
      }
    }
  }
  if (inside) return;
  // The image's box in LPS, from its eight outer corners.
  Eigen::Vector3d image_lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), image_hi = -image_lo;
  for (int c = 0; c < 8; ++c) {
    Eigen::Vector4d corner(-0.5, -0.5, -0.5, 1.0);
    for (int a = 0; a < 3; ++a) {
      if ((c >> a) & 1) corner[a] = static_cast<double>(grid.size[static_cast<std::size_t>(a)]) - 0.5;
    }
    const Eigen::Vector3d x = (grid.ijk_to_lps * corner).head<3>();
    image_lo = image_lo.cwiseMin(x);
    image_hi = image_hi.cwiseMax(x);
  }
  const auto box = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return fmt::format("x {:.1f}..{:.1f}, y {:.1f}..{:.1f}, z {:.1f}..{:.1f} mm", a.x() * 1e3, b.x() * 1e3, a.y() * 1e3,
                       b.y() * 1e3, a.z() * 1e3, b.z() * 1e3);
  };
  throw InputError(
      fmt::format("{}: {} covers {} (LPS), not all of the lungs at rest ({}); expected a CT around the lungs",
                  spec.image_where, spec.image_file.string(), box(image_lo, image_hi), box(lo, hi)));
}

// The rest tetrahedra on the grid as labels: lung i + 1 where its rest tets hold the voxel (`rest`,
// voxels::rest_lungs on `grid`).
image::LabelMap rest_label_map(const model::Model& model, const voxels::Grid& grid,
                               const std::vector<std::uint8_t>& rest) {
  image::LabelMap map;
  map.size = grid.size;
  map.ijk_to_lps = grid.ijk_to_lps;
  map.labels.assign(rest.begin(), rest.end());
  map.transform_source = "pneuma";
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    map.segments.push_back({std::string(scenario::lung_name(model.lungs[i].side)), static_cast<std::int32_t>(i) + 1});
  }
  return map;
}
// The volume of the voxels holding any of `values` (m^3). A table of the values (labels are 0 to
// 65535 where they are lung) in place of a search per voxel: the rest label map has 70.8M voxels
// at case004's own grid, most of them not lung, each of which the search compared with every value.
double lung_volume(const image::LabelMap& map, const std::vector<int>& values) {
  int top = -1;
  for (const int v : values) top = std::max(top, v);
  std::vector<std::uint8_t> is_lung(static_cast<std::size_t>(top + 1), 0);
  for (const int v : values) {
    if (v >= 0) is_lung[static_cast<std::size_t>(v)] = 1;
  }
  const auto n = static_cast<std::uint32_t>(is_lung.size());
  std::size_t count = 0;
  for (const std::int32_t v : map.labels) {
    const auto u = static_cast<std::uint32_t>(v);  // a negative label wraps beyond the table
    count += u < n ? is_lung[u] : 0u;
  }
  return static_cast<double>(count) * map.voxel_volume_m3();
}

class VoxelsOutput final : public Output {
  struct VoxelPoint;  // below

 public:
  VoxelsOutput(std::filesystem::path dir, VoxelsSpec spec) : dir_(std::move(dir)), spec_(std::move(spec)) {}
  std::string name() const override { return kVoxelsKey; }
  void begin(const model::Model& model, const RunInfo& /*run*/) override { check_image_covers_lungs(model, spec_); }

  std::vector<std::filesystem::path> finish(const model::Model& model, const RunRecord& run) override {
    const auto& series = run.drive->series;
    const VoxelScene& scene = run_voxel_scene(model, run);
    const double rest_lung_m3 = scene.lung_volume_m3(scene.labels());
    const voxels::Grid& grid = scene.grid();

    std::filesystem::create_directories(dir_ / "voxels");
    std::vector<std::filesystem::path> files;
    if (!run.cache_dir.empty()) files.push_back(dir_ / kRestLungsCacheFile);  // kept for the next run

    voxels::TimePoint point;
    double worst_volume_error = 0.0, min_jacobian = std::numeric_limits<double>::infinity(), folded = 0.0;
    std::size_t folded_tets = 0;
    const std::vector<VoxelPoint> time_points = points(model, run);
    // The sequences hold the phase bins when asked (a 4D-CT's phases, by their percentage), else
    // every time point by its time.
    const auto in_sequence = [this](const VoxelPoint& at) { return !spec_.phase_bins || !at.frame.has_value(); };
    std::optional<voxels::TimePointSequences> sequences;
    if (!spec_.sequences.empty()) {
      std::vector<double> index;
      for (const VoxelPoint& at : time_points) {
        if (in_sequence(at)) index.push_back(at.frame ? series.time_s[*at.frame] : at.phase_percent);
      }
      std::sort(index.begin(), index.end());
      const std::vector<std::int32_t>& rest = scene.labels().labels;
      const auto [lo, hi] = std::minmax_element(rest.begin(), rest.end());
      sequences.emplace(
          dir_ / "voxels", spec_.sequences, spec_.phase_bins ? "phase" : "time", spec_.phase_bins ? "%" : "s", index,
          voxels::label_voxel(lo == rest.end() ? 0 : *lo, hi == rest.end() ? 0 : *hi), spec_.dvf_convention);
    }
    // Computed in the sequences' order (by time, the bins by phase) so that a sequence plays
    // forward; voxels.csv keeps the order asked.
    const auto key = [&](const VoxelPoint& at) { return at.frame ? series.time_s[*at.frame] : at.phase_percent; };
    std::vector<std::size_t> order(time_points.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      const bool in_a = in_sequence(time_points[a]), in_b = in_sequence(time_points[b]);
      if (in_a != in_b) return in_a;
      return in_a && key(time_points[a]) < key(time_points[b]);
    });
    std::vector<std::string> row_of(time_points.size());
    std::vector<VoxelPointFigures> figures(time_points.size());  // voxels.csv's, for report.html
    // Structures: weighted (ITV, mid-ventilation) over the phase bins when asked, else over every time point.
    std::vector<StructureTracker> structures;
    for (const StructureSpec& structure : spec_.structures)
      structures.emplace_back(dir_ / "voxels", spec_.extension, structure);
    const double total_samples = [&] {
      double n = 0.0;
      for (const VoxelPoint& at : time_points) n += at.frame ? 0.0 : static_cast<double>(at.bin_samples);
      return n;
    }();
    std::optional<DicomRun> dicom;
    if (spec_.dicom) dicom.emplace(*run.scenario, *spec_.image, spec_.image_dicom, dicom_structures(model, scene));
    // Each time point's files are written by `writes` while the next one's buffers are computed,
    // and while the sequences, structures and DICOM files below read this one's. Declared after
    // `point`: its destructor waits before the buffers go.
    voxels::WriteQueue writes;
    for (std::size_t step = 0; step < order.size(); ++step) {
      const std::size_t i = order[step];
      const VoxelPoint& at = time_points[i];
      writes.wait();  // the last time point's files, before its buffers are reused
      const voxels::TimePointFiles written =
          scene.compute_and_write(at.scales, point, dir_ / "voxels", at.tag, writes, step + 1 < order.size());
      if (sequences && in_sequence(at)) sequences->append(point);
      for (StructureTracker& structure : structures) {
        const double weight = !spec_.phase_bins ? 1.0
                              : at.frame        ? 0.0
                                                : static_cast<double>(at.bin_samples) / total_samples;
        structure.add(at.tag, point, weight);
      }
      for (const auto& f : {written.forward, written.pullback, written.labels, written.ct, written.jacobian}) {
        if (!f.empty()) files.push_back(f);
      }
      if (dicom) {
        const std::vector<std::filesystem::path> dicom_files =
            dicom->write(dir_ / "dicom", at.tag, at.phase_percent, at.amplitude_bin, static_cast<int>(step + 1), point);
        files.insert(files.end(), dicom_files.begin(), dicom_files.end());
      }
      // The warped lungs' volume against the rest label map's plus each lung's share of the
      // physiology's change (the volume the surface frames follow).
      const double expected = rest_lung_m3 + at.lung_change_m3;
      const double warped = scene.lung_volume_m3(*point.labels);
      const double error = (warped - expected) / expected;
      worst_volume_error = std::max(worst_volume_error, std::abs(error));
      min_jacobian = std::min(min_jacobian, point.jacobian.min);
      folded = std::max(folded, point.jacobian.folded_volume_fraction);
      std::string scale_text;
      for (const double sc : at.scales) scale_text += fmt::format("{}{:.9g}", scale_text.empty() ? "" : " ", sc);
      row_of[i] = fmt::format("{},{},{},{},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{},{:.6g}\n", at.tag,
                              at.frame ? std::to_string(*at.frame) : "",
                              at.frame ? fmt::format("{:.6f}", series.time_s[*at.frame]) : "", scale_text,
                              at.volume_m3 * 1e6, expected * 1e6, warped * 1e6, error * 100.0, point.jacobian.min,
                              point.jacobian.max, point.jacobian.folded_tets, point.jacobian.folded_volume_fraction);
      folded_tets = std::max(folded_tets, point.jacobian.folded_tets);
      figures[i] = {at.tag, at.frame ? std::optional<double>(series.time_s[*at.frame]) : std::nullopt, error * 100.0,
                    point.jacobian.min, point.jacobian.folded_tets};
    }
    writes.wait();
    run.shared.get<VoxelFigures>([&] { return std::make_shared<const VoxelFigures>(VoxelFigures{figures}); });
    if (sequences) {
      for (const auto& f : sequences->finish()) files.push_back(f);
    }
    if (!structures.empty()) {
      std::map<std::string, double> time_of;  // the frames' tags; a bin has no time
      for (const VoxelPoint& at : time_points)
        if (at.frame) time_of[at.tag] = series.time_s[*at.frame];
      write_structures(run, structures, time_of, files);
    }
    if (!spec_.points.empty()) files.push_back(write_trajectories(model, run, time_points));
    const std::filesystem::path csv = dir_ / "voxels" / "voxels.csv";
    write_stream_atomically(csv, false, [&](std::ostream& out) {
      out << "time_point,frame,time_s,scales,physiology_volume_mL,expected_lung_volume_mL,warped_lung_volume_mL,"
             "volume_error_percent,min_jacobian,max_jacobian,folded_tets,folded_volume_fraction\n";
      for (const std::string& row : row_of) out << row;
    });
    files.push_back(csv);
    facts_ = {{"voxels.time_points", std::to_string(row_of.size())},
              {"voxels.grid", fmt::format("{} x {} x {}", grid.size[0], grid.size[1], grid.size[2])},
              {"voxels.spacing_mm", fmt::format("{:.6g}", grid.spacing_m().x() * 1e3)},
              {"voxels.min_jacobian", fmt::format("{:.6g}", min_jacobian)},
              {"voxels.folded_volume_fraction", fmt::format("{:.6g}", folded)},
              {"voxels.folded_tets", std::to_string(folded_tets)},
              {"voxels.max_lung_volume_error_percent", fmt::format("{:.6g}", worst_volume_error * 100.0)},
              {"voxels.interior_model", field::interior_model_name(model.lungs.front().interior->options.model)},
              {"voxels.interior_mesher", mesh::tet_mesher_name(model.lungs.front().interior->mesher)},
              {"voxels.interior_tets", std::to_string(tet_count(model))}};
    // What the unfolding did (docs/voxels.md, "No folded tetrahedron"), over the lungs.
    std::size_t unfolded = 0, dropped = 0;
    double dropped_m3 = 0.0;
    for (const model::LungModel& lung : model.lungs) {
      unfolded += lung.interior->report.unfolded_nodes;
      dropped += lung.interior->report.dropped_tets;
      dropped_m3 += lung.interior->report.dropped_volume_m3;
    }
    facts_.emplace_back("voxels.unfolded_nodes", std::to_string(unfolded));
    facts_.emplace_back("voxels.dropped_tets", std::to_string(dropped));
    facts_.emplace_back("voxels.dropped_volume_mm3", fmt::format("{:.6g}", dropped_m3 * 1e9));
    // Whether the rest lungs' mask came from the previous run's folder (and why a file there was not used).
    facts_.emplace_back("voxels.rest_lungs", scene.rest_lungs_reused() ? "reused from cache"
                                             : scene.rest_lungs_discarded().empty()
                                                 ? "computed"
                                                 : "computed; " + scene.rest_lungs_discarded());
    return files;
  }
  std::vector<std::pair<std::string, std::string>> facts() const override { return facts_; }

 private:
  static std::size_t tet_count(const model::Model& model) {
    std::size_t n = 0;
    for (const model::LungModel& lung : model.lungs) n += lung.interior->mesh.tet_count();
    return n;
  }

  // structures.csv (each structure at each time point) and structures-summary.csv (its ITV and
  // mid-ventilation), beside each structure's files.
  // The same numbers shared for report.html (VoxelStructures): each printed once and read back.
  void write_structures(const RunRecord& run, std::vector<StructureTracker>& structures,
                        const std::map<std::string, double>& time_of, std::vector<std::filesystem::path>& files) {
    const auto mm = [](const Eigen::Vector3d& x) {
      return std::isfinite(x.x()) ? fmt::format("{:.4f},{:.4f},{:.4f}", x.x() * 1e3, x.y() * 1e3, x.z() * 1e3)
                                  : std::string(",,");
    };
    const auto read_back = [](const Eigen::Vector3d& x) -> std::optional<std::array<double, 3>> {
      if (!std::isfinite(x.x())) return std::nullopt;
      std::array<double, 3> out{};
      for (int a = 0; a < 3; ++a) out[static_cast<std::size_t>(a)] = std::stod(fmt::format("{:.4f}", x[a] * 1e3));
      return out;
    };
    const auto g6 = [](double x) { return std::stod(fmt::format("{:.6g}", x)); };
    VoxelStructures shared;
    std::string rows, summary;
    for (StructureTracker& structure : structures) {
      for (const auto& f : structure.finish()) files.push_back(f);
      StructureFacts facts;
      facts.name = structure.spec().name;
      for (const StructureTracker::Row& row : structure.rows()) {
        rows += fmt::format("{},{},{:.6g},{},{:.6g}\n", structure.spec().name, row.tag, row.volume_m3 * 1e6,
                            mm(row.centroid_m), row.weight);
        const auto time = time_of.find(row.tag);
        facts.rows.push_back({row.tag, time == time_of.end() ? std::nullopt : std::optional<double>(time->second),
                              g6(row.volume_m3 * 1e6), read_back(row.centroid_m), g6(row.weight)});
      }
      const std::optional<std::size_t> mid = structure.midventilation();
      summary +=
          fmt::format("{},{:.6g},{},{},{}\n", structure.spec().name, structure.itv_volume_m3() * 1e6,
                      mid ? structure.rows()[*mid].tag : "",
                      mid ? mm(structure.rows()[*mid].centroid_m) : std::string(",,"), mm(structure.mean_position_m()));
      if (structure.itv()) facts.itv_ml = g6(structure.itv_volume_m3() * 1e6);
      if (mid) {
        facts.midventilation = structure.rows()[*mid].tag;
        facts.midventilation_mm = read_back(structure.rows()[*mid].centroid_m);
      }
      facts.mean_mm = read_back(structure.mean_position_m());
      shared.facts.push_back(std::move(facts));
      shared.itvs.push_back(structure.itv());
      facts_.emplace_back("structures." + structure.spec().name + ".itv_mL",
                          fmt::format("{:.6g}", structure.itv_volume_m3() * 1e6));
      if (mid)
        facts_.emplace_back("structures." + structure.spec().name + ".midventilation", structure.rows()[*mid].tag);
    }
    const std::filesystem::path csv = dir_ / "voxels" / "structures.csv";
    write_stream_atomically(csv, false, [&](std::ostream& out) {
      out << "structure,time_point,volume_mL,centroid_x_mm,centroid_y_mm,centroid_z_mm,weight\n" << rows;
    });
    const std::filesystem::path summary_csv = dir_ / "voxels" / "structures-summary.csv";
    write_stream_atomically(summary_csv, false, [&](std::ostream& out) {
      out << "structure,itv_mL,midventilation,midventilation_x_mm,midventilation_y_mm,midventilation_z_mm,"
             "mean_x_mm,mean_y_mm,mean_z_mm\n"
          << summary;
    });
    files.push_back(csv);
    files.push_back(summary_csv);
    run.shared.get<VoxelStructures>([&] { return std::make_shared<const VoxelStructures>(std::move(shared)); });
  }

  // trajectories.csv: every point at every frame, then at each phase bin (when `phases` is in `at`).
  std::filesystem::path write_trajectories(const model::Model& model, const RunRecord& run,
                                           const std::vector<VoxelPoint>& time_points) const {
    const auto& series = run.drive->series;
    std::vector<PointMotion> motions;
    for (const Fiducial& f : spec_.points) motions.push_back(locate(model, f.rest_m));
    // Each position printed once: the CSV's text and report.html's numbers (VoxelTracks) the same.
    const auto mm = [](double x_m) { return fmt::format("{:.4f}", x_m * 1e3); };
    VoxelTracks tracks;
    tracks.times_s = series.time_s;
    for (std::size_t p = 0; p < spec_.points.size(); ++p) {
      const Eigen::Vector3d& rest = spec_.points[p].rest_m;
      tracks.points.push_back(
          {spec_.points[p].name, moves_with(model, motions[p]), {rest.x() * 1e3, rest.y() * 1e3, rest.z() * 1e3}, {}});
    }
    std::filesystem::path csv = dir_ / "voxels" / "trajectories.csv";
    write_stream_atomically(csv, false, [&](std::ostream& out) {
      out << "point,moves_with,frame,time_s,bin,x_mm,y_mm,z_mm\n";
      std::vector<double> scales(model.lungs.size());
      const auto row = [&](const std::string& when, bool frame) {
        for (std::size_t p = 0; p < spec_.points.size(); ++p) {
          const Eigen::Vector3d x = moved_point(model, spec_.points[p].rest_m, motions[p], scales);
          const std::array<std::string, 3> text{mm(x.x()), mm(x.y()), mm(x.z())};
          out << fmt::format("{},{},{},{},{},{}\n", spec_.points[p].name, tracks.points[p].moves_with, when, text[0],
                             text[1], text[2]);
          if (frame)
            tracks.points[p].position_mm.push_back({std::stod(text[0]), std::stod(text[1]), std::stod(text[2])});
        }
      };
      for (std::size_t k = 0; k < series.time_s.size(); ++k) {
        for (std::size_t i = 0; i < model.lungs.size(); ++i) scales[i] = run.scales[i][k];
        row(fmt::format("{},{:.6f},", k, series.time_s[k]), true);
      }
      for (const VoxelPoint& at : time_points) {
        if (at.frame) continue;
        scales = at.scales;
        row(",," + at.tag, false);
      }
    });
    run.shared.get<VoxelTracks>([&] { return std::make_shared<const VoxelTracks>(std::move(tracks)); });
    return csv;
  }

  // The frame of the run's lowest volume: end-expiration, and the volume the rest label map stands for.
  static std::size_t lowest_volume_frame(const std::vector<double>& volume_m3) {
    return static_cast<std::size_t>(std::min_element(volume_m3.begin(), volume_m3.end()) - volume_m3.begin());
  }
  // A time point to write: a frame, or a respiratory bin at its mean volume.
  struct VoxelPoint {
    std::string tag;                   // in the file names: "end_inspiration", "2.400s", "bin_03"
    double phase_percent = -1.0;       // a bin's centre (b * 100 / N); -1 for a frame
    bool amplitude_bin = false;        // the bins are by amplitude, not phase
    std::optional<std::size_t> frame;  // none for a bin
    std::vector<double> scales;        // per model lung
    double volume_m3 = 0.0;            // the physiology's volume above FRC
    double lung_change_m3 = 0.0;       // the lungs' volume change from the scan's (their shares of it)
    std::size_t bin_samples = 0;       // a bin's frames: its share of the breathing time
  };

  // The frames asked for, then (with `phases` in `at`) the non-empty bins of the run's binning.
  std::vector<VoxelPoint> points(const model::Model& model, const RunRecord& run) const {
    const auto& series = run.drive->series;
    // The lungs' volume change from the scan's (the rest label map shows each lung at its
    // reference volume, mesh.reference_volume: the volume the rest mesh stands for), averaged
    // over `frames`: the lungs' shares of it.
    auto lung_change = [&](const std::vector<std::size_t>& frames) {
      double change = 0.0;
      for (const model::LungModel& lung : model.lungs) {
        const std::vector<double>& volume = lung.volumes(*run.drive);
        double mean = 0.0;
        for (const std::size_t k : frames) mean += volume[k];
        mean /= static_cast<double>(frames.size());
        change += lung.share * (mean - lung.reference_volume_m3);
      }
      return change;
    };
    std::vector<VoxelPoint> out;
    for (const auto& [k, tag] : frames_of(series.time_s, series.volume_m3)) {
      VoxelPoint p{tag, -1.0, false, k, {}, series.volume_m3[k], lung_change({k})};
      for (std::size_t i = 0; i < model.lungs.size(); ++i) p.scales.push_back(run.scales[i][k]);
      out.push_back(std::move(p));
    }
    if (spec_.phase_bins) {
      const physiology::PhaseBinning binning = required_phase_bins(run, std::string("outputs.") + kVoxelsKey + ".at");
      for (std::size_t b = 0; b < binning.bins.size(); ++b) {
        const physiology::PhaseBin& bin = binning.bins[b];
        if (bin.samples.empty()) continue;
        out.push_back({fmt::format("bin_{:02}", b), bin.centre_percent,
                       binning.method == physiology::BinningMethod::amplitude, std::nullopt,
                       phase_bin_scales(model, *run.drive, bin), bin.mean_volume_m3, lung_change(bin.samples),
                       bin.samples.size()});
      }
    }
    return out;
  }

  // The frames of the time points with their tags, in the order asked (a frame asked twice: the
  // first). A moment is named as asked (`end_inspiration`), so a script finds its file without the
  // run's times; a time by its frame's time in seconds (`2.400s`).
  std::vector<std::pair<std::size_t, std::string>> frames_of(const std::vector<double>& time_s,
                                                             const std::vector<double>& volume_m3) const {
    const std::size_t low = lowest_volume_frame(volume_m3);
    const auto high =
        static_cast<std::size_t>(std::max_element(volume_m3.begin(), volume_m3.end()) - volume_m3.begin());
    std::vector<std::pair<std::size_t, std::string>> frames;
    for (const VoxelTime& at : spec_.at) {
      std::size_t k = 0;
      std::string tag;
      if (const auto* moment = std::get_if<VoxelMoment>(&at)) {
        const bool expiration = *moment == VoxelMoment::end_expiration;
        k = expiration ? low : high;
        tag = expiration ? "end_expiration" : "end_inspiration";
      } else {
        const double t = std::get<double>(at);
        k = static_cast<std::size_t>(
            std::min_element(time_s.begin(), time_s.end(),
                             [t](double a, double b) { return std::abs(a - t) < std::abs(b - t); }) -
            time_s.begin());
        tag = fmt::format("{:.3f}s", time_s[k]);
      }
      const auto same = [k](const auto& frame) { return frame.first == k; };
      if (std::none_of(frames.begin(), frames.end(), same)) frames.emplace_back(k, std::move(tag));
    }
    return frames;
  }

  std::filesystem::path dir_;
  VoxelsSpec spec_;
  std::vector<std::pair<std::string, std::string>> facts_;
};

}  // namespace

VoxelScene::VoxelScene(const model::Model& model, const scenario::Scenario& scenario, const VoxelsSpec& spec,
                       const voxels::RestLungsCache& cache)
    : model_(model), spec_(spec) {
  for (const model::LungModel& lung : model.lungs) {
    if (!lung.interior) throw Error(ExitCode::failure, "voxels: the model was compiled without the lungs' inside");
  }
  check_image_covers_lungs(model, spec);
  // The label map the lungs came from (compile read it once and kept it for this), else one of the
  // rest tetrahedra: 1 for the right lung (or the only one), 2 for the left.
  const bool from_labels = !scenario.mesh.labels_file.empty();
  if (from_labels) {
    if (!model.label_map) throw Error(ExitCode::failure, "voxels: the model was compiled without its label map");
    labels_ = model.label_map;
    for (const model::LungModel& lung : model.lungs) {
      lung_labels_.insert(lung_labels_.end(), lung.label_values.begin(), lung.label_values.end());
    }
  }
  grid_ = run_grid(model, labels_.get(), spec.spacing_m);
  // Which voxels of the label map each lung's rest mesh holds (warp_labels keeps its rim): kept in
  // the output folder for the next run (at a CT's own grid, a rasterisation of ten million voxels).
  std::vector<voxels::LungMotion> at_rest;
  for (const model::LungModel& lung : model.lungs) {
    at_rest.push_back({lung.interior->mesh, lung.interior->unit_displacement, 0.0});
  }
  voxels::RestLungsLookup rest =
      voxels::cached_rest_lungs(from_labels ? voxels::grid_of(*labels_) : grid_, at_rest, cache);
  rest_lung_ = std::move(rest.mask);
  rest_lungs_reused_ = rest.reused;
  rest_lungs_discarded_ = std::move(rest.discarded);
  if (!from_labels) {  // the label map of the rest tets is that mask itself
    labels_ = std::make_shared<const image::LabelMap>(rest_label_map(model, grid_, rest_lung_));
    for (std::size_t i = 0; i < model.lungs.size(); ++i) lung_labels_.push_back(static_cast<int>(i) + 1);
  }
}

double VoxelScene::lung_volume_m3(const image::LabelMap& map) const { return lung_volume(map, lung_labels_); }

void VoxelScene::compute(std::span<const double> scales, voxels::TimePoint& point) const {
  compute_on(grid_, scales, point);
}

std::vector<InsidePart> VoxelScene::parts_reaching(const voxels::Grid& grid,
                                                   std::span<const std::array<double, 2>> scale_ranges) const {
  if (scale_ranges.size() != model_.lungs.size()) {
    throw ValueError(fmt::format("voxels: {} scale ranges for {} lungs", scale_ranges.size(), model_.lungs.size()));
  }
  // The grid's box (voxel centres) grown by a voxel's diagonal: far wider than the rasteriser's
  // tolerance, so every tet that can hold a voxel is kept (a few more do no harm).
  auto [lo, hi] = grid.centres_box_m();
  const double margin = grid.ijk_to_lps.block<3, 3>(0, 0).cwiseAbs().sum();
  lo.array() -= margin;
  hi.array() += margin;
  std::vector<InsidePart> parts(model_.lungs.size());
  for (std::size_t i = 0; i < model_.lungs.size(); ++i) {
    const model::LungInterior& inside = *model_.lungs[i].interior;
    const double s_lo = std::min(0.0, scale_ranges[i][0]), s_hi = std::max(0.0, scale_ranges[i][1]);
    constexpr auto none = std::numeric_limits<std::uint32_t>::max();
    std::vector<std::uint32_t> renumbered(inside.mesh.nodes.size(), none);
    InsidePart& part = parts[i];
    for (const mesh::Tetrahedron& tet : inside.mesh.tets) {
      Eigen::Vector3d a = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), b = -a;
      for (const std::uint32_t n : tet) {
        for (const double s : {s_lo, s_hi}) {
          const Eigen::Vector3d p = inside.mesh.nodes[n] + s * inside.unit_displacement[n];
          a = a.cwiseMin(p);
          b = b.cwiseMax(p);
        }
      }
      if ((b.array() < lo.array()).any() || (a.array() > hi.array()).any()) continue;
      mesh::Tetrahedron kept{};
      for (std::size_t c = 0; c < 4; ++c) {
        std::uint32_t& to = renumbered[tet[c]];
        if (to == none) {
          to = static_cast<std::uint32_t>(part.mesh.nodes.size());
          part.mesh.nodes.push_back(inside.mesh.nodes[tet[c]]);
          part.unit_displacement.push_back(inside.unit_displacement[tet[c]]);
        }
        kept[c] = to;
      }
      part.mesh.tets.push_back(kept);
    }
  }
  return parts;
}

void VoxelScene::compute_on(const voxels::Grid& grid, std::span<const double> scales, voxels::TimePoint& point,
                            bool with_image, bool with_jacobian, const std::vector<InsidePart>* parts,
                            const voxels::Image* image) const {
  with_inputs(grid, scales, with_image, with_jacobian, parts, image,
              [&](std::span<const voxels::LungMotion> lungs, const voxels::TimePointInputs& inputs) {
                voxels::compute_time_point(grid, lungs, inputs, point);
              });
}

voxels::TimePointFiles VoxelScene::compute_and_write(std::span<const double> scales, voxels::TimePoint& point,
                                                     const std::filesystem::path& folder, const std::string& tag,
                                                     voxels::WriteQueue& writes, bool more_to_come) const {
  voxels::TimePointFiles files;
  with_inputs(grid_, scales, true, false, nullptr, nullptr,
              [&](std::span<const voxels::LungMotion> lungs, const voxels::TimePointInputs& given) {
                voxels::TimePointInputs inputs = given;
                inputs.keep_rest_raster = more_to_come;
                files = voxels::compute_and_write_time_point(grid_, lungs, inputs, point, folder, tag, writes,
                                                             spec_.extension, spec_.dvf_convention);
              });
  return files;
}

void VoxelScene::with_inputs(
    const voxels::Grid& grid, std::span<const double> scales_in, bool with_image, bool with_jacobian,
    const std::vector<InsidePart>* parts, const voxels::Image* image,
    const std::function<void(std::span<const voxels::LungMotion>, const voxels::TimePointInputs&)>& compute) const {
  if (scales_in.size() != model_.lungs.size()) {
    throw ValueError(fmt::format("voxels: {} scales for {} lungs", scales_in.size(), model_.lungs.size()));
  }
  if (parts != nullptr && parts->size() != model_.lungs.size()) {
    throw ValueError(fmt::format("voxels: {} inside parts for {} lungs", parts->size(), model_.lungs.size()));
  }
  const std::vector<double> scales(scales_in.begin(), scales_in.end());
  std::vector<voxels::LungMotion> lungs;
  for (std::size_t i = 0; i < model_.lungs.size(); ++i) {
    const model::LungInterior& inside = *model_.lungs[i].interior;
    if (parts != nullptr) {
      lungs.push_back({(*parts)[i].mesh, (*parts)[i].unit_displacement, scales[i]});
    } else {
      lungs.push_back({inside.mesh, inside.unit_displacement, scales[i]});
    }
  }
  const model::BodyMotion* body = model_.body.get();
  voxels::TimePointInputs inputs;
  inputs.labels = labels_.get();
  inputs.rest_lung = &rest_lung_;
  inputs.lung_labels = lung_labels_;
  inputs.ct = with_image ? (image != nullptr ? image : spec_.image.get()) : nullptr;
  inputs.mass_preserving = spec_.mass_preserving;
  inputs.jacobian_map = spec_.jacobian || with_jacobian;
  if (body) {
    // The lungs' body grids summed with this time point's scales once (BodyMotion::Frame): each
    // voxel's lookup is then one trilinear interpolation, not one per lung.
    auto frame = std::make_shared<const model::BodyMotion::Frame>(body->frame(scales));
    // Each thread's lookups through its own Cursor: the rasterisers ask row after row of voxels,
    // which share the lattice's y-z blends (the same bits as frame->displacement).
    inputs.forward_outside = [frame](const Eigen::Vector3d& x, const Eigen::Vector3d*) {
      thread_local model::BodyMotion::Frame::Cursor cursor;
      return cursor.displacement(*frame, x);
    };
    // The inverse of x -> x + u(x) outside the lungs (BodyMotion::Frame::inverse) solved on a
    // lattice of half u's cell (3 mm) over the grid's box and interpolated: one lookup per
    // voxel, not an iteration (#50; docs/voxels.md gives its largest difference from the exact one).
    const auto [lo, hi] = grid.centres_box_m();
    auto inverse = std::make_shared<const model::BodyMotion::Frame>(frame->inverse_field(lo, hi, kInverseRefine));
    inputs.pullback_outside = [inverse](const Eigen::Vector3d& x, const Eigen::Vector3d*) {
      thread_local model::BodyMotion::Frame::Cursor cursor;
      return cursor.displacement(*inverse, x);
    };
  }
  compute(lungs, inputs);
}

const VoxelsSpec* requested_voxels(const scenario::Scenario& scenario) {
  const scenario::OutputRequest* request = scenario.output(kVoxelsKey);
  return request ? &std::any_cast<const VoxelsSpec&>(request->settings) : nullptr;
}

const VoxelScene& run_voxel_scene(const model::Model& model, const RunRecord& run) {
  return run.shared.get<VoxelScene>([&] {
    const VoxelsSpec* spec = requested_voxels(*run.scenario);
    if (spec == nullptr) throw Error(ExitCode::failure, "voxels: the scenario has no voxel output");
    voxels::RestLungsCache cache;
    if (!run.cache_dir.empty())
      cache = {run.cache_dir / kRestLungsCacheFile, run.info.output_dir / kRestLungsCacheFile};
    return std::make_shared<const VoxelScene>(model, *run.scenario, *spec, cache);
  });
}

namespace {

// The report's fixed scales: a lung window for the CT, and the Jacobian from halving to doubling
// (log scale, 1 in the middle).
constexpr std::array<double, 2> kCtWindowHu{-1000.0, 200.0};
constexpr std::array<double, 2> kJacobianRange{0.5, 2.0};

// The box of `ct` that the pull-back `field` samples (each voxel's x + v(x), its trilinear
// corners and two voxels more for rounding), as an image of its own on the same lattice: a
// slice plane's warped CT from it is the whole scan's, and the mass-preserving CT, made anew
// at each channel time, is made on a slab of the scan instead of all of it.
voxels::Image ct_reached(const voxels::Image& ct, const voxels::DisplacementField& field) {
  const Eigen::Matrix4d to_ijk = ct.grid.lps_to_ijk();
  std::array<double, 3> lo{}, hi{};
  lo.fill(std::numeric_limits<double>::infinity());
  hi.fill(-std::numeric_limits<double>::infinity());
  const auto& n = field.grid.size;
  for (std::size_t k = 0, v = 0; k < n[2]; ++k)
    for (std::size_t j = 0; j < n[1]; ++j)
      for (std::size_t i = 0; i < n[0]; ++i, ++v) {
        const Eigen::Vector3d x = field.grid.centre_m(i, j, k) + field.displacement_m[v].cast<double>();
        const Eigen::Vector3d q = (to_ijk * x.homogeneous()).head<3>();
        if (!q.allFinite()) continue;
        for (std::size_t a = 0; a < 3; ++a) {
          lo[a] = std::min(lo[a], q[static_cast<Eigen::Index>(a)]);
          hi[a] = std::max(hi[a], q[static_cast<Eigen::Index>(a)]);
        }
      }
  std::array<std::size_t, 3> first{}, size{};
  for (std::size_t a = 0; a < 3; ++a) {
    const double top = static_cast<double>(ct.grid.size[a] - 1);
    // Nothing reached (an empty plane): one voxel, which no sample reads.
    if (!(lo[a] <= hi[a])) lo[a] = hi[a] = 0.0;
    const double from = std::clamp(std::floor(lo[a]) - 2.0, 0.0, top),
                 to = std::clamp(std::ceil(hi[a]) + 2.0, 0.0, top);
    first[a] = static_cast<std::size_t>(from);
    size[a] = static_cast<std::size_t>(to) - first[a] + 1;
  }
  voxels::Image crop;
  crop.grid.size = size;
  Eigen::Matrix4d shift = Eigen::Matrix4d::Identity();
  shift.block<3, 1>(0, 3) << static_cast<double>(first[0]), static_cast<double>(first[1]),
      static_cast<double>(first[2]);
  crop.grid.ijk_to_lps = ct.grid.ijk_to_lps * shift;
  crop.values.resize(crop.grid.voxel_count());
  for (std::size_t k = 0, v = 0; k < size[2]; ++k)
    for (std::size_t j = 0; j < size[1]; ++j, v += size[0]) {
      const float* row = ct.values.data() + ct.grid.index(first[0], first[1] + j, first[2] + k);
      std::copy(row, row + size[0], crop.values.begin() + static_cast<std::ptrdiff_t>(v));
    }
  return crop;
}

std::uint8_t channel_byte(double value, const LabelSlice::Channel& channel) {
  const double lo = channel.log ? std::log(channel.lo) : channel.lo;
  const double hi = channel.log ? std::log(channel.hi) : channel.hi;
  const double v = channel.log ? std::log(std::max(value, 1e-12)) : value;
  const double byte = std::round(255.0 * (v - lo) / (hi - lo));
  return static_cast<std::uint8_t>(std::clamp(std::isfinite(byte) ? byte : 0.0, 0.0, 255.0));
}

}  // namespace

std::vector<LabelSlice> report_label_slices(const model::Model& model, const RunRecord& run,
                                            std::vector<int>& lung_labels, std::size_t max_times,
                                            std::size_t max_channel_times) {
  if (requested_voxels(*run.scenario) == nullptr || max_times == 0) return {};
  for (const model::LungModel& lung : model.lungs) {
    if (!lung.interior) return {};
  }
  const VoxelScene& scene = run_voxel_scene(model, run);
  lung_labels = scene.lung_labels();
  // The lungs' box at rest, and the first lung's middle.
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  Eigen::Vector3d first_lo = lo, first_hi = hi;
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    for (const auto& v : model.lungs[i].rest.vertices) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
      if (i == 0) {
        first_lo = first_lo.cwiseMin(v);
        first_hi = first_hi.cwiseMax(v);
      }
    }
  }
  // Margins: 2 cm around, 8 cm below (the abdomen moving with the diaphragm).
  lo -= Eigen::Vector3d(0.02, 0.02, 0.08);
  hi += Eigen::Vector3d::Constant(0.02);
  const Eigen::Vector3d extent = hi - lo;
  const double h = std::max(2e-3, extent.maxCoeff() / 200.0);
  const auto count = [h](double length) { return static_cast<std::size_t>(std::ceil(length / h)) + 1; };
  // A plane's grid: i along `across` (x or y), k along z (S), one voxel thick at `fixed`.
  auto plane = [&](bool coronal) {
    voxels::Grid grid;
    grid.size = coronal ? std::array<std::size_t, 3>{count(extent.x()), 1, count(extent.z())}
                        : std::array<std::size_t, 3>{1, count(extent.y()), count(extent.z())};
    grid.ijk_to_lps = Eigen::Matrix4d::Identity();
    grid.ijk_to_lps.block<3, 3>(0, 0) *= h;
    grid.ijk_to_lps.block<3, 1>(0, 3) = coronal ? Eigen::Vector3d(lo.x(), 0.5 * (lo.y() + hi.y()), lo.z())
                                                : Eigen::Vector3d(0.5 * (first_lo.x() + first_hi.x()), lo.y(), lo.z());
    return grid;
  };
  const std::vector<double>& time_s = run.drive->series.time_s;
  const std::size_t frames = time_s.size(), n = std::min(frames, max_times);
  std::vector<LabelSlice> slices;
  voxels::TimePoint point;
  const VoxelsSpec& spec = *requested_voxels(*run.scenario);
  const bool scene_has_image = spec.image != nullptr;
  // |DVF|'s scale: the largest displacement of any lung's surface over the run, rounded up to a
  // whole millimetre (the field's largest value is on the surface, where the lung moves most).
  double max_displacement_mm = 1.0;
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    const auto& u = model.lungs[i].unit_displacement;
    double largest_u = 0.0;
    for (const auto& d : u) largest_u = std::max(largest_u, d.norm());
    double largest_s = 0.0;
    for (const double sc : run.scales[i]) largest_s = std::max(largest_s, std::abs(sc));
    max_displacement_mm = std::max(max_displacement_mm, std::ceil(largest_u * largest_s * 1e3));
  }
  const VoxelStructures* shared_structures = run.shared.find<VoxelStructures>();  // the ITVs
  image::LabelMap warped_mask;
  // Each lung's lowest and highest scale of the run: the parts of the insides a plane needs.
  std::vector<std::array<double, 2>> scale_ranges;
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    const auto [lowest, highest] = std::minmax_element(run.scales[i].begin(), run.scales[i].end());
    scale_ranges.push_back(run.scales[i].empty() ? std::array<double, 2>{0.0, 0.0}
                                                 : std::array<double, 2>{*lowest, *highest});
  }
  for (const bool coronal : {true, false}) {
    const voxels::Grid grid = plane(coronal);
    const std::vector<InsidePart> parts = scene.parts_reaching(grid, scale_ranges);
    LabelSlice slice;
    for (const StructureSpec& structure : spec.structures) slice.structures.push_back({structure.name, {}, {}});
    slice.name = coronal ? "coronal" : "sagittal";
    const Eigen::Vector3d origin = grid.ijk_to_lps.block<3, 1>(0, 3);
    slice.fixed =
        coronal ? fmt::format("y = {:.1f} mm", origin.y() * 1e3) : fmt::format("x = {:.1f} mm", origin.x() * 1e3);
    slice.width = coronal ? grid.size[0] : grid.size[1];
    slice.height = grid.size[2];
    slice.pixel_mm = h * 1e3;
    slice.origin_mm = {origin.x() * 1e3, origin.y() * 1e3, origin.z() * 1e3};
    // The channels at every `stride`-th slice time (the first and the last among them).
    const std::size_t stride = max_channel_times == 0 ? n + 1 : (n + max_channel_times - 1) / max_channel_times;
    const bool with_ct = scene_has_image;
    if (max_channel_times > 0) {
      if (with_ct) slice.channels.push_back({"ct", "HU", kCtWindowHu[0], kCtWindowHu[1], false, {}});
      slice.channels.push_back({"displacement", "mm", 0.0, max_displacement_mm, false, {}});
      slice.channels.push_back({"jacobian", "", kJacobianRange[0], kJacobianRange[1], true, {}});
    }
    for (std::size_t t = 0; t < n; ++t) {
      // Frames spread evenly, the first and the last included.
      const std::size_t k = n == 1 ? 0 : (t * (frames - 1) + (n - 1) / 2) / (n - 1);
      std::vector<double> scales;
      for (std::size_t i = 0; i < model.lungs.size(); ++i) scales.push_back(run.scales[i][k]);
      const bool channels = max_channel_times > 0 && (t % stride == 0 || t + 1 == n);
      // The CT's slices from the whole insides (its rest lungs are found on the CT's own grid),
      // on the part of the scan this plane's pull-back reaches: the field first, from the parts.
      const bool ct_now = channels && with_ct;
      if (ct_now) {
        scene.compute_on(grid, scales, point, false, false, &parts);
        const voxels::Image ct = ct_reached(*spec.image, point.pullback);
        scene.compute_on(grid, scales, point, true, true, nullptr, &ct);
      } else {
        scene.compute_on(grid, scales, point, false, channels, &parts);
      }
      // Pixel (row, c) of the plane: row 0 is the most superior.
      const auto voxel = [&](std::size_t row, std::size_t c) {
        const std::size_t z = slice.height - 1 - row;
        return coronal ? grid.index(c, 0, z) : grid.index(0, c, z);
      };
      std::vector<std::int32_t> image;
      image.reserve(slice.width * slice.height);
      for (std::size_t row = 0; row < slice.height; ++row)
        for (std::size_t c = 0; c < slice.width; ++c) image.push_back(point.labels->labels[voxel(row, c)]);
      slice.times_s.push_back(time_s[k]);
      slice.labels.push_back(std::move(image));
      // Each structure as the voxel output warps it (StructureTracker::add): the label among the
      // warped labels, or the mask file pulled back.
      for (std::size_t s = 0; s < spec.structures.size(); ++s) {
        const StructureSpec& structure = spec.structures[s];
        if (structure.mask) voxels::warp_labels(*structure.mask, point.pullback, warped_mask);
        const std::vector<std::int32_t>& values = structure.mask ? warped_mask.labels : point.labels->labels;
        std::vector<std::int32_t> mask;
        mask.reserve(slice.width * slice.height);
        for (std::size_t row = 0; row < slice.height; ++row) {
          for (std::size_t c = 0; c < slice.width; ++c) {
            const std::int32_t v = values[voxel(row, c)];
            mask.push_back(structure.mask ? v != 0 : v == structure.label);
          }
        }
        slice.structures[s].masks.push_back(std::move(mask));
      }
      if (!channels) continue;
      slice.channel_times_s.push_back(time_s[k]);
      for (LabelSlice::Channel& channel : slice.channels) {
        std::vector<std::uint8_t> bytes;
        bytes.reserve(slice.width * slice.height);
        for (std::size_t row = 0; row < slice.height; ++row) {
          for (std::size_t c = 0; c < slice.width; ++c) {
            const std::size_t v = voxel(row, c);
            const double value = channel.name == "ct"             ? point.ct->values[v]
                                 : channel.name == "displacement" ? point.forward.displacement_m[v].norm() * 1e3
                                                                  : point.jacobian_map->values[v];
            bytes.push_back(channel_byte(value, channel));
          }
        }
        channel.images.push_back(std::move(bytes));
      }
    }
    // Each ITV sampled at the plane's pixel centres (nearest voxel; 0 outside it).
    for (std::size_t s = 0; shared_structures != nullptr && s < shared_structures->itvs.size(); ++s) {
      if (!shared_structures->itvs[s] || s >= slice.structures.size()) continue;
      const image::LabelMap& itv = *shared_structures->itvs[s];
      const voxels::Grid itv_grid = voxels::grid_of(itv);
      const Eigen::Matrix4d to_ijk = itv_grid.lps_to_ijk();
      std::vector<std::int32_t>& out = slice.structures[s].itv;
      for (std::size_t row = 0; row < slice.height; ++row) {
        for (std::size_t c = 0; c < slice.width; ++c) {
          const std::size_t z = slice.height - 1 - row;
          const Eigen::Vector3d x = coronal ? grid.centre_m(c, 0, z) : grid.centre_m(0, c, z);
          const Eigen::Vector3d ijk = (to_ijk * x.homogeneous()).head<3>();
          std::array<std::size_t, 3> at{};
          bool inside = true;
          for (std::size_t a = 0; a < 3; ++a) {
            const double nearest = std::round(ijk[static_cast<Eigen::Index>(a)]);
            inside = inside && nearest >= 0.0 && nearest < static_cast<double>(itv_grid.size[a]);
            at[a] = inside ? static_cast<std::size_t>(nearest) : 0;
          }
          out.push_back(inside && itv.labels[itv_grid.index(at[0], at[1], at[2])] != 0);
        }
      }
    }
    slices.push_back(std::move(slice));
  }
  return slices;
}

OutputPlugin voxels_output() {
  OutputNeeds needs;
  needs.interior = true;
  return {{kVoxelsKey, false, read_spec}, needs, [](const std::any& settings, const std::filesystem::path& out) {
            return std::make_unique<VoxelsOutput>(out, std::any_cast<VoxelsSpec>(settings));
          }};
}

}  // namespace pneuma::outputs
