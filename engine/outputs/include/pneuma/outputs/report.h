#pragma once
// report.html: one self-contained page per run (docs/formats.md): the lung breathing (the
// run's glb, three.js, orbit, play/pause/scrub) in step with the physiology plots (volume, flow,
// pressures) and the per-region motion table, under one time cursor. It opens from the file
// system without a server or the internet: three.js (Debian's libjs-three, r111, found at
// configure time), the page's script, the data and the glb (base64) are all inside the file.
#include <cstddef>
#include <filesystem>
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
