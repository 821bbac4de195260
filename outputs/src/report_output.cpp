// The report.html output: the run's facts, physiology, motion and glb gathered into ReportInput.
#include <fmt/format.h>

#include "pneuma/outputs/frame_outputs.h"
#include "pneuma/outputs/motion_csv.h"
#include "pneuma/outputs/phases.h"
#include "pneuma/outputs/report.h"
#include "pneuma/outputs/voxels_output.h"

namespace pneuma::outputs {
namespace {

// What report.html shows: the physiology.csv series, the motion table, the run's key facts and
// the glb (the bytes breathing.glb has, made here too when the glTF output is off).
ReportInput report_input(const model::Model& model, const RunRecord& run) {
  const scenario::Scenario& s = *run.scenario;
  const std::vector<double>& time_s = run.drive->series.time_s;
  ReportInput r;
  r.scenario_name = s.name;
  r.description = s.description;
  r.duration_s = time_s.empty() ? 0.0 : time_s.back();
  r.frame_rate_hz = s.frame_rate_hz;
  r.frame_count = time_s.size();
  r.physiology = run.physiology;
  std::string mesh = s.mesh.file.filename().string();
  if (!s.mesh.labels_file.empty()) mesh = s.mesh.labels_file.filename().string();
  if (s.mesh.phantom) mesh = *s.mesh.phantom == mesh::Lung::left ? "left lung phantom" : "right lung phantom";
  if (model.two_lungs()) {
    if (s.mesh.lungs[0].phantom) mesh = "lung phantoms";
    if (!s.mesh.lungs[0].file.empty())
      mesh = s.mesh.lungs[0].file.filename().string() + ", " + s.mesh.lungs[1].file.filename().string();
    mesh = "both lungs: " + mesh;
  }
  r.facts = {
      {"scenario", s.file.filename().string()},
      {"mesh", fmt::format("{}, {} vertices, {} triangles", mesh, model.vertex_count(), model.triangle_count())},
  };
  // Each lung's own facts: one lung's rows as they always were; two lungs' prefixed by side.
  auto lung_facts = [&](std::size_t i) {
    const model::LungModel& lung = model.lungs[i];
    const std::string side = model.two_lungs() ? std::string(scenario::lung_name(lung.side)) + " lung " : "";
    const double rest_volume = lung.volume_map.volume(0.0);
    std::vector<std::pair<std::string, std::string>> facts;
    if (model.two_lungs()) {
      facts.emplace_back(side + "mesh", fmt::format("{} vertices, {} triangles", lung.rest.vertex_count(),
                                                    lung.rest.triangle_count()));
    }
    facts.emplace_back(side + "rest volume, area",
                       fmt::format("{:.1f} mL, {:.1f} cm\u00b2", rest_volume * 1e6, lung.rest_area_m2 * 1e4));
    return facts;
  };
  auto lung_motion_facts = [&](std::size_t i) {
    const model::LungModel& lung = model.lungs[i];
    const std::string side = model.two_lungs() ? std::string(scenario::lung_name(lung.side)) + " lung " : "";
    const double rest_volume = lung.volume_map.volume(0.0);
    std::vector<std::pair<std::string, std::string>> facts;
    std::string share = fmt::format("{:g} %", (model.two_lungs() ? lung.share : s.mesh.share) * 100.0);
    if (lung.compartment >= 0) share += " of compartment " + s.mesh.lungs[i].compartment_name;
    facts.emplace_back(model.two_lungs() ? side + "share of each breath" : "mesh share of each breath", share);
    facts.emplace_back(
        side.empty() ? "mesh volume change" : side + "volume change",
        fmt::format("{:.1f} to {:.1f} mL", (lung.volume_map.volume(run.info.min_scale[i]) - rest_volume) * 1e6,
                    (lung.volume_map.volume(run.info.max_scale[i]) - rest_volume) * 1e6));
    return facts;
  };
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    for (auto& f : lung_facts(i)) r.facts.push_back(std::move(f));
  }
  r.facts.emplace_back("tissue", s.field.tissue_name);
  r.facts.emplace_back("frames",
                       fmt::format("{} at {:g} Hz, 0 to {:g} s", r.frame_count, s.frame_rate_hz, r.duration_s));
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    for (auto& f : lung_motion_facts(i)) r.facts.push_back(std::move(f));
  }
  r.facts.emplace_back("field", run.field_reused ? "reused from cache" : "computed");
  if (s.physiology.trace) {
    // What the measured trace was and what was done to it (physiology/trace.h).
    const physiology::Trace& trace = *s.physiology.trace;
    const physiology::TraceReport& t = trace.report;
    r.facts.emplace_back("breathing trace",
                         fmt::format("{} ({} '{}'), {} samples, {} invalid, {} gap{}", trace.file.filename().string(),
                                     physiology::signal_name(trace.signal), trace.column, t.samples, t.invalid_samples,
                                     t.gaps, t.gaps == 1 ? "" : "s"));
    if (trace.signal == physiology::TraceSignal::amplitude) {
      std::string how = fmt::format("{:.1f} mL per amplitude unit", t.scale_m3_per_unit * 1e6);
      if (t.calibration_span_s > 0.0)
        how +=
            fmt::format(" (from spirometry over {:.1f} s, r\u00b2 = {:.3f})", t.calibration_span_s, t.calibration_r2);
      r.facts.emplace_back("trace calibration", how);
    }
    if (t.drift_m3_per_s != 0.0)
      r.facts.emplace_back("trace drift removed", fmt::format("{:.1f} mL/min", t.drift_m3_per_s * 1e6 * 60.0));
  }
  const physiology::SimulationResult& physiology = *run.physiology;
  if (!physiology.breaths.empty()) {
    double tidal = 0.0, minute = 0.0;
    for (const auto& b : physiology.breaths) {
      tidal += b.tidal_volume_m3;
      minute += b.minute_ventilation_m3_per_s;
    }
    const double n = static_cast<double>(physiology.breaths.size());
    r.facts.emplace_back("breaths", std::to_string(physiology.breaths.size()));
    r.facts.emplace_back("tidal volume (mean)", fmt::format("{:.0f} mL", tidal / n * 1e6));
    r.facts.emplace_back("minute ventilation (mean)", fmt::format("{:.2f} L/min", minute / n * 1e3 * 60.0));
  }
  r.motion = *run.motion;
  r.lung_names = motion_lung_names(model);
  r.glb = make_glb(model, run.info, time_s, run.scales);
  // The respiratory bins, when the run sorts its frames into them or follows a measured trace.
  if (s.output(kPhasesKey) != nullptr || s.physiology.trace) {
    const physiology::PhaseBinning binning = run_phase_bins(run);
    ReportBins bins;
    bins.method = physiology::binning_method_name(binning.method);
    for (const physiology::PhaseBin& bin : binning.bins) {
      bins.centre_percent.push_back(bin.centre_percent);
      bins.frames.push_back(bin.samples.size());
      bins.mean_volume_m3.push_back(bin.mean_volume_m3);
    }
    bins.bin_of_frame = binning.bin_of;
    r.bins = std::move(bins);
  }
  r.slices = report_label_slices(model, run, r.lung_labels);
  if (const VoxelFigures* figures = run.shared.find<VoxelFigures>()) r.voxel_points = figures->points;
  if (const VoxelStructures* structures = run.shared.find<VoxelStructures>()) r.structures = structures->facts;
  if (const VoxelTracks* tracks = run.shared.find<VoxelTracks>()) {
    r.track_times_s = tracks->times_s;
    r.tracks = tracks->points;
  }
  return r;
}

class ReportOutput final : public Output {
 public:
  explicit ReportOutput(std::filesystem::path file) : file_(std::move(file)) {}
  std::string name() const override { return "report"; }
  std::vector<std::filesystem::path> finish(const model::Model& model, const RunRecord& run) override {
    write_report(file_, report_input(model, run));
    return {file_};
  }

 private:
  std::filesystem::path file_;
};

}  // namespace

OutputPlugin report_output() {
  return {{"report", true, no_settings},
          {.physiology = true, .breath_motion = true},
          [](const std::any&, const std::filesystem::path& out) {
            return std::make_unique<ReportOutput>(out / "report.html");
          }};
}

}  // namespace pneuma::outputs
