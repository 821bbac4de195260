#include "pneuma/physiology/mechanics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include "pneuma/core/error.h"

namespace pneuma::physiology {
namespace {

// Within this share of the range from either asymptote the curve continues as its tangent.
// A real trajectory never gets there (it takes ~20 widths of pressure), but the integrator's
// predictor may step past an asymptote; a C1 extension keeps the right-hand side defined.
constexpr double kAsymptoteMargin = 1e-9;

// Venegas' curve solved for pressure: P(V) = c - d * ln(b / (V - a) - 1), and its slope
// dP/dV = b d / (x (b - x)) with x = V - a.
double sigmoid_pressure(const SigmoidCompliance& s, double absolute_volume_m3) {
  const double b = s.volume_range_m3;
  const double x = absolute_volume_m3 - s.lower_volume_m3;
  const double lo = kAsymptoteMargin * b, hi = (1.0 - kAsymptoteMargin) * b;
  const double clamped = std::clamp(x, lo, hi);
  const double p = s.inflection_pressure_pa - s.width_pa * std::log(b / clamped - 1.0);
  if (clamped == x) return p;
  return p + (x - clamped) * b * s.width_pa / (clamped * (b - clamped));
}

struct PressureOf {
  double volume;
  double operator()(const LinearCompliance& c) const { return volume / c.compliance_m3_per_pa; }
  double operator()(const SigmoidCompliance& s) const {
    return sigmoid_pressure(s, s.relaxed_volume_m3 + volume) - sigmoid_pressure(s, s.relaxed_volume_m3);
  }
};

struct ComplianceOf {
  double volume;
  double operator()(const LinearCompliance& c) const { return c.compliance_m3_per_pa; }
  double operator()(const SigmoidCompliance& s) const {
    // dV/dP = (V - a)(a + b - V) / (b d), constant beyond the asymptote margins.
    const double x = std::clamp(s.relaxed_volume_m3 + volume - s.lower_volume_m3, kAsymptoteMargin * s.volume_range_m3,
                                (1.0 - kAsymptoteMargin) * s.volume_range_m3);
    return x * (s.volume_range_m3 - x) / (s.volume_range_m3 * s.width_pa);
  }
};

// One compartment's flow out: through the expiratory resistance, capped by the Starling resistor.
// `capped` tells which bound holds.
double expiratory_flow(const Mechanics& m, double pd, double pel, bool* capped = nullptr) {
  const double raw = m.expiratory_airway_resistance_pa_s_per_m3 > 0.0 ? m.expiratory_airway_resistance_pa_s_per_m3
                                                                      : m.airway_resistance_pa_s_per_m3;
  const double free_flow = (pd - pel) / (raw + m.compartments[0].resistance_pa_s_per_m3);
  const double cap = m.flow_limited() ? -std::max(pel - m.critical_pressure_pa, 0.0) / m.upstream_resistance_pa_s_per_m3
                                      : -std::numeric_limits<double>::infinity();
  if (capped) *capped = cap > free_flow;
  return std::max(free_flow, cap);
}

}  // namespace

double elastic_pressure(const Elasticity& elasticity, double volume_m3) {
  return std::visit(PressureOf{volume_m3}, elasticity);
}

double volume_at_pressure(const Elasticity& elasticity, double pressure_pa) {
  if (const auto* lin = std::get_if<LinearCompliance>(&elasticity)) return lin->compliance_m3_per_pa * pressure_pa;
  const auto& s = std::get<SigmoidCompliance>(elasticity);
  const double p = sigmoid_pressure(s, s.relaxed_volume_m3) + pressure_pa;
  return s.lower_volume_m3 + s.volume_range_m3 / (1.0 + std::exp(-(p - s.inflection_pressure_pa) / s.width_pa)) -
         s.relaxed_volume_m3;
}

double compliance_at(const Elasticity& elasticity, double volume_m3) {
  return std::visit(ComplianceOf{volume_m3}, elasticity);
}

void validate(const Mechanics& m) {
  if (m.compartments.empty()) throw ValueError("at least one compartment is needed");
  if (!(m.airway_resistance_pa_s_per_m3 >= 0.0)) throw ValueError("airway resistance must be >= 0");
  if (!(m.chest_wall_fraction >= 0.0 && m.chest_wall_fraction <= 1.0))
    throw ValueError("chest wall fraction must lie in [0, 1]");
  if (!(m.expiratory_airway_resistance_pa_s_per_m3 >= 0.0) || !(m.upstream_resistance_pa_s_per_m3 >= 0.0) ||
      !std::isfinite(m.critical_pressure_pa))
    throw ValueError("expiratory and upstream resistances must be >= 0, the critical pressure finite");
  if (m.expiration_differs() && m.compartments.size() != 1)
    throw ValueError("an expiratory resistance or flow limitation needs the single model");
  for (const Compartment& c : m.compartments) {
    if (m.compartments.size() > 1 && !(c.resistance_pa_s_per_m3 > 0.0))
      throw ValueError("compartment '" + c.name + "': a parallel compartment needs a positive resistance");
    if (m.compartments.size() == 1 && !(c.resistance_pa_s_per_m3 + m.airway_resistance_pa_s_per_m3 > 0.0))
      throw ValueError("the total resistance must be positive");
    if (const auto* lin = std::get_if<LinearCompliance>(&c.elasticity)) {
      if (!(lin->compliance_m3_per_pa > 0.0))
        throw ValueError("compartment '" + c.name + "': compliance must be positive");
    } else {
      const auto& s = std::get<SigmoidCompliance>(c.elasticity);
      if (!(s.volume_range_m3 > 0.0) || !(s.width_pa > 0.0))
        throw ValueError("compartment '" + c.name + "': sigmoid range and width must be positive");
      if (!(s.relaxed_volume_m3 > s.lower_volume_m3 && s.relaxed_volume_m3 < s.lower_volume_m3 + s.volume_range_m3))
        throw ValueError("compartment '" + c.name +
                         "': the relaxed volume must lie between the sigmoid's lower volume and TLC");
    }
  }
}

double compartment_flows(const Mechanics& m, double pd, const double* v, double* q) {
  const std::size_t n = m.compartments.size();
  if (n == 1) {
    const double r = m.airway_resistance_pa_s_per_m3 + m.compartments[0].resistance_pa_s_per_m3;
    const double pel = elastic_pressure(m.compartments[0].elasticity, v[0]);
    q[0] = (pd - pel) / r;
    if (q[0] < 0.0 && m.expiration_differs()) q[0] = expiratory_flow(m, pd, pel);
    return q[0];
  }
  // Q_i = (Pd - Pel_i - Raw Q) / R_i and Q = sum Q_i  =>  Q = sum((Pd - Pel_i)/R_i) / (1 + Raw G).
  double g = 0.0, weighted = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double gi = 1.0 / m.compartments[i].resistance_pa_s_per_m3;
    g += gi;
    weighted += gi * (pd - elastic_pressure(m.compartments[i].elasticity, v[i]));
  }
  const double total = weighted / (1.0 + m.airway_resistance_pa_s_per_m3 * g);
  for (std::size_t i = 0; i < n; ++i) {
    q[i] = (pd - elastic_pressure(m.compartments[i].elasticity, v[i]) - m.airway_resistance_pa_s_per_m3 * total) /
           m.compartments[i].resistance_pa_s_per_m3;
  }
  return total;
}

double flow_rate_of_change(const Mechanics& m, double dpd_dt, const double* v, const double* q) {
  // Q = sum g_i (Pd - Pel_i) / (1 + Raw G)  =>  dQ/dt = sum g_i (dPd/dt - Pel_i'(V_i) Q_i) / (1 + Raw G);
  // one compartment: Q = (Pd - Pel) / (Raw + R_1).
  const std::size_t n = m.compartments.size();
  if (n == 1) {
    const double r = m.airway_resistance_pa_s_per_m3 + m.compartments[0].resistance_pa_s_per_m3;
    const double elastic_rate = q[0] / compliance_at(m.compartments[0].elasticity, v[0]);  // dPel/dt
    if (q[0] < 0.0 && m.expiration_differs()) {
      bool capped = false;
      const double pel = elastic_pressure(m.compartments[0].elasticity, v[0]);
      const double pd = pel + q[0] * r;  // any Pd that gives this flow out picks the same branch
      expiratory_flow(m, pd, pel, &capped);
      if (capped) return -elastic_rate / m.upstream_resistance_pa_s_per_m3;
      const double raw = m.expiratory_airway_resistance_pa_s_per_m3 > 0.0 ? m.expiratory_airway_resistance_pa_s_per_m3
                                                                          : m.airway_resistance_pa_s_per_m3;
      return (dpd_dt - elastic_rate) / (raw + m.compartments[0].resistance_pa_s_per_m3);
    }
    return (dpd_dt - elastic_rate) / r;
  }
  double g = 0.0, weighted = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double gi = 1.0 / m.compartments[i].resistance_pa_s_per_m3;
    g += gi;
    weighted += gi * (dpd_dt - q[i] / compliance_at(m.compartments[i].elasticity, v[i]));
  }
  return weighted / (1.0 + m.airway_resistance_pa_s_per_m3 * g);
}

double driving_pressure_for_flow(const Mechanics& m, double total_flow, const double* v) {
  const std::size_t n = m.compartments.size();
  if (n == 1) {
    // A prescribed flow out (never asked of the modes) goes through the expiratory resistance.
    const double raw = total_flow < 0.0 && m.expiratory_airway_resistance_pa_s_per_m3 > 0.0
                           ? m.expiratory_airway_resistance_pa_s_per_m3
                           : m.airway_resistance_pa_s_per_m3;
    return elastic_pressure(m.compartments[0].elasticity, v[0]) +
           (raw + m.compartments[0].resistance_pa_s_per_m3) * total_flow;
  }
  double g = 0.0, weighted = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double gi = 1.0 / m.compartments[i].resistance_pa_s_per_m3;
    g += gi;
    weighted += gi * elastic_pressure(m.compartments[i].elasticity, v[i]);
  }
  return (total_flow * (1.0 + m.airway_resistance_pa_s_per_m3 * g) + weighted) / g;
}

double alveolar_pressure(const Mechanics& m, double airway_pressure_pa, double total_flow) {
  double r = total_flow < 0.0 && m.expiratory_airway_resistance_pa_s_per_m3 > 0.0
                 ? m.expiratory_airway_resistance_pa_s_per_m3
                 : m.airway_resistance_pa_s_per_m3;
  if (m.compartments.size() == 1) r += m.compartments[0].resistance_pa_s_per_m3;
  return airway_pressure_pa - r * total_flow;
}

}  // namespace pneuma::physiology
