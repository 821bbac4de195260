#pragma once
// Integrates the lung model over time with SUNDIALS CVODE (BDF) and reports volumes, flows,
// pressures and per-breath metrics.
#include <limits>
#include <string>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/core/units.h"
#include "pneuma/physiology/drivers.h"
#include "pneuma/physiology/mechanics.h"

namespace pneuma::physiology {

// Mechanics take effect at start_time_s; the driver from the first breath that starts at or
// after it (a ventilator applies new settings at the next breath, not mid-breath).
// The patient's effort, like the mechanics, acts from start_time_s (it is the patient's, not a
// ventilator setting); its breaths repeat from the time it was last changed.
struct Setting {
  double start_time_s = 0.0;
  Mechanics mechanics;
  Driver driver;
  PatientEffort effort{};  // only with a ventilator driver
  Circuit circuit{};       // the ventilator's circuit and leaks (none: the machine at the airway)
  Alarms alarms{};         // the ventilator's alarm limits (none set: no alarm)
};

// Throws ValueError when the setting's driver cannot work with its mechanics or circuit (PAV: no
// circuit, and gain * assisted resistance below the patient's inspiratory resistance).
void validate(const Setting& setting);

// An expiratory hold (a manoeuvre, not a setting): at the first end of expiration at or after
// at_s (when the next breath would start), the ventilator closes both valves for duration_s and
// reads the airway pressure at the end: the total PEEP (set PEEP + intrinsic PEEP, once the
// compartments have shared their pressures). The breath's expiration lasts the hold longer and
// the next breath is a machine breath right after it (cpap_psv: the patient's next trigger).
struct ExpiratoryHold {
  double at_s = 0.0;
  double duration_s = 0.0;
};

// The whole timeline: settings[0] starts at 0, the rest in increasing start time; the holds in
// increasing time.
struct Protocol {
  std::vector<Setting> settings;
  std::vector<ExpiratoryHold> holds{};
};

struct SolverOptions {
  double relative_tolerance = 1e-8;
  double absolute_tolerance_m3 = 1e-12;
  double max_step_s = 0.0;  // 0: no limit
};

struct SimulationOptions {
  double duration_s = 60.0;
  double output_rate_hz = 100.0;  // 0: no time series (metrics only)
  SolverOptions solver;
};

// Time series, one entry per output sample (columns, so they stream straight to CSV/HDF5).
struct TimeSeries {
  std::vector<double> time_s;
  std::vector<double> volume_m3;  // above the relaxed volume (FRC at zero pressure), all compartments
  std::vector<double> flow_m3_per_s;
  std::vector<double> airway_pressure_pa;
  std::vector<double> alveolar_pressure_pa;
  std::vector<double> pleural_pressure_pa;
  std::vector<double> muscle_pressure_pa;
  std::vector<std::vector<double>> compartment_volume_m3;  // [compartment][sample]
  std::size_t size() const { return time_s.size(); }
};

struct BreathMetrics {
  double start_s = 0.0;
  double duration_s = 0.0;
  const char* mode = "";
  double tidal_volume_m3 = 0.0;              // the swing: max minus min volume over the breath
  double inspired_volume_m3 = 0.0;           // end of the inspiratory phase minus start volume
  double set_tidal_volume_m3 = 0.0;          // the driver's setting (spontaneous target, volume control); 0: none
  double minute_ventilation_m3_per_s = 0.0;  // tidal volume / breath duration
  double peak_pressure_pa = 0.0;             // highest airway pressure
  double plateau_pressure_pa = 0.0;          // alveolar pressure at the end of inspiration
  double peep_pa = 0.0;
  double dynamic_compliance_m3_per_pa = 0.0;  // VT / (max(Paw + Pmus) - PEEP)
  double end_expiratory_volume_m3 = 0.0;
  double muscle_amplitude_pa = 0.0;  // the spontaneous driver's amplitude in this breath
  // Ventilator breaths (empty or NaN for spontaneous ones).
  const char* trigger = "";  // what started the breath: "time", "patient_flow", "patient_pressure"
  double trigger_delay_s = std::numeric_limits<double>::quiet_NaN();  // effort onset to trigger (patient triggers)
  const char* cycle = "";  // what ended inspiration: "time", "flow", "volume", "pressure_limit", "volume_limit"
  double inspiratory_time_s = 0.0;       // inspiratory phases, pause included
  double mean_airway_pressure_pa = 0.0;  // airway pressure averaged over the breath
  double intrinsic_peep_pa = 0.0;  // end-expiratory hold pressure minus set PEEP: recoil of the end-expiratory volume
  int missed_triggers = 0;         // patient efforts starting in this breath that triggered nothing
  bool double_triggered = false;   // triggered by the same effort as the breath before
  const char* breath_type = "";    // "mandatory" (machine cycled) or "spontaneous" (pressure support); "" unventilated
  double expiratory_hold_s = 0.0;  // the hold made at the end of this breath's expiration; 0: none
  double total_peep_pa = std::numeric_limits<double>::quiet_NaN();  // airway pressure at the hold's end
  // What the ventilator measures at its own ports (ventilator breaths): the volume it delivered
  // during inspiration (VTi: into the patient, the leaks and the tubing) and the volume that came
  // back during expiration (VTe); without a circuit, the patient's inspired and expired volumes.
  double vti_m3 = std::numeric_limits<double>::quiet_NaN();
  double vte_m3 = std::numeric_limits<double>::quiet_NaN();
  double set_inspiratory_pressure_pa = std::numeric_limits<double>::quiet_NaN();  // pressure breaths: above PEEP
  std::string alarms;  // the alarms this breath raised, ';'-separated ("high_pressure;low_tidal_volume")
  // Cycling asynchrony against the patient's effort (ventilator breaths with an effort, not APRV):
  // the end of inspiration minus the end of the neural inspiration (the effort's rise) of the
  // effort in progress; NaN when no effort's neural inspiration overlaps the breath's inspiration.
  double cycle_delay_s = std::numeric_limits<double>::quiet_NaN();
  bool early_cycling = false;  // cycle_delay_s < 0: the machine stops while the patient still pulls
  bool late_cycling = false;   // cycle_delay_s > kLateCyclingShare of the neural inspiratory time
  // Flow starvation (flow-controlled inspirations with an effort): the largest drop of the airway
  // pressure below the passive lung's at the same instant and state (the effort removed); NaN
  // otherwise. Flagged above kFlowStarvation_pa.
  double flow_starvation_pa = std::numeric_limits<double>::quiet_NaN();
  bool flow_starvation = false;
};

// Late cycling: the machine's inspiration outlasts the neural one by more than this share of it.
constexpr double kLateCyclingShare = 0.2;
// Flow starvation: the airway pressure more than this below the passive lung's (2 cmH2O).
constexpr double kFlowStarvation_pa = 2.0 * units::pa_per_cmh2o;

struct SolverStats {
  long steps = 0;
  long rhs_evaluations = 0;
  long restarts = 0;  // one per phase boundary or action
};

struct SimulationResult {
  std::vector<std::string> compartment_names;
  TimeSeries series;
  std::vector<BreathMetrics> breaths;  // completed breaths only
  SolverStats stats;
};

// Throws ValueError for a protocol that cannot work (named setting), and
// pneuma::Error when CVODE fails or a target tidal volume cannot be reached.
SimulationResult simulate(const Protocol& protocol, const SimulationOptions& options);

}  // namespace pneuma::physiology
