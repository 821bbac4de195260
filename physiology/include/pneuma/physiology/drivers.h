#pragma once
// What drives a breath: the patient's breathing muscles or a mechanical ventilator.
//
// A breath is a short sequence of phases within which the drive is smooth. Phase switches are
// discontinuities (a valve opens, the flow steps), so the integrator stops and restarts at
// every phase boundary instead of integrating across it.
#include <array>
#include <variant>
#include "pneuma/core/error.h"

namespace pneuma::physiology {

// Spontaneous breathing. The muscle pressure rises as a half cosine over the inspiratory time,
// relaxes as a half cosine over the first half of expiration and rests for the second half
// (a smooth version of the profile of Mecklenburgh & Mapleson, and of Albanese et al. 2016).
struct Spontaneous {
  double rate_hz = 0.2;
  double ie_ratio = 0.5;                // Ti / Te
  double amplitude_pa = 0.0;            // peak muscle pressure
  double target_tidal_volume_m3 = 0.0;  // > 0: the simulator finds the amplitude that gives it
  bool operator==(const Spontaneous&) const = default;
};

// Volume control: constant inspiratory flow delivering the set tidal volume, an optional
// end-inspiratory pause, then passive expiration to PEEP.
struct VolumeControl {
  double rate_hz = 0.2;
  double tidal_volume_m3 = 0.0;
  double inspiratory_time_s = 1.0;  // flow time + pause time
  double pause_time_s = 0.0;
  double peep_pa = 0.0;
  bool operator==(const VolumeControl&) const = default;
};

// Pressure control: airway pressure PEEP + set pressure during inspiration (a square wave).
struct PressureControl {
  double rate_hz = 0.2;
  double inspiratory_pressure_pa = 0.0;  // above PEEP
  double inspiratory_time_s = 1.0;
  double peep_pa = 0.0;
  bool operator==(const PressureControl&) const = default;
};

// Assisted ventilation: every breath starts on a patient trigger, or on the backup timer when
// none comes within 60 / rate of the last breath's start (VC-AC, PC-AC); CPAP with pressure
// support has no backup: each breath is the patient's. During expiration the ventilator holds
// PEEP and watches the patient:
// - flow trigger: a bias flow keeps the airway at PEEP; the breath starts when the flow into
//   the patient rises through the threshold;
// - pressure trigger: the circuit is closed to inspiration (the expiratory valve only lets gas
//   out), so once the patient pulls, the airway is occluded (no flow, Paw = recoil - Pmus);
//   the breath starts when Paw falls the threshold below PEEP; Paw back above PEEP reopens
//   the expiratory valve.
// A trigger is armed by a crossing: a flow already above the threshold when expiration begins
// does not trigger until it has fallen below it and risen again.
//
// SIMV (synchronised intermittent mandatory ventilation) mixes both kinds of breath: mandatory
// breaths (volume or pressure controlled, time cycled) at the set rate, and the patient's own
// breaths in between, pressure supported by `support_pa` (0: at PEEP, unsupported). The clock
// schedules a mandatory breath every 60 / rate from the mode's start (the first at once); a
// trigger window of `trigger_window_s` ends at each scheduled time, and the first patient trigger
// inside it gets the mandatory breath early (synchronised), after which the next one is due a
// period after the scheduled time. No trigger in the window: the machine starts the breath at
// the scheduled time. Every other trigger starts a spontaneous, supported breath.
// prvc: pressure-regulated volume control (PRVC, VC+): a PC-AC breath whose inspiratory pressure
// the machine adjusts breath by breath toward a target tidal volume (see Assisted::prvc_step_pa).
// aprv: airway pressure release ventilation (APRV, BiLevel): the airway held at P_high
// (PEEP + inspiratory_pressure_pa) for T_high (inspiratory_time_s), released to P_low (peep_pa)
// for T_low (60 / rate - T_high), on the clock; the patient breathes at either level through the
// demand valve (the pressure stays set whatever the effort), so no trigger starts anything.
// pav: proportional assist ventilation: a patient-triggered breath during which the machine adds
// Paw - PEEP = gain (R_set Q + E_set dV) (Q the patient's flow, dV the volume since the trigger),
// a share of the pressure the patient's own effort needs against the set (known) R and E.
enum class AssistMode { volume, pressure, pressure_support, simv_volume, simv_pressure, prvc, aprv, pav };
enum class TriggerKind { flow, pressure };
enum class CycleKind { time, flow, volume };
enum class FlowWaveform { square, decelerating };  // decelerating: linear ramp from peak to 0

struct Assisted {
  AssistMode mode = AssistMode::volume;
  double rate_hz = 0.2;             // backup rate; 0 for pressure support (no backup)
  double peep_pa = 0.0;             // PEEP, or the CPAP level
  double inspiratory_time_s = 1.0;  // time cycle; the longest inspiration when cycled on flow or volume
  // Volume mode.
  double tidal_volume_m3 = 0.0;
  double pause_time_s = 0.0;  // end-inspiratory pause within inspiratory_time_s
  FlowWaveform waveform = FlowWaveform::square;
  double pressure_limit_pa = 0.0;  // absolute airway pressure that ends inspiration; 0: none
  // Pressure modes.
  double inspiratory_pressure_pa = 0.0;  // above PEEP (the support pressure in pressure support)
  double rise_time_s = 0.0;              // Paw = PEEP + P (1 - exp(-3 t / rise)): 95 % of P at the rise time; 0: a step
  CycleKind cycle = CycleKind::time;
  double cycle_fraction = 0.25;      // flow cycle: end inspiration when flow falls to this share of its peak
  double cycle_flow_m3_per_s = 0.0;  // flow cycle at an absolute flow instead (cycle_fraction 0): Pulse's, Drager's
  double cycle_volume_m3 = 0.0;      // volume cycle: end inspiration when this volume is delivered
  double volume_limit_m3 = 0.0;      // delivered volume that ends inspiration; 0: none
  // Trigger.
  TriggerKind trigger = TriggerKind::flow;
  double trigger_threshold = 0.0;  // m^3/s into the patient (flow) or Pa below PEEP (pressure)
  // SIMV: the spontaneous breaths are cycled by `cycle` (flow at 25 % by default), at most
  // kLongestSupportedInspiration_s; the mandatory ones on time.
  double support_pa = 0.0;        // pressure support of the spontaneous breaths, above PEEP (also BiLevel's)
  double trigger_window_s = 0.0;  // the window before each scheduled mandatory breath, (0, 60 / rate]
  // PRVC: `tidal_volume_m3` is the target, `inspiratory_pressure_pa` the first (test) breath's
  // pressure. After each breath the pressure moves by dP (VT_target / VTi - 1) (the compliance
  // the breath measured), bounded to +-prvc_step_pa, within [0, pressure_limit_pa - PEEP].
  double prvc_step_pa = 0.0;
  // PAV: the assist's gain (0 < gain < 1) and the patient's resistance and elastance it assumes.
  // Cycled by `cycle` (flow at 25 % by default), at most inspiratory_time_s; no backup rate.
  double pav_gain = 0.0;
  double pav_resistance_pa_s_per_m3 = 0.0;
  double pav_elastance_pa_per_m3 = 0.0;
  // Apnea backup (cpap_psv): no breath within apnea_time_s of the last breath's start (or of the
  // mode's start) starts PC-AC breaths on the backup settings until the patient triggers.
  double apnea_time_s = 0.0;  // 0: no apnea backup
  double backup_rate_hz = 0.0;
  double backup_pressure_pa = 0.0;  // above PEEP
  double backup_inspiratory_time_s = 0.0;
  bool operator==(const Assisted&) const = default;
};

// The backup ventilation of a cpap_psv driver during apnea: PC-AC, time cycled, same PEEP,
// trigger and rise time.
Assisted apnea_backup(const Assisted& a);

// The ventilator circuit between the machine and the patient's airway (the Y-piece):
// ventilator --Rt-- [Y-piece: tubing compliance Ct, leaks to the atmosphere] -- patient.
// The patient sees the Y-piece pressure Py; the machine sets its own pressure or flow, and
// measures the flow it delivers Qv = Qpatient + Qleak + Ct dPy/dt (VTi, VTe, leak %, triggers
// and cycles on flow).
enum class LeakLaw { orifice, linear };
struct Leak {
  LeakLaw law = LeakLaw::orifice;
  double coefficient = 0.0;  // orifice: Q = k sqrt(P), m^3/s/Pa^0.5; linear: Q = k P, m^3/s/Pa; 0: none
  bool operator==(const Leak&) const = default;
};
struct Circuit {
  double tubing_compliance_m3_per_pa = 0.0;
  double tubing_resistance_pa_s_per_m3 = 0.0;  // needed with a tubing compliance (it fills through it)
  Leak port;                                   // the circuit's fixed leak (an exhalation port, a vented mask)
  Leak patient;                                // the mask's or the tube's (ETT cuff) leak
  bool active() const {
    return tubing_compliance_m3_per_pa > 0.0 || tubing_resistance_pa_s_per_m3 > 0.0 || port.coefficient > 0.0 ||
           patient.coefficient > 0.0;
  }
  bool operator==(const Circuit&) const = default;
};
// Flow out through a leak at a pressure P above the atmosphere (into the circuit below it).
double leak_flow(const Leak& leak, double pressure_pa);
// The leak's coefficient that lets `flow` out at `pressure`.
double leak_coefficient(LeakLaw law, double flow_m3_per_s, double pressure_pa);

// The ventilator's alarm limits (0: off), checked on each completed ventilator breath.
struct Alarms {
  double high_pressure_pa = 0.0;             // peak airway pressure above
  double low_pressure_pa = 0.0;              // peak airway pressure below
  double low_tidal_volume_m3 = 0.0;          // VTe below
  double low_minute_volume_m3_per_s = 0.0;   // expired volume over the last minute below
  double disconnection_leak_fraction = 0.0;  // (VTi - VTe) / VTi at or above: the circuit is open
  bool operator==(const Alarms&) const = default;
};

// The longest inspiration of a pressure-supported breath in SIMV (cpap_psv sets its own).
constexpr double kLongestSupportedInspiration_s = 3.0;

bool is_simv(const Assisted& a);
// BiLevel: APRV whose patient breaths at P_low are pressure supported (support_pa > 0). Scheduled
// as SIMV with no trigger window: the high phases on the clock, every trigger at P_low a
// supported breath (cycled by `cycle`, at most kLongestSupportedInspiration_s).
bool is_bilevel(const Assisted& a);
// SIMV's default trigger window: 60 % of the cycle, at most 10 s.
double default_trigger_window_s(double rate_hz);
// The breath an assisted driver gives: for AC modes and CPAP, the driver itself; for SIMV and
// BiLevel, the mandatory breath (a VC-AC or PC-AC breath cycled on time) or the spontaneous one
// (a pressure-support breath with the driver's support, cycle and rise time).
Assisted simv_breath(const Assisted& a, bool mandatory);

// The patient's own breathing effort on a ventilated patient: the spontaneous driver's muscle
// pressure profile (half-cosine rise over Ti, relaxation over `release_share` of Te (half, as the
// spontaneous driver, by default), rest), repeating at its own rate from `anchor` (the time it
// was set), whatever the ventilator does.
struct PatientEffort {
  double rate_hz = 0.0;
  double ie_ratio = 0.5;
  double amplitude_pa = 0.0;   // 0: a passive patient
  double release_share = 0.5;  // the relaxation's length, a share of the expiration, in (0, 1]
  bool active() const { return amplitude_pa > 0.0; }
  bool operator==(const PatientEffort&) const = default;
};

// Muscle pressure of an effort `t_s` seconds after its anchor, and its time derivative.
double effort_pressure(const PatientEffort& effort, double t_s);
double effort_pressure_rate(const PatientEffort& effort, double t_s);
// The first boundary of the effort's profile (onset, end of rise, end of relaxation) strictly
// after `t_s` (both relative to the anchor); infinity for a passive patient.
double next_effort_boundary(const PatientEffort& effort, double t_s);

using Driver = std::variant<Spontaneous, VolumeControl, PressureControl, Assisted>;

struct Phase {
  double end_s = 0.0;  // offset from the breath's start
  bool inspiratory = false;
};

struct BreathPlan {
  std::array<Phase, 3> phases{};
  int count = 0;
  double period_s() const { return phases[static_cast<std::size_t>(count - 1)].end_s; }
};

// What the driver imposes at one instant.
struct Drive {
  bool flow_controlled = false;                // true: total flow is set, airway pressure follows
  double flow_m3_per_s = 0.0;                  // when flow_controlled
  double airway_pressure_pa = 0.0;             // when pressure controlled
  double airway_pressure_rate_pa_per_s = 0.0;  // its time derivative (pressure controlled)
  double muscle_pressure_pa = 0.0;
  double peep_pa = 0.0;
  // Proportional assist (PAV's inspiration): the airway pressure is PEEP + gain (R Q + E dV),
  // a function of the state the simulator solves for; airway_pressure_pa is PEEP until then.
  double assist_gain = 0.0;
  double assist_resistance_pa_s_per_m3 = 0.0;
  double assist_elastance_pa_per_m3 = 0.0;
};

// The phases of an assisted breath (the `phase` of drive_at for an Assisted driver). Their ends
// are events found during the integration (trigger, cycle, limit), not a fixed plan.
enum AssistPhase : int { kAssistFlow = 0, kAssistPause, kAssistPressure, kAssistExpiration, kAssistOccluded };

BreathPlan plan_breath(const Driver& driver);
// The drive in `phase` at `t_in_breath` seconds after the breath's start.
Drive drive_at(const Driver& driver, int phase, double t_in_breath_s);
double peep_of(const Driver& driver);
bool is_ventilator(const Driver& driver);
const char* mode_name(const Driver& driver);

// Throws ValueError naming the first setting that cannot work.
void validate(const Driver& driver);
void validate(const Circuit& circuit);
void validate(const PatientEffort& effort);

}  // namespace pneuma::physiology
