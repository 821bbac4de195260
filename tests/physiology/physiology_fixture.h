#pragma once
// Builders for small protocols in clinical units, so each test reads like its oracle.
#include "pneuma/physiology/simulate.h"

namespace pneuma::test {

constexpr double kCmH2O = 98.0665;  // Pa
constexpr double kLitre = 1e-3;     // m^3
constexpr double kLPerCmH2O = kLitre / kCmH2O;
constexpr double kCmH2OsPerL = kCmH2O / kLitre;

inline physiology::Mechanics single_linear(double compliance_l_per_cmh2o, double resistance_cmh2o_s_per_l) {
  physiology::Mechanics m;
  m.airway_resistance_pa_s_per_m3 = resistance_cmh2o_s_per_l * kCmH2OsPerL;
  m.compartments = {{"lung", physiology::LinearCompliance{compliance_l_per_cmh2o * kLPerCmH2O}, 0.0}};
  return m;
}

inline physiology::SimulationOptions tight(double duration_s, double output_rate_hz = 100.0) {
  physiology::SimulationOptions o;
  o.duration_s = duration_s;
  o.output_rate_hz = output_rate_hz;
  o.solver.relative_tolerance = 1e-11;
  o.solver.absolute_tolerance_m3 = 1e-15;
  return o;
}

inline physiology::Protocol just(const physiology::Mechanics& m, const physiology::Driver& d) {
  return physiology::Protocol{{physiology::Setting{0.0, m, d}}};
}

// An assisted ventilator in pressure (or pressure-support) `mode`: rate, inspiratory pressure
// above PEEP, inspiratory time and PEEP; flow trigger at 2 L/min.
inline physiology::Assisted pressure_mode(physiology::AssistMode mode, double rate_hz, double dp_pa, double ti_s,
                                          double peep_pa) {
  physiology::Assisted a;
  a.mode = mode;
  a.rate_hz = rate_hz;
  a.inspiratory_pressure_pa = dp_pa;
  a.inspiratory_time_s = ti_s;
  a.peep_pa = peep_pa;
  a.trigger_threshold = 2 * kLitre / 60;
  return a;
}

// Volume control: rate, tidal volume, inspiratory time, end-inspiratory pause and PEEP; flow
// trigger at 2 L/min.
inline physiology::Assisted vc_ac(double rate_hz, double vt_m3, double ti_s, double pause_s, double peep_pa) {
  physiology::Assisted a;
  a.mode = physiology::AssistMode::volume;
  a.rate_hz = rate_hz;
  a.tidal_volume_m3 = vt_m3;
  a.inspiratory_time_s = ti_s;
  a.pause_time_s = pause_s;
  a.peep_pa = peep_pa;
  a.trigger_threshold = 2 * kLitre / 60;
  return a;
}

}  // namespace pneuma::test
