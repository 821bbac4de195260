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

}  // namespace pneuma::test
