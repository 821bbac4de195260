#include "pneuma/physiology/columns.h"

#include <array>
#include <cmath>

#include "pneuma/core/units.h"

namespace pneuma::physiology {
namespace {

constexpr double kMl = units::ml_per_m3;
constexpr double kLitre = units::litres_per_m3;
constexpr double kCmH2O = units::cmh2o_per_pa;

using Breath = BreathMetrics;
using Number = std::optional<double>;

// The ventilator's columns have values for ventilator breaths only (a patient trigger's delay
// only where it was measured).
Number if_ventilated(const Breath& b, double value) {
  if (*b.trigger == '\0' || std::isnan(value)) return std::nullopt;
  return value;
}

// Each value in its column's unit, converted as the CSV always has (the same operations in the
// same order, so the same digits).
constexpr std::array<BreathColumn, 36> kBreathColumns{{
    {"breath", "", CellFormat::whole, [](const Breath&, std::size_t i) -> Number { return static_cast<double>(i + 1); },
     nullptr},
    {"start_s", "s", CellFormat::fixed6, [](const Breath& b, std::size_t) -> Number { return b.start_s; }, nullptr},
    {"duration_s", "s", CellFormat::fixed6, [](const Breath& b, std::size_t) -> Number { return b.duration_s; },
     nullptr},
    {"mode", "", CellFormat::text, nullptr, [](const Breath& b) { return b.mode; }},
    {"tidal_volume_mL", "mL", CellFormat::significant9,
     [](const Breath& b, std::size_t) -> Number { return b.tidal_volume_m3 * kMl; }, nullptr},
    {"minute_ventilation_L_per_min", "L/min", CellFormat::significant9,
     [](const Breath& b, std::size_t) -> Number { return b.minute_ventilation_m3_per_s * kLitre * 60.0; }, nullptr},
    {"peak_pressure_cmH2O", "cmH2O", CellFormat::significant9,
     [](const Breath& b, std::size_t) -> Number { return b.peak_pressure_pa * kCmH2O; }, nullptr},
    {"plateau_pressure_cmH2O", "cmH2O", CellFormat::significant9,
     [](const Breath& b, std::size_t) -> Number { return b.plateau_pressure_pa * kCmH2O; }, nullptr},
    {"peep_cmH2O", "cmH2O", CellFormat::significant9,
     [](const Breath& b, std::size_t) -> Number { return b.peep_pa * kCmH2O; }, nullptr},
    {"dynamic_compliance_mL_per_cmH2O", "mL/cmH2O", CellFormat::significant9,
     [](const Breath& b, std::size_t) -> Number { return b.dynamic_compliance_m3_per_pa * kMl / kCmH2O; }, nullptr},
    {"end_expiratory_volume_mL", "mL", CellFormat::significant9,
     [](const Breath& b, std::size_t) -> Number { return b.end_expiratory_volume_m3 * kMl; }, nullptr},
    {"muscle_amplitude_cmH2O", "cmH2O", CellFormat::significant9,
     [](const Breath& b, std::size_t) -> Number { return b.muscle_amplitude_pa * kCmH2O; }, nullptr},
    {"inspired_volume_mL", "mL", CellFormat::significant9,
     [](const Breath& b, std::size_t) -> Number { return b.inspired_volume_m3 * kMl; }, nullptr},
    // 0: the driver sets none.
    {"set_tidal_volume_mL", "mL", CellFormat::significant9,
     [](const Breath& b, std::size_t) -> Number {
       if (!(b.set_tidal_volume_m3 > 0.0)) return std::nullopt;
       return b.set_tidal_volume_m3 * kMl;
     },
     nullptr},
    {"trigger", "", CellFormat::text, nullptr, [](const Breath& b) { return b.trigger; }},
    {"trigger_delay_s", "s", CellFormat::significant9,
     [](const Breath& b, std::size_t) { return if_ventilated(b, b.trigger_delay_s); }, nullptr},
    {"cycle", "", CellFormat::text, nullptr, [](const Breath& b) { return b.cycle; }},
    {"inspiratory_time_s", "s", CellFormat::significant9,
     [](const Breath& b, std::size_t) { return if_ventilated(b, b.inspiratory_time_s); }, nullptr},
    {"ie_ratio", "", CellFormat::significant9,
     [](const Breath& b, std::size_t) {
       return if_ventilated(b, b.inspiratory_time_s / (b.duration_s - b.inspiratory_time_s));
     },
     nullptr},
    {"mean_airway_pressure_cmH2O", "cmH2O", CellFormat::significant9,
     [](const Breath& b, std::size_t) -> Number { return b.mean_airway_pressure_pa * kCmH2O; }, nullptr},
    {"intrinsic_peep_cmH2O", "cmH2O", CellFormat::significant9,
     [](const Breath& b, std::size_t) { return if_ventilated(b, b.intrinsic_peep_pa * kCmH2O); }, nullptr},
    {"missed_triggers", "", CellFormat::whole,
     [](const Breath& b, std::size_t) -> Number { return static_cast<double>(b.missed_triggers); }, nullptr},
    {"double_trigger", "", CellFormat::whole,
     [](const Breath& b, std::size_t) -> Number { return b.double_triggered ? 1.0 : 0.0; }, nullptr},
    {"breath_type", "", CellFormat::text, nullptr, [](const Breath& b) { return b.breath_type; }},
    // The expiratory hold's columns: empty for breaths without one.
    {"expiratory_hold_s", "s", CellFormat::significant9,
     [](const Breath& b, std::size_t) -> Number {
       if (!(b.expiratory_hold_s > 0.0)) return std::nullopt;
       return b.expiratory_hold_s;
     },
     nullptr},
    {"total_peep_cmH2O", "cmH2O", CellFormat::significant9,
     [](const Breath& b, std::size_t) -> Number {
       if (!(b.expiratory_hold_s > 0.0)) return std::nullopt;
       return b.total_peep_pa * kCmH2O;
     },
     nullptr},
    // What the ventilator measures at its ports (the circuit's leaks and tubing included).
    {"vti_mL", "mL", CellFormat::significant9,
     [](const Breath& b, std::size_t) { return if_ventilated(b, b.vti_m3 * kMl); }, nullptr},
    {"vte_mL", "mL", CellFormat::significant9,
     [](const Breath& b, std::size_t) { return if_ventilated(b, b.vte_m3 * kMl); }, nullptr},
    {"leak_percent", "%", CellFormat::significant9,
     [](const Breath& b, std::size_t) -> Number {
       if (!(b.vti_m3 > 0.0)) return std::nullopt;
       return if_ventilated(b, (b.vti_m3 - b.vte_m3) / b.vti_m3 * 100.0);
     },
     nullptr},
    {"inspiratory_pressure_cmH2O", "cmH2O", CellFormat::significant9,
     [](const Breath& b, std::size_t) { return if_ventilated(b, b.set_inspiratory_pressure_pa * kCmH2O); }, nullptr},
    {"alarms", "", CellFormat::text, nullptr, [](const Breath& b) { return b.alarms.c_str(); }},
    // Cycling and flow asynchrony against the patient's effort: the delay and the dip empty without
    // one, the flags (counts, like double_trigger) 0.
    {"cycle_delay_s", "s", CellFormat::significant9,
     [](const Breath& b, std::size_t) -> Number {
       if (std::isnan(b.cycle_delay_s)) return std::nullopt;
       return b.cycle_delay_s;
     },
     nullptr},
    {"early_cycling", "", CellFormat::whole,
     [](const Breath& b, std::size_t) -> Number { return b.early_cycling ? 1.0 : 0.0; }, nullptr},
    {"late_cycling", "", CellFormat::whole,
     [](const Breath& b, std::size_t) -> Number { return b.late_cycling ? 1.0 : 0.0; }, nullptr},
    {"flow_starvation_cmH2O", "cmH2O", CellFormat::significant9,
     [](const Breath& b, std::size_t) -> Number {
       if (std::isnan(b.flow_starvation_pa)) return std::nullopt;
       return b.flow_starvation_pa * kCmH2O;
     },
     nullptr},
    {"flow_starvation", "", CellFormat::whole,
     [](const Breath& b, std::size_t) -> Number { return b.flow_starvation ? 1.0 : 0.0; }, nullptr},
}};

}  // namespace

double SeriesColumn::at(const TimeSeries& series, std::size_t sample) const {
  if (compartment >= 0) return series.compartment_volume_m3[static_cast<std::size_t>(compartment)][sample] * kMl;
  return value(series, sample);
}

std::vector<SeriesColumn> series_columns(const SimulationResult& result) {
  using S = TimeSeries;
  std::vector<SeriesColumn> columns{
      {"time_s", "s", CellFormat::fixed6, [](const S& s, std::size_t k) { return s.time_s[k]; }},
      {"volume_mL", "mL", CellFormat::significant9, [](const S& s, std::size_t k) { return s.volume_m3[k] * kMl; }},
      {"flow_L_per_s", "L/s", CellFormat::significant9,
       [](const S& s, std::size_t k) { return s.flow_m3_per_s[k] * kLitre; }},
      {"airway_pressure_cmH2O", "cmH2O", CellFormat::significant9,
       [](const S& s, std::size_t k) { return s.airway_pressure_pa[k] * kCmH2O; }},
      {"alveolar_pressure_cmH2O", "cmH2O", CellFormat::significant9,
       [](const S& s, std::size_t k) { return s.alveolar_pressure_pa[k] * kCmH2O; }},
      {"pleural_pressure_cmH2O", "cmH2O", CellFormat::significant9,
       [](const S& s, std::size_t k) { return s.pleural_pressure_pa[k] * kCmH2O; }},
      {"muscle_pressure_cmH2O", "cmH2O", CellFormat::significant9,
       [](const S& s, std::size_t k) { return s.muscle_pressure_pa[k] * kCmH2O; }},
  };
  // One compartment's volume is volume_mL itself.
  if (result.compartment_names.size() > 1) {
    for (std::size_t c = 0; c < result.compartment_names.size(); ++c) {
      columns.push_back({"volume_" + result.compartment_names[c] + "_mL", "mL", CellFormat::significant9, nullptr,
                         static_cast<int>(c)});
    }
  }
  return columns;
}

std::span<const BreathColumn> breath_columns() { return kBreathColumns; }

}  // namespace pneuma::physiology
