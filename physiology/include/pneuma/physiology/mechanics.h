#pragma once
// Lumped respiratory mechanics: compartments with elastic recoil behind resistances.
//
// Equation of motion (pressures relative to atmosphere, SI inside):
//   Paw(t) + Pmus(t) = Pel(V) + R * dV/dt,   with Paw = PEEP + Pvent(t)
// V is the volume above the relaxed volume (the functional residual capacity at zero airway
// pressure), so Pel(0) = 0 and PEEP holds V_ee = Pel^-1(PEEP) at end expiration: raising
// PEEP raises the end-expiratory volume (recruitment on a sigmoid curve). Measured from V_ee
// this is the textbook form Pvent + Pmus = Pel + R dV/dt + PEEP.
// Compartments sit in parallel behind one shared airway resistance; each has its own elastic
// recoil and branch resistance. One compartment is the classic single model.
#include <string>
#include <variant>
#include <vector>
#include "pneuma/core/error.h"

namespace pneuma::physiology {

// Pel(V) = V / C.
struct LinearCompliance {
  double compliance_m3_per_pa = 0.0;
};

// Venegas, Harris & Simon (1998), J Appl Physiol 84:389: V(P) = a + b / (1 + exp(-(P - c) / d)),
// absolute volume against distending pressure. The volume saturates toward a + b (total lung
// capacity). Pel(V) = P(V_rest + V) - P(V_rest), so Pel(0) = 0 at the relaxed volume V_rest.
struct SigmoidCompliance {
  double lower_volume_m3 = 0.0;         // a: volume at very low pressure
  double volume_range_m3 = 0.0;         // b: a + b is the volume at very high pressure (TLC)
  double inflection_pressure_pa = 0.0;  // c: pressure of steepest slope
  double width_pa = 0.0;                // d: pressure range of the steep part
  double relaxed_volume_m3 = 0.0;       // V_rest: absolute volume where Pel = 0 (FRC), in (a, a + b)
};

using Elasticity = std::variant<LinearCompliance, SigmoidCompliance>;

struct Compartment {
  std::string name;  // "lung", "upper", "lower": used for output column names
  Elasticity elasticity;
  double resistance_pa_s_per_m3 = 0.0;  // branch resistance, in series behind the airway
};

struct Mechanics {
  double airway_resistance_pa_s_per_m3 = 0.0;  // shared by all compartments
  std::vector<Compartment> compartments;       // one or more, in parallel
  // For the pleural pressure estimate: Ppl = -Ptp_rest + f * Pel - Pmus, where f is the
  // chest wall's share of the respiratory system's elastic recoil (the rest is the lung's).
  double transpulmonary_pressure_at_rest_pa = 490.3325;  // 5 cmH2O
  double chest_wall_fraction = 0.5;
  // One compartment only: the airway resistance while the flow is out (0: the same as in), and
  // expiratory flow limitation, a Starling resistor: the airway collapses at its choke point when
  // the pressure downstream falls below the critical pressure, so the expiratory flow is at most
  // (Pel - Pcrit) / Rs (Rs: the resistance upstream of the choke point; 0: no limitation), and
  // none once the recoil is below Pcrit. An airway pressure below Pcrit then no longer changes
  // the flow out (the waterfall), which is why external PEEP below Pcrit does not add to it.
  double expiratory_airway_resistance_pa_s_per_m3 = 0.0;
  double critical_pressure_pa = 0.0;
  double upstream_resistance_pa_s_per_m3 = 0.0;
  bool flow_limited() const { return upstream_resistance_pa_s_per_m3 > 0.0; }
  // Whether expiration differs from inspiration (its own resistance or a flow limitation).
  bool expiration_differs() const { return expiratory_airway_resistance_pa_s_per_m3 > 0.0 || flow_limited(); }
};

// Elastic recoil pressure at volume V above the relaxed volume (Pel(0) = 0). The sigmoid
// continues as its tangent within 1e-9 of its range from either asymptote (never reached by
// a real trajectory; it keeps the integrator's trial steps defined).
double elastic_pressure(const Elasticity& elasticity, double volume_m3);
// dV/dPel at volume V.
double compliance_at(const Elasticity& elasticity, double volume_m3);
// The volume V with Pel(V) = pressure (the inverse of elastic_pressure).
double volume_at_pressure(const Elasticity& elasticity, double pressure_pa);

// Throws ValueError naming the first parameter that is not physical.
void validate(const Mechanics& mechanics);

// Flows into each compartment for a driving pressure Pd = Paw + Pmus.
// `volumes` and `flows` have one entry per compartment. Returns the total flow.
double compartment_flows(const Mechanics& mechanics, double driving_pressure_pa, const double* volumes_m3,
                         double* flows_m3_per_s);

// d(total flow)/dt when the driving pressure changes at `driving_pressure_rate` (Pa/s), at the
// given volumes and compartment flows (those of compartment_flows).
double flow_rate_of_change(const Mechanics& mechanics, double driving_pressure_rate_pa_per_s, const double* volumes_m3,
                           const double* flows_m3_per_s);

// The driving pressure that produces a prescribed total flow (volume control).
double driving_pressure_for_flow(const Mechanics& mechanics, double total_flow_m3_per_s, const double* volumes_m3);

// Pressure at the branching point below the airway (the alveolar pressure of a single model).
// Not while a flow limitation caps the flow out (the drop is then not R Q): Pel - Pmus there.
double alveolar_pressure(const Mechanics& mechanics, double airway_pressure_pa, double total_flow_m3_per_s);

}  // namespace pneuma::physiology
