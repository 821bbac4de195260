#pragma once
// report.html: one self-contained page per run (docs/formats.md): the lung breathing (the
// run's glb, three.js, orbit, play/pause/scrub) in step with the physiology plots (volume, flow,
// pressures), the per-region motion table, the respiratory bins (phases) and slices of the
// warped label map (voxel outputs), under one time cursor. It opens from the file
// system without a server or the internet: three.js (Debian's libjs-three, r111, found at
// configure time), the page's script, the data and the glb (base64) are all inside the file.
#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "pneuma/outputs/breath_motion.h"
#include "pneuma/outputs/output.h"
#include "pneuma/physiology/simulate.h"

namespace pneuma::outputs {

// The most samples per plotted series; longer series keep every `report_stride()`-th sample.
inline constexpr std::size_t kReportMaxSamples = 4000;

// The decimation step for `samples` samples: 1 when they fit, else ceil(samples / (max - 1)).
// The page plots samples 0, stride, 2 stride, ... and always the last one: at most max_samples.
std::size_t report_stride(std::size_t samples, std::size_t max_samples = kReportMaxSamples);

// The run's frames in respiratory bins (outputs.phases, or a measured trace), for the bands on
// the volume plot and the bin under the cursor.
struct ReportBins {
  std::string method;                  // "phase" | "amplitude"
  std::vector<double> centre_percent;  // per bin
  std::vector<std::size_t> frames;     // per bin: how many frames it holds
  std::vector<double> mean_volume_m3;  // per bin (NaN when empty)
  std::vector<int> bin_of_frame;       // per frame: its bin, -1 for none
};

// One plane through the warped label map at several times (voxel outputs on): the image the
// page draws under the cursor, the diaphragm's descent visible in it.
struct LabelSlice {
  std::string name;                   // "coronal" | "sagittal"
  std::string fixed;                  // the plane, such as "y = 12.0 mm" (LPS)
  std::size_t width = 0, height = 0;  // pixels; row 0 is the most superior
  double pixel_mm = 0.0;
  // The LPS centre (mm) of the plane's voxel (0, 0, 0): the bottom-left pixel (row height - 1,
  // column 0). Columns run along x (coronal) or y (sagittal), rows up along z.
  std::array<double, 3> origin_mm{};
  std::vector<double> times_s;
  std::vector<std::vector<std::int32_t>> labels;  // per time: width * height, row by row
  // Beside the labels, at `channel_times_s` (some of `times_s`): 8-bit images of the same pixels,
  // each byte b standing for lo + (hi - lo) b / 255 (log: exp of that in log space).
  struct Channel {
    std::string name;  // "ct" (the warped CT, when given), "displacement" (|forward DVF|), "jacobian"
    std::string unit;  // "HU", "mm", ""
    double lo = 0.0, hi = 1.0;
    bool log = false;
    std::vector<std::vector<std::uint8_t>> images;  // per channel time: width * height, row by row
  };
  std::vector<double> channel_times_s;
  std::vector<Channel> channels;
  // Each structure (voxels.structures) on the plane: per time of `times_s` its warped mask (0/1,
  // width * height, row by row, pulled back as the labels), and its ITV sampled at the pixels
  // (nearest voxel; empty without one).
  struct Structure {
    std::string name;
    std::vector<std::vector<std::int32_t>> masks;
    std::vector<std::int32_t> itv;
  };
  std::vector<Structure> structures;
};

// One voxel time point's quality figures (voxels.csv), for the page under the cursor.
struct VoxelPointFigures {
  std::string tag;               // "end_inspiration", "2.400s", "bin_03"
  std::optional<double> time_s;  // none for a bin
  double volume_error_percent = 0.0;
  double min_jacobian = 0.0;
  std::size_t folded_tets = 0;
};

// A point that follows the breath (voxels.points) at every frame: trajectories.csv's frame rows,
// the same numbers (LPS mm, as the CSV prints them).
struct PointTrack {
  std::string name;
  std::string moves_with;                          // "right interior", "body", ...
  std::array<double, 3> rest_mm{};                 // where the fiducials CSV puts it
  std::vector<std::array<double, 3>> position_mm;  // per frame
};

// A structure's figures as structures.csv and structures-summary.csv print them.
struct StructureFacts {
  std::string name;
  struct Row {
    std::string tag;
    std::optional<double> time_s;  // none for a bin
    double volume_ml = 0.0;
    std::optional<std::array<double, 3>> centroid_mm;  // none when the mask is empty
    double weight = 0.0;
  };
  std::vector<Row> rows;
  std::optional<double> itv_ml;  // none without a weighted time point
  std::string midventilation;    // its time point's tag, "" for none
  std::optional<std::array<double, 3>> midventilation_mm, mean_mm;
};

struct ReportInput {
  std::string scenario_name;
  std::string description;
  double duration_s = 0.0;  // the animation's extent: the last frame's time
  double frame_rate_hz = 0.0;
  std::size_t frame_count = 0;
  // The physiology series as physiology.csv has it (same samples, same columns, same units).
  const physiology::SimulationResult* physiology = nullptr;
  std::vector<BreathMotion> motion;                        // the motion table: means over breaths
  std::vector<std::string> lung_names;                     // two lungs: by BreathMotion::lung; one: empty
  std::vector<std::pair<std::string, std::string>> facts;  // {label, value with unit}, in order
  std::string glb;                                         // the run's breathing.glb bytes
  std::optional<ReportBins> bins;                          // with outputs.phases or a trace
  std::vector<LabelSlice> slices;                          // with voxel outputs
  std::vector<int> lung_labels;                            // the slices' lung label values
  std::vector<VoxelPointFigures> voxel_points;             // voxels.csv's figures (voxel outputs)
  std::vector<double> track_times_s;                       // the frames' times, for `tracks`
  std::vector<PointTrack> tracks;                          // voxels.points (trajectories.csv)
  std::vector<StructureFacts> structures;                  // voxels.structures (structures*.csv)
};

// The whole page. Throws ValueError when `physiology` is null or empty.
std::string report_html(const ReportInput& input);

// Writes report_html() to `path` atomically. Throws IoError.
void write_report(const std::filesystem::path& path, const ReportInput& input);

// `outputs: {report: true}` (on by default): report.html with the run's facts, its physiology at
// the output rate, the motion table and the glb (the bytes breathing.glb has, made here too when
// the glTF output is off).
OutputPlugin report_output();

}  // namespace pneuma::outputs
