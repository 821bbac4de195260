#include "pneuma/outputs/physiology_csv.h"

#include <fmt/format.h>
#include <fmt/os.h>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/units.h"
#include "pneuma/outputs/ventilator_facts.h"

namespace pneuma::outputs {
namespace {

constexpr double kMl = 1.0 / units::m3_per_ml;
constexpr double kLitre = 1.0 / units::m3_per_litre;
constexpr double kCmH2O = 1.0 / units::pa_per_cmh2o;

}  // namespace

void write_time_series_csv(const std::filesystem::path& path, const physiology::SimulationResult& result) {
  const auto& s = result.series;
  const bool regional = result.compartment_names.size() > 1;
  write_stream_atomically(path, false, [&](std::ostream& out) {
    out << "time_s,volume_mL,flow_L_per_s,airway_pressure_cmH2O,alveolar_pressure_cmH2O,"
           "pleural_pressure_cmH2O,muscle_pressure_cmH2O";
    if (regional) {
      for (const auto& name : result.compartment_names) out << ",volume_" << name << "_mL";
    }
    out << '\n';
    std::string line;
    for (std::size_t k = 0; k < s.size(); ++k) {
      line =
          fmt::format("{:.6f},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g}", s.time_s[k], s.volume_m3[k] * kMl,
                      s.flow_m3_per_s[k] * kLitre, s.airway_pressure_pa[k] * kCmH2O, s.alveolar_pressure_pa[k] * kCmH2O,
                      s.pleural_pressure_pa[k] * kCmH2O, s.muscle_pressure_pa[k] * kCmH2O);
      if (regional) {
        for (const auto& column : s.compartment_volume_m3) line += fmt::format(",{:.9g}", column[k] * kMl);
      }
      line += '\n';
      out << line;
    }
  });
}

void write_breaths_csv(const std::filesystem::path& path, const physiology::SimulationResult& result) {
  write_stream_atomically(path, false, [&](std::ostream& out) {
    out << "breath,start_s,duration_s,mode,tidal_volume_mL,minute_ventilation_L_per_min,peak_pressure_cmH2O,"
           "plateau_pressure_cmH2O,peep_cmH2O,dynamic_compliance_mL_per_cmH2O,end_expiratory_volume_mL,"
           "muscle_amplitude_cmH2O,inspired_volume_mL,set_tidal_volume_mL,trigger,trigger_delay_s,cycle,"
           "inspiratory_time_s,ie_ratio,mean_airway_pressure_cmH2O,intrinsic_peep_cmH2O,missed_triggers,"
           "double_trigger,breath_type,expiratory_hold_s,total_peep_cmH2O\n";
    for (std::size_t i = 0; i < result.breaths.size(); ++i) {
      const auto& b = result.breaths[i];
      const std::string set = b.set_tidal_volume_m3 > 0.0 ? fmt::format("{:.9g}", b.set_tidal_volume_m3 * kMl) : "";
      out << fmt::format("{},{:.6f},{:.6f},{},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{}", i + 1,
                         b.start_s, b.duration_s, b.mode, b.tidal_volume_m3 * kMl,
                         b.minute_ventilation_m3_per_s * kLitre * 60.0, b.peak_pressure_pa * kCmH2O,
                         b.plateau_pressure_pa * kCmH2O, b.peep_pa * kCmH2O,
                         b.dynamic_compliance_m3_per_pa * kMl / kCmH2O, b.end_expiratory_volume_m3 * kMl,
                         b.muscle_amplitude_pa * kCmH2O, b.inspired_volume_m3 * kMl, set);
      // Ventilator columns, empty for spontaneous breaths (and the delay for machine triggers);
      // the trigger counts are 0 there.
      const bool ventilated = *b.trigger != '\0';
      const auto number = [&](double v) { return ventilated && v == v ? fmt::format("{:.9g}", v) : std::string(); };
      out << fmt::format(",{},{},{},{},{},{:.9g},{},{},{}", b.trigger, number(b.trigger_delay_s), b.cycle,
                         number(b.inspiratory_time_s),
                         number(b.inspiratory_time_s / (b.duration_s - b.inspiratory_time_s)),
                         b.mean_airway_pressure_pa * kCmH2O, number(b.intrinsic_peep_pa * kCmH2O), b.missed_triggers,
                         b.double_triggered ? 1 : 0);
      // The expiratory hold's columns, empty for breaths without one.
      const bool held = b.expiratory_hold_s > 0.0;
      out << fmt::format(",{},{},{}\n", b.breath_type, held ? fmt::format("{:.9g}", b.expiratory_hold_s) : "",
                         held ? fmt::format("{:.9g}", b.total_peep_pa * kCmH2O) : "");
    }
  });
}

namespace {

class PhysiologyCsv final : public Output {
 public:
  explicit PhysiologyCsv(std::filesystem::path dir) : dir_(std::move(dir)) {}
  std::string name() const override { return "physiology_csv"; }
  std::vector<std::filesystem::path> finish(const model::Model&, const RunRecord& run) override {
    write_time_series_csv(dir_ / "physiology.csv", *run.physiology);
    write_breaths_csv(dir_ / "physiology-breaths.csv", *run.physiology);
    // The ventilator's settings and a summary of the breaths the CSV lists, for the manifest.
    if (run.scenario) facts_ = ventilator_facts(run.scenario->physiology.protocol, *run.physiology);
    return {dir_ / "physiology.csv", dir_ / "physiology-breaths.csv"};
  }
  std::vector<std::pair<std::string, std::string>> facts() const override { return facts_; }

 private:
  std::filesystem::path dir_;
  std::vector<std::pair<std::string, std::string>> facts_;
};

}  // namespace

OutputPlugin physiology_csv_output() {
  return {{"physiology_csv", true, no_settings},
          {.physiology = true},
          [](const std::any&, const std::filesystem::path& out) { return std::make_unique<PhysiologyCsv>(out); }};
}

}  // namespace pneuma::outputs
