// The report.html output: the run's facts, physiology, motion and glb gathered into ReportInput.
#include <fmt/format.h>

#include "pneuma/outputs/frame_outputs.h"
#include "pneuma/outputs/report.h"

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
  r.frame_count = run.scales.size();
  r.physiology = run.physiology;
  const double rest_volume = model.volume_map.volume(0.0);
  std::string mesh = s.mesh.file.filename().string();
  if (!s.mesh.labels_file.empty()) mesh = s.mesh.labels_file.filename().string();
  if (s.mesh.phantom) mesh = *s.mesh.phantom == mesh::Lung::left ? "left lung phantom" : "right lung phantom";
  r.facts = {
      {"scenario", s.file.filename().string()},
      {"mesh",
       fmt::format("{}, {} vertices, {} triangles", mesh, model.rest.vertex_count(), model.rest.triangle_count())},
      {"rest volume, area", fmt::format("{:.1f} mL, {:.1f} cm\u00b2", rest_volume * 1e6, model.rest_area_m2 * 1e4)},
      {"tissue", s.field.tissue_name},
      {"frames", fmt::format("{} at {:g} Hz, 0 to {:g} s", run.scales.size(), s.frame_rate_hz, r.duration_s)},
      {"mesh share of each breath", fmt::format("{:g} %", s.mesh.share * 100.0)},
      {"mesh volume change",
       fmt::format("{:.1f} to {:.1f} mL", (model.volume_map.volume(run.info.min_scale) - rest_volume) * 1e6,
                   (model.volume_map.volume(run.info.max_scale) - rest_volume) * 1e6)},
      {"field", run.field_reused ? "reused from cache" : "computed"},
  };
  if (s.physiology.trace) {
    // What the measured trace was and what was done to it (physiology/trace.h).
    const physiology::Trace& trace = *s.physiology.trace;
    const physiology::TraceReport& t = trace.report;
    r.facts.emplace_back("breathing trace",
                         fmt::format("{} ({} '{}'), {} samples, {} invalid, {} gap{}", trace.file.filename().string(),
                                     physiology::signal_name(trace.signal), trace.column, t.samples, t.invalid_samples,
                                     t.gaps, t.gaps == 1 ? "" : "s"));
    if (trace.signal == physiology::TraceSignal::amplitude)
      r.facts.emplace_back("trace calibration", fmt::format("{:.1f} mL per amplitude unit", t.scale_m3_per_unit * 1e6));
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
  r.glb = make_glb(model, run.info, time_s, run.scales);
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
