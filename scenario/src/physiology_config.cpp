#include "pneuma/scenario/physiology_config.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>
#include <system_error>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/core/paths.h"
#include "pneuma/core/text.h"

namespace pneuma::scenario {
namespace {

using physiology::Driver;
using physiology::Mechanics;
using scenario::Node;
namespace kind = units::kind;

const std::vector<std::string> kModes{"spontaneous", "volume_control", "pressure_control", "vc_ac", "pc_ac",
                                      "cpap_psv",    "vc_simv",        "pc_simv",          "prvc",  "aprv",
                                      "pav"};
// Accepted as `driver.mode` beside kModes, at t = 0 only (read_trace_driver).
const std::vector<std::string> kModesWithTrace{"spontaneous", "volume_control", "pressure_control", "vc_ac", "pc_ac",
                                               "cpap_psv",    "vc_simv",        "pc_simv",          "prvc",  "aprv",
                                               "pav",         "trace"};
const std::vector<std::string> kModels{"single", "two_compartment"};

// Every driver setting by name, so an action can patch any of them and a mode switch can
// carry over the ones the new mode shares (rate, PEEP, timing).
struct DriverFields {
  std::optional<double> rate, ie_ratio, inspiratory_time, tidal_volume, muscle_pressure, pause, peep,
      inspiratory_pressure;
  // Assist modes.
  std::optional<physiology::FlowWaveform> waveform;
  std::optional<double> rise_time, pressure_limit, volume_limit, pressure_support;
  std::optional<physiology::TriggerKind> trigger;
  std::optional<double> trigger_threshold;
  std::optional<physiology::CycleKind> cycle;
  std::optional<double> cycle_fraction, cycle_volume, cycle_flow;
  std::optional<double> trigger_window;                                                     // SIMV
  std::optional<double> pressure_step;                                                      // PRVC
  std::optional<double> apnea_time, backup_rate, backup_pressure, backup_inspiratory_time;  // cpap_psv
  std::optional<double> high_pressure, low_pressure, high_time, low_time;                   // APRV
  std::optional<double> gain, assisted_resistance, assisted_compliance;                     // PAV
};

bool is_simv(const std::string& mode) { return mode == "vc_simv" || mode == "pc_simv"; }
bool is_assist(const std::string& mode) {
  return mode == "vc_ac" || mode == "pc_ac" || mode == "cpap_psv" || mode == "prvc" || mode == "aprv" ||
         mode == "pav" || is_simv(mode);
}

DriverFields fields_of(const Driver& driver) {
  DriverFields f;
  std::visit(
      [&](const auto& d) {
        using T = std::decay_t<decltype(d)>;
        if (d.rate_hz > 0.0) f.rate = d.rate_hz;
        if constexpr (std::is_same_v<T, physiology::Assisted>) {
          f.inspiratory_time = d.inspiratory_time_s;
          f.peep = d.peep_pa;
          f.trigger = d.trigger;
          f.trigger_threshold = d.trigger_threshold;
          if (physiology::is_simv(d)) {
            f.pressure_support = d.support_pa;
            // A default window follows the rate; only a window that was set is carried.
            if (d.trigger_window_s != physiology::default_trigger_window_s(d.rate_hz))
              f.trigger_window = d.trigger_window_s;
          }
          if (d.mode == physiology::AssistMode::volume || d.mode == physiology::AssistMode::simv_volume) {
            f.tidal_volume = d.tidal_volume_m3;
            f.pause = d.pause_time_s;
            f.waveform = d.waveform;
            if (d.pressure_limit_pa > 0.0) f.pressure_limit = d.pressure_limit_pa;
          }
          if (d.mode == physiology::AssistMode::prvc) {
            f.tidal_volume = d.tidal_volume_m3;
            f.pressure_step = d.prvc_step_pa;
            if (d.pressure_limit_pa > 0.0) f.pressure_limit = d.pressure_limit_pa;
          }
          if (d.mode == physiology::AssistMode::aprv) {
            if (d.support_pa > 0.0) f.pressure_support = d.support_pa;
            f.high_pressure = d.peep_pa + d.inspiratory_pressure_pa;
            f.low_pressure = d.peep_pa;
            f.high_time = d.inspiratory_time_s;
            f.low_time = 1.0 / d.rate_hz - d.inspiratory_time_s;
          }
          if (d.mode == physiology::AssistMode::pav) {
            f.gain = d.pav_gain;
            f.assisted_resistance = d.pav_resistance_pa_s_per_m3;
            f.assisted_compliance = 1.0 / d.pav_elastance_pa_per_m3;
            if (d.pressure_limit_pa > 0.0) f.pressure_limit = d.pressure_limit_pa;
          }
          if (d.apnea_time_s > 0.0) {
            f.apnea_time = d.apnea_time_s;
            f.backup_rate = d.backup_rate_hz;
            f.backup_pressure = d.backup_pressure_pa;
            f.backup_inspiratory_time = d.backup_inspiratory_time_s;
          }
          if (d.mode != physiology::AssistMode::volume) {
            if (d.mode == physiology::AssistMode::pressure || d.mode == physiology::AssistMode::simv_pressure ||
                d.mode == physiology::AssistMode::prvc)
              f.inspiratory_pressure = d.inspiratory_pressure_pa;
            else if (d.mode == physiology::AssistMode::pressure_support) f.pressure_support = d.inspiratory_pressure_pa;
            f.rise_time = d.rise_time_s;
            f.cycle = d.cycle;
            f.cycle_fraction = d.cycle_fraction;
            if (d.cycle_flow_m3_per_s > 0.0) f.cycle_flow = d.cycle_flow_m3_per_s;
            if (d.cycle_volume_m3 > 0.0) f.cycle_volume = d.cycle_volume_m3;
            if (d.volume_limit_m3 > 0.0) f.volume_limit = d.volume_limit_m3;
          }
          // APRV without support cycles nothing: BiLevel's support added later takes its own default.
          if (d.mode == physiology::AssistMode::aprv && d.support_pa == 0.0) {
            f.cycle.reset();
            f.cycle_fraction.reset();
          }
        } else if constexpr (std::is_same_v<T, physiology::Spontaneous>) {
          f.ie_ratio = d.ie_ratio;
          if (d.target_tidal_volume_m3 > 0) f.tidal_volume = d.target_tidal_volume_m3;
          else f.muscle_pressure = d.amplitude_pa;
        } else {
          f.inspiratory_time = d.inspiratory_time_s;
          f.peep = d.peep_pa;
          if constexpr (std::is_same_v<T, physiology::VolumeControl>) {
            f.tidal_volume = d.tidal_volume_m3;
            f.pause = d.pause_time_s;
          } else {
            f.inspiratory_pressure = d.inspiratory_pressure_pa;
          }
        }
      },
      driver);
  return f;
}

// Which keys each mode takes ("ie_ratio" and "inspiratory_time" are alternatives). In SIMV the
// pressure-mode keys (rise time, cycle, volume limit) shape the supported breaths.
bool mode_takes(const std::string& mode, const std::string& key) {
  const bool aprv_key = key == "high_pressure" || key == "low_pressure" || key == "high_time" || key == "low_time";
  // Levels and times, no rate; BiLevel: pressure support of the breaths at P_low, their trigger and cycle.
  if (mode == "aprv")
    return aprv_key || key == "rise_time" || key == "pressure_support" || key == "trigger" || key == "cycle";
  if (aprv_key) return false;
  const bool pav_key = key == "gain" || key == "assisted_resistance" || key == "assisted_compliance";
  if (mode == "pav")
    return pav_key || key == "inspiratory_time" || key == "peep" || key == "trigger" || key == "cycle" ||
           key == "pressure_limit" || key == "volume_limit";
  if (pav_key) return false;
  if (key == "rate") return mode != "cpap_psv";
  if (mode == "spontaneous") return key == "ie_ratio" || key == "tidal_volume" || key == "muscle_pressure";
  if (key == "inspiratory_time" || key == "peep") return true;
  if (key == "ie_ratio") return mode != "cpap_psv";
  if (is_assist(mode) && key == "trigger") return true;
  const bool volume_key = key == "tidal_volume" || key == "pause" || key == "waveform" || key == "pressure_limit";
  const bool pressure_mode_key = key == "rise_time" || key == "cycle" || key == "volume_limit";
  const bool simv_key = key == "pressure_support" || key == "trigger_window" || pressure_mode_key;
  if (mode == "volume_control") return key == "tidal_volume" || key == "pause";
  if (mode == "vc_ac") return volume_key;
  if (mode == "vc_simv") return volume_key || simv_key;
  if (mode == "pc_simv") return key == "inspiratory_pressure" || simv_key;
  if (mode == "pressure_control") return key == "inspiratory_pressure";
  if (mode == "pc_ac") return key == "inspiratory_pressure" || pressure_mode_key;
  if (mode == "prvc")
    return key == "inspiratory_pressure" || key == "tidal_volume" || key == "pressure_step" ||
           key == "pressure_limit" || pressure_mode_key;
  if (key == "apnea") return mode == "cpap_psv";
  return key == "pressure_support" || pressure_mode_key;  // cpap_psv
}

const std::vector<std::string> kDriverKeys{"rate",
                                           "ie_ratio",
                                           "inspiratory_time",
                                           "tidal_volume",
                                           "muscle_pressure",
                                           "pause",
                                           "peep",
                                           "inspiratory_pressure",
                                           "waveform",
                                           "rise_time",
                                           "pressure_limit",
                                           "volume_limit",
                                           "pressure_support",
                                           "trigger",
                                           "cycle",
                                           "trigger_window",
                                           "pressure_step",
                                           "apnea",
                                           "high_pressure",
                                           "low_pressure",
                                           "high_time",
                                           "low_time",
                                           "gain",
                                           "assisted_resistance",
                                           "assisted_compliance"};

// trigger: {flow: 2 L/min} or {pressure: 2 cmH2O}, a positive threshold.
void read_trigger(const scenario::Node& n, DriverFields& f) {
  const scenario::Node t = n.map("trigger");
  const auto keys = t.keys();
  if (keys.size() != 1) t.fail("expected one of flow (e.g. '2 L/min') or pressure (e.g. '2 cmH2O')");
  if (keys[0] == "flow") {
    f.trigger = physiology::TriggerKind::flow;
    f.trigger_threshold = t.positive_quantity("flow", kind::flow);
  } else if (keys[0] == "pressure") {
    f.trigger = physiology::TriggerKind::pressure;
    f.trigger_threshold = t.positive_quantity("pressure", kind::pressure);
  } else {
    t.fail_at(keys[0], "unknown trigger; expected flow (e.g. '2 L/min') or pressure (e.g. '2 cmH2O')");
  }
}

// cycle: time, or {flow: 25 %} (a share of the peak inspiratory flow), or {volume: 500 mL}.
void read_cycle(const scenario::Node& n, DriverFields& f) {
  if (!n.is_map("cycle")) {
    n.choice("cycle", {"time"});
    f.cycle = physiology::CycleKind::time;
    return;
  }
  const scenario::Node c = n.map("cycle");
  const auto keys = c.keys();
  if (keys.size() != 1) c.fail("expected time, or one of flow (e.g. '25 %') or volume (e.g. '500 mL')");
  if (keys[0] == "flow" && c.string("flow").find('/') != std::string::npos) {
    // An absolute flow ('5 L/min'): the cycle when the flow falls to it, as Drager's and Pulse's.
    f.cycle = physiology::CycleKind::flow;
    f.cycle_fraction = 0.0;
    f.cycle_flow = c.positive_quantity("flow", kind::flow);
  } else if (keys[0] == "flow") {
    const double fraction = c.quantity("flow", kind::fraction);
    if (!(fraction > 0.0 && fraction < 1.0))
      c.fail_at("flow", "expected a share of the peak flow above 0 and below 100 %, got '" + c.string("flow") + "'");
    f.cycle = physiology::CycleKind::flow;
    f.cycle_fraction = fraction;
    f.cycle_flow.reset();
  } else if (keys[0] == "volume") {
    f.cycle = physiology::CycleKind::volume;
    f.cycle_volume = c.positive_quantity("volume", kind::volume);
  } else {
    c.fail_at(keys[0], "unknown cycle; expected time, flow (e.g. '25 %') or volume (e.g. '500 mL')");
  }
}

// The ranges the lung model and its solver take (docs/scenarios.md, limits): far outside them
// CVODE fails after minutes, or at once, without naming the key. SI bounds; `range` says them in
// the units users write.
struct Range {
  double lo, hi;
  const char* text;
};
constexpr double kLitresPerCmH2O = units::m3_per_l_per_pa_per_cmh2o;
constexpr double kCmH2OSecondsPerLitre = units::pa_s_per_m3_per_cmh2o_s_per_l;
constexpr Range kCompliance{1e-3 * kLitresPerCmH2O, 10.0 * kLitresPerCmH2O, "a compliance from 0.001 to 10 L/cmH2O"};
constexpr Range kResistance{0.1 * kCmH2OSecondsPerLitre, 1000.0 * kCmH2OSecondsPerLitre,
                            "a resistance from 0.1 to 1000 cmH2O*s/L"};
constexpr Range kRelativeTolerance{1e-12, 0.1, "a relative tolerance from 1e-12 to 0.1"};
constexpr Range kAbsoluteTolerance{1e-15, 1e-4, "an absolute tolerance from 1e-12 L to 0.1 L"};
constexpr Range kMaxStep{1e-6, 10.0, "a maximum step from 1e-6 s to 10 s"};
// A driver's pressures (PEEP, inspiratory, muscle, support, limit) and volumes (tidal, limit),
// and a pressure-volume curve's: far beyond any breath, where the lung model's first step fails
// (peep: 1e308 cmH2O, volume_range: 2e300 L).
constexpr Range kDriverPressure{-200.0 * units::pa_per_cmh2o, 200.0 * units::pa_per_cmh2o,
                                "a pressure from -200 to 200 cmH2O"};
constexpr Range kDriverVolume{-1e-2, 1e-2, "a volume of at most 10 L"};
// A breathing or ventilator rate: one breath a minute to beyond the fastest conventional
// ventilation (high-frequency oscillation is not what the lumped model describes). At 1e-5 /min
// the tidal-volume calibration integrates eight breaths of a year each.
constexpr Range kBreathingRate{1.0 / 60.0, 200.0 / 60.0, "a rate from 1 /min to 200 /min"};
constexpr Range kCurveWidth{0.1 * units::pa_per_cmh2o, 200.0 * units::pa_per_cmh2o, "a width from 0.1 to 200 cmH2O"};

// `value` (read from `key`) when it lies in `range`; else the one-line error at the key, in the
// file that holds it (a preset's own file for a value it gives).
double in_range(const scenario::Node& n, const std::string& key, double value, const Range& range) {
  if (!(value >= range.lo && value <= range.hi))
    n.fail_at(key, std::string("expected ") + range.text + ", got " + quote_input(n.string(key)));
  return value;
}

// Overlays the driver keys present in `n` on `f`, refusing keys the mode does not take.
void overlay_driver(const scenario::Node& n, const std::string& mode, DriverFields& f) {
  for (const std::string& key : kDriverKeys) {
    if (n.has(key) && !mode_takes(mode, key)) n.fail_at(key, "not a setting of " + mode + " mode");
  }
  if (n.has("ie_ratio") && n.has("inspiratory_time"))
    n.fail_at("inspiratory_time", "give ie_ratio or inspiratory_time, not both");
  if (n.has("tidal_volume") && n.has("muscle_pressure"))
    n.fail_at("muscle_pressure", "give tidal_volume or muscle_pressure, not both");
  if (n.has("rate")) f.rate = in_range(n, "rate", n.quantity("rate", kind::rate), kBreathingRate);
  if (auto v = n.optional_ratio("ie_ratio")) {
    f.ie_ratio = v;
    f.inspiratory_time.reset();
  }
  if (auto v = n.optional_quantity("inspiratory_time", kind::duration)) {
    f.inspiratory_time = v;
    f.ie_ratio.reset();
  }
  if (auto v = n.optional_quantity("tidal_volume", kind::volume)) {
    f.tidal_volume = in_range(n, "tidal_volume", *v, kDriverVolume);
    f.muscle_pressure.reset();
  }
  if (auto v = n.optional_quantity("muscle_pressure", kind::pressure)) {
    f.muscle_pressure = in_range(n, "muscle_pressure", *v, kDriverPressure);
    f.tidal_volume.reset();
  }
  if (auto v = n.optional_quantity("pause", kind::duration)) f.pause = v;
  if (auto v = n.optional_quantity("peep", kind::pressure)) f.peep = in_range(n, "peep", *v, kDriverPressure);
  if (auto v = n.optional_quantity("inspiratory_pressure", kind::pressure))
    f.inspiratory_pressure = in_range(n, "inspiratory_pressure", *v, kDriverPressure);
  if (n.has("waveform")) {
    f.waveform = n.choice("waveform", {"square", "decelerating"}) == "square" ? physiology::FlowWaveform::square
                                                                              : physiology::FlowWaveform::decelerating;
  }
  if (auto v = n.optional_quantity("rise_time", kind::duration)) {
    if (!(*v >= 0.0)) n.fail_at("rise_time", "expected a duration >= 0, got '" + n.string("rise_time") + "'");
    f.rise_time = v;
  }
  if (n.has("pressure_limit"))
    f.pressure_limit =
        in_range(n, "pressure_limit", n.positive_quantity("pressure_limit", kind::pressure), kDriverPressure);
  if (n.has("volume_limit"))
    f.volume_limit = in_range(n, "volume_limit", n.positive_quantity("volume_limit", kind::volume), kDriverVolume);
  if (auto v = n.optional_quantity("pressure_support", kind::pressure)) {
    if (!(*v >= 0.0))
      n.fail_at("pressure_support", "expected a pressure >= 0, got '" + n.string("pressure_support") + "'");
    f.pressure_support = in_range(n, "pressure_support", *v, kDriverPressure);
  }
  if (n.has("trigger")) read_trigger(n, f);
  if (n.has("cycle")) read_cycle(n, f);
  if (n.has("trigger_window")) f.trigger_window = n.positive_quantity("trigger_window", kind::duration);
  if (n.has("pressure_step"))
    f.pressure_step =
        in_range(n, "pressure_step", n.positive_quantity("pressure_step", kind::pressure), kDriverPressure);
  for (const char* key : {"high_pressure", "low_pressure"}) {
    if (auto v = n.optional_quantity(key, kind::pressure)) {
      if (!(*v >= 0.0)) n.fail_at(key, std::string("expected a pressure >= 0, got '") + n.string(key) + "'");
      (std::string(key) == "high_pressure" ? f.high_pressure : f.low_pressure) = in_range(n, key, *v, kDriverPressure);
    }
  }
  if (n.has("high_time")) f.high_time = n.positive_quantity("high_time", kind::duration);
  if (n.has("low_time")) f.low_time = n.positive_quantity("low_time", kind::duration);
  if (n.has("gain")) {
    const double g = n.quantity("gain", kind::fraction);
    if (!(g > 0.0 && g < 1.0))
      n.fail_at("gain",
                "expected a share of the patient's pressure above 0 and below 100 %, got '" + n.string("gain") + "'");
    f.gain = g;
  }
  if (n.has("assisted_resistance"))
    f.assisted_resistance =
        in_range(n, "assisted_resistance", n.positive_quantity("assisted_resistance", kind::resistance), kResistance);
  if (n.has("assisted_compliance"))
    f.assisted_compliance =
        in_range(n, "assisted_compliance", n.positive_quantity("assisted_compliance", kind::compliance), kCompliance);
  if (auto apnea = n.optional_map("apnea")) {
    // apnea: {time, rate, inspiratory_pressure, inspiratory_time}: the backup's PC-AC breaths.
    f.apnea_time = apnea->positive_quantity("time", kind::duration);
    f.backup_rate = in_range(*apnea, "rate", apnea->quantity("rate", kind::rate), kBreathingRate);
    const double p = apnea->quantity("inspiratory_pressure", kind::pressure);
    if (!(p >= 0.0)) apnea->fail_at("inspiratory_pressure", "expected a pressure >= 0");
    f.backup_pressure = in_range(*apnea, "inspiratory_pressure", p, kDriverPressure);
    const double ti = apnea->positive_quantity("inspiratory_time", kind::duration);
    if (!(ti < 1.0 / *f.backup_rate))
      apnea->fail_at("inspiratory_time", fmt::format("expected less than one backup breath (60 / rate = {:g} s), got "
                                                     "'{}'",
                                                     1.0 / *f.backup_rate, apnea->string("inspiratory_time")));
    f.backup_inspiratory_time = ti;
    apnea->finish();
  }
}

// A leak: {flow: 20 L/min, at: 10 cmH2O, law: orifice | linear}: the flow it lets out at that
// pressure (orifice, the default: Q = k sqrt(P); linear: Q = k P).
physiology::Leak read_leak(const scenario::Node& n) {
  physiology::Leak leak;
  const double flow = n.quantity("flow", kind::flow);
  if (!(flow >= 0.0 && flow <= 1.0))
    n.fail_at("flow", "expected a flow from 0 to 60000 L/min, got '" + n.string("flow") + "'");
  const double at = in_range(n, "at", n.positive_quantity("at", kind::pressure), kDriverPressure);
  if (n.has("law"))
    leak.law =
        n.choice("law", {"orifice", "linear"}) == "linear" ? physiology::LeakLaw::linear : physiology::LeakLaw::orifice;
  n.finish();
  leak.coefficient = physiology::leak_coefficient(leak.law, flow, at);
  return leak;
}

// circuit: {compliance: 2 mL/cmH2O, resistance: 1 cmH2O*s/L, leak: {...}, patient_leak: {...}},
// patched key by key over `circuit`.
physiology::Circuit overlay_circuit(const scenario::Node& n, physiology::Circuit circuit) {
  auto c = n.optional_map("circuit");
  if (!c) return circuit;
  if (auto v = c->optional_quantity("compliance", kind::compliance)) {
    if (!(*v >= 0.0 && *v <= 0.1 * kLitresPerCmH2O))
      c->fail_at("compliance",
                 "expected a tubing compliance from 0 to 100 mL/cmH2O, got '" + c->string("compliance") + "'");
    circuit.tubing_compliance_m3_per_pa = *v;
  }
  if (auto v = c->optional_quantity("resistance", kind::resistance)) {
    if (!(*v >= 0.0 && *v <= kResistance.hi))
      c->fail_at("resistance",
                 "expected a tubing resistance from 0 to 1000 cmH2O*s/L, got '" + c->string("resistance") + "'");
    circuit.tubing_resistance_pa_s_per_m3 = *v;
  }
  if (auto l = c->optional_map("leak")) circuit.port = read_leak(*l);
  if (auto l = c->optional_map("patient_leak")) circuit.patient = read_leak(*l);
  c->finish();
  if (circuit.tubing_compliance_m3_per_pa > 0.0 && !(circuit.tubing_resistance_pa_s_per_m3 > 0.0))
    c->fail_at(c->has("compliance") ? "compliance" : "resistance",
               "a tubing compliance fills through the tubing: give the tubing resistance too (such as '1 cmH2O*s/L')");
  return circuit;
}

// alarms: {high_pressure, low_pressure, low_tidal_volume, low_minute_volume, disconnection},
// patched key by key over `alarms`.
physiology::Alarms overlay_alarms(const scenario::Node& n, physiology::Alarms alarms) {
  auto a = n.optional_map("alarms");
  if (!a) return alarms;
  if (a->has("high_pressure"))
    alarms.high_pressure_pa =
        in_range(*a, "high_pressure", a->positive_quantity("high_pressure", kind::pressure), kDriverPressure);
  if (a->has("low_pressure"))
    alarms.low_pressure_pa =
        in_range(*a, "low_pressure", a->positive_quantity("low_pressure", kind::pressure), kDriverPressure);
  if (a->has("low_tidal_volume"))
    alarms.low_tidal_volume_m3 =
        in_range(*a, "low_tidal_volume", a->positive_quantity("low_tidal_volume", kind::volume), kDriverVolume);
  if (a->has("low_minute_volume"))
    alarms.low_minute_volume_m3_per_s = a->positive_quantity("low_minute_volume", kind::flow);
  if (a->has("disconnection")) {
    const double f = a->quantity("disconnection", kind::fraction);
    if (!(f > 0.0 && f <= 1.0))
      a->fail_at("disconnection",
                 "expected a leak share above 0 and at most 100 %, got '" + a->string("disconnection") + "'");
    alarms.disconnection_leak_fraction = f;
  }
  a->finish();
  if (alarms.high_pressure_pa > 0.0 && !(alarms.high_pressure_pa > alarms.low_pressure_pa))
    a->fail_at(a->has("high_pressure") ? "high_pressure" : "low_pressure",
               "expected the high pressure alarm above the low one");
  return alarms;
}

std::string fmt_cmh2o(double pa) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%g", pa / units::pa_per_cmh2o);
  return buffer;
}

double require(const scenario::Node& n, const std::optional<double>& value, const std::string& key,
               const units::Kind& k) {
  if (!value)
    n.fail_missing(std::string("missing key '") + key + "' (expected " + k.name + " such as '" + k.example + "')");
  return *value;
}

// An assist mode's driver from its fields; defaults: a flow trigger at 2 L/min, a square flow,
// no rise time; pc_ac cycles on time, cpap_psv on flow at 25 % of the peak, with inspiration
// at most 3 s.
// APRV from its levels and times: P_low is PEEP, P_high - P_low the inspiratory pressure, T_high
// the inspiratory time, one release cycle T_high + T_low.
physiology::Assisted build_aprv(const scenario::Node& n, const DriverFields& f) {
  physiology::Assisted a;
  a.mode = physiology::AssistMode::aprv;
  const double high = require(n, f.high_pressure, "high_pressure", kind::pressure);
  const double low = require(n, f.low_pressure, "low_pressure", kind::pressure);
  const double th = require(n, f.high_time, "high_time", kind::duration);
  const double tl = require(n, f.low_time, "low_time", kind::duration);
  if (!(high > low)) {
    const std::string what =
        "expected high_pressure above low_pressure (" + fmt_cmh2o(low) + " cmH2O), got " + fmt_cmh2o(high) + " cmH2O";
    n.fail_at(n.has("high_pressure") ? "high_pressure" : "low_pressure", what);
  }
  if (!(1.0 / (th + tl) <= kBreathingRate.hi))
    n.fail_at(n.has("high_time") ? "high_time" : "low_time",
              fmt::format("expected a release cycle (high_time + low_time) of at least {:g} s, got {:g} s",
                          1.0 / kBreathingRate.hi, th + tl));
  a.peep_pa = low;
  a.inspiratory_pressure_pa = high - low;
  a.inspiratory_time_s = th;
  a.rate_hz = 1.0 / (th + tl);
  a.rise_time_s = f.rise_time.value_or(0.0);
  if (!(a.rise_time_s < th))
    n.fail_at(n.has("rise_time") ? "rise_time" : "high_time",
              fmt::format("expected a rise time shorter than high_time ({:g} s), got {:g} s", th, a.rise_time_s));
  a.cycle = physiology::CycleKind::time;
  a.trigger_threshold = f.trigger_threshold.value_or(2.0 * units::m3_per_litre / 60.0);
  a.trigger = f.trigger.value_or(physiology::TriggerKind::flow);
  // BiLevel: the breaths at P_low supported, cycled on flow (25 % of the peak by default).
  a.support_pa = f.pressure_support.value_or(0.0);
  if (a.support_pa > 0.0) {
    a.cycle = f.cycle.value_or(physiology::CycleKind::flow);
    a.cycle_fraction = f.cycle_fraction.value_or(0.25);
    a.cycle_flow_m3_per_s = f.cycle_flow.value_or(0.0);
    if (a.cycle == physiology::CycleKind::volume) a.cycle_volume_m3 = require(n, f.cycle_volume, "cycle", kind::volume);
  } else if (n.has("trigger") || n.has("cycle")) {
    n.fail_at(n.has("trigger") ? "trigger" : "cycle",
              "APRV triggers and cycles nothing; set pressure_support for BiLevel's supported breaths");
  }
  return a;
}

physiology::Assisted build_assisted(const scenario::Node& n, const std::string& mode, const DriverFields& f) {
  if (mode == "aprv") return build_aprv(n, f);
  physiology::Assisted a;
  a.mode = mode == "vc_ac"     ? physiology::AssistMode::volume
           : mode == "pc_ac"   ? physiology::AssistMode::pressure
           : mode == "vc_simv" ? physiology::AssistMode::simv_volume
           : mode == "pc_simv" ? physiology::AssistMode::simv_pressure
           : mode == "prvc"    ? physiology::AssistMode::prvc
           : mode == "pav"     ? physiology::AssistMode::pav
                               : physiology::AssistMode::pressure_support;
  const bool pav = a.mode == physiology::AssistMode::pav;
  const bool support = a.mode == physiology::AssistMode::pressure_support || pav;
  const bool simv = physiology::is_simv(a);
  a.rate_hz = support ? 0.0 : require(n, f.rate, "rate", kind::rate);
  a.peep_pa = f.peep.value_or(0.0);
  if (f.inspiratory_time) a.inspiratory_time_s = *f.inspiratory_time;
  else if (f.ie_ratio && !support) a.inspiratory_time_s = (1.0 / a.rate_hz) * *f.ie_ratio / (1.0 + *f.ie_ratio);
  else if (support) a.inspiratory_time_s = 3.0;
  else n.fail_missing("missing key 'inspiratory_time' or 'ie_ratio' (expected a duration such as '1 s')");
  a.trigger = f.trigger.value_or(physiology::TriggerKind::flow);
  a.trigger_threshold = f.trigger_threshold.value_or(2.0 * units::m3_per_litre / 60.0);
  if (simv) {
    a.support_pa = f.pressure_support.value_or(0.0);
    a.trigger_window_s = f.trigger_window.value_or(physiology::default_trigger_window_s(a.rate_hz));
    if (!(a.trigger_window_s <= 1.0 / a.rate_hz)) {
      const std::string what =
          fmt::format("expected a trigger window of at most one cycle (60 / rate = {:g} s), got {:g} s",
                      1.0 / a.rate_hz, a.trigger_window_s);
      if (n.has("trigger_window")) n.fail_at("trigger_window", what);
      if (n.has("rate")) n.fail_at("rate", what);
      n.fail(what);
    }
  }
  if (a.mode == physiology::AssistMode::volume || a.mode == physiology::AssistMode::simv_volume) {
    a.tidal_volume_m3 = require(n, f.tidal_volume, "tidal_volume", kind::volume);
    a.pause_time_s = f.pause.value_or(0.0);
    a.waveform = f.waveform.value_or(physiology::FlowWaveform::square);
    a.pressure_limit_pa = f.pressure_limit.value_or(0.0);
    if (a.pressure_limit_pa > 0.0 && !(a.pressure_limit_pa > a.peep_pa)) {
      const std::string what = "expected a pressure limit above PEEP (" + fmt_cmh2o(a.peep_pa) + " cmH2O), got " +
                               fmt_cmh2o(a.pressure_limit_pa) + " cmH2O";
      if (n.has("pressure_limit")) n.fail_at("pressure_limit", what);
      if (n.has("peep")) n.fail_at("peep", what);
      n.fail(what);
    }
  }
  if (a.mode != physiology::AssistMode::volume) {
    if (a.mode != physiology::AssistMode::simv_volume && !pav)
      a.inspiratory_pressure_pa = support ? require(n, f.pressure_support, "pressure_support", kind::pressure)
                                          : require(n, f.inspiratory_pressure, "inspiratory_pressure", kind::pressure);
    a.rise_time_s = f.rise_time.value_or(0.0);
    a.cycle = f.cycle.value_or(support || simv ? physiology::CycleKind::flow : physiology::CycleKind::time);
    a.cycle_fraction = f.cycle_fraction.value_or(0.25);
    a.cycle_flow_m3_per_s = f.cycle_flow.value_or(0.0);
    if (a.cycle == physiology::CycleKind::volume) a.cycle_volume_m3 = require(n, f.cycle_volume, "cycle", kind::volume);
    a.volume_limit_m3 = f.volume_limit.value_or(0.0);
  }
  if (a.mode == physiology::AssistMode::prvc) {
    a.tidal_volume_m3 = require(n, f.tidal_volume, "tidal_volume", kind::volume);
    a.prvc_step_pa = f.pressure_step.value_or(3.0 * units::pa_per_cmh2o);
    a.pressure_limit_pa = f.pressure_limit.value_or(0.0);
    if (a.pressure_limit_pa > 0.0 && !(a.pressure_limit_pa > a.peep_pa + a.inspiratory_pressure_pa)) {
      const std::string what = "expected a pressure limit above PEEP + inspiratory_pressure (" +
                               fmt_cmh2o(a.peep_pa + a.inspiratory_pressure_pa) + " cmH2O), got " +
                               fmt_cmh2o(a.pressure_limit_pa) + " cmH2O";
      n.fail_at(n.has("pressure_limit") ? "pressure_limit" : n.has("peep") ? "peep" : "inspiratory_pressure", what);
    }
  }
  if (pav) {
    a.pav_gain = require(n, f.gain, "gain", kind::fraction);
    a.pav_resistance_pa_s_per_m3 = require(n, f.assisted_resistance, "assisted_resistance", kind::resistance);
    a.pav_elastance_pa_per_m3 = 1.0 / require(n, f.assisted_compliance, "assisted_compliance", kind::compliance);
    a.pressure_limit_pa = f.pressure_limit.value_or(0.0);
    if (a.pressure_limit_pa > 0.0 && !(a.pressure_limit_pa > a.peep_pa))
      n.fail_at(n.has("pressure_limit") ? "pressure_limit" : "peep", "expected a pressure limit above PEEP (" +
                                                                         fmt_cmh2o(a.peep_pa) + " cmH2O), got " +
                                                                         fmt_cmh2o(a.pressure_limit_pa) + " cmH2O");
  }
  if (support && !pav && f.apnea_time) {
    a.apnea_time_s = *f.apnea_time;
    a.backup_rate_hz = *f.backup_rate;
    a.backup_pressure_pa = *f.backup_pressure;
    a.backup_inspiratory_time_s = *f.backup_inspiratory_time;
  }
  return a;
}

Driver build_driver(const scenario::Node& n, const std::string& mode, const DriverFields& f) {
  Driver driver;
  if (is_assist(mode)) {
    driver = build_assisted(n, mode, f);
    try {
      physiology::validate(driver);
    } catch (const ValueError& e) {
      n.fail(e.what());
    }
    return driver;
  }
  const double rate = require(n, f.rate, "rate", kind::rate);
  if (mode == "spontaneous") {
    physiology::Spontaneous s;
    s.rate_hz = rate;
    if (!f.ie_ratio) n.fail_missing("missing key 'ie_ratio' (expected a ratio such as '1:2')");
    s.ie_ratio = *f.ie_ratio;
    if (f.tidal_volume) s.target_tidal_volume_m3 = *f.tidal_volume;
    else s.amplitude_pa = require(n, f.muscle_pressure, "tidal_volume' or 'muscle_pressure", kind::volume);
    driver = s;
  } else {
    double ti = 0.0;
    if (f.inspiratory_time) ti = *f.inspiratory_time;
    else if (f.ie_ratio) ti = (1.0 / rate) * *f.ie_ratio / (1.0 + *f.ie_ratio);
    else n.fail_missing("missing key 'inspiratory_time' or 'ie_ratio' (expected a duration such as '1 s')");
    const double peep = f.peep.value_or(0.0);
    if (mode == "volume_control") {
      driver = physiology::VolumeControl{rate, require(n, f.tidal_volume, "tidal_volume", kind::volume), ti,
                                         f.pause.value_or(0.0), peep};
    } else {
      driver = physiology::PressureControl{
          rate, require(n, f.inspiratory_pressure, "inspiratory_pressure", kind::pressure), ti, peep};
    }
  }
  try {
    physiology::validate(driver);
  } catch (const ValueError& e) {
    n.fail(e.what());
  }
  return driver;
}

// A compartment's elastic recoil: `compliance` (linear) or `pressure_volume_curve` (sigmoid).
std::optional<physiology::Elasticity> read_elasticity(const scenario::Node& n) {
  if (n.has("compliance") && n.has("pressure_volume_curve"))
    n.fail_at("pressure_volume_curve", "give compliance or pressure_volume_curve, not both");
  if (n.has("compliance")) {
    return physiology::LinearCompliance{
        in_range(n, "compliance", n.positive_quantity("compliance", kind::compliance), kCompliance)};
  }
  if (auto curve = n.optional_map("pressure_volume_curve")) {
    physiology::SigmoidCompliance s;
    s.lower_volume_m3 = in_range(*curve, "lower_volume", curve->quantity("lower_volume", kind::volume), kDriverVolume);
    s.volume_range_m3 =
        in_range(*curve, "volume_range", curve->positive_quantity("volume_range", kind::volume), kDriverVolume);
    s.inflection_pressure_pa = in_range(*curve, "inflection_pressure",
                                        curve->quantity("inflection_pressure", kind::pressure), kDriverPressure);
    s.width_pa = in_range(*curve, "width", curve->positive_quantity("width", kind::pressure), kCurveWidth);
    s.relaxed_volume_m3 =
        in_range(*curve, "relaxed_volume", curve->positive_quantity("relaxed_volume", kind::volume), kDriverVolume);
    curve->finish();
    if (!(s.relaxed_volume_m3 > s.lower_volume_m3 && s.relaxed_volume_m3 < s.lower_volume_m3 + s.volume_range_m3))
      curve->fail_at("relaxed_volume", "expected a volume between lower_volume and lower_volume + volume_range");
    return s;
  }
  return std::nullopt;
}

void overlay_compartment(const scenario::Node& n, physiology::Compartment& c, bool need_resistance) {
  if (auto e = read_elasticity(n)) c.elasticity = *e;
  if (auto r = n.optional_quantity("resistance", kind::resistance)) {
    if (!(*r > 0)) n.fail_at("resistance", "expected a positive resistance");
    c.resistance_pa_s_per_m3 = in_range(n, "resistance", *r, kResistance);
  } else if (need_resistance) {
    n.fail_missing("missing key 'resistance' (expected a resistance such as '2 cmH2O*s/L')");
  }
}

// Mechanics keys: for `single` the compartment's elasticity and the airway resistance;
// for `two_compartment` the airway resistance and compartments.upper/lower.
void overlay_mechanics(const scenario::Node& n, const std::string& model, Mechanics& m, bool initial) {
  if (model == "single") {
    if (n.has("compartments")) n.fail_at("compartments", "only a two_compartment model has compartments");
    physiology::Compartment& lung = m.compartments[0];
    const bool had = n.has("compliance") || n.has("pressure_volume_curve");
    if (auto e = read_elasticity(n)) lung.elasticity = *e;
    if (initial && !had) n.fail_missing("missing key 'compliance' (expected a compliance such as '0.1 L/cmH2O')");
  } else {
    for (const char* key : {"compliance", "pressure_volume_curve"}) {
      if (n.has(key))
        n.fail_at(key, "a two_compartment model sets this per compartment (compartments.upper, compartments.lower)");
    }
    auto compartments = n.optional_map("compartments");
    if (initial && !compartments) n.fail_missing("missing key 'compartments' (with 'upper' and 'lower')");
    if (compartments) {
      for (std::size_t i = 0; i < 2; ++i) {
        const std::string name = i == 0 ? "upper" : "lower";
        auto c = compartments->optional_map(name);
        if (initial && !c) compartments->fail_missing("missing key '" + name + "'");
        if (!c) continue;
        const bool had = c->has("compliance") || c->has("pressure_volume_curve");
        if (initial && !had) c->fail_missing("missing key 'compliance' (expected a compliance such as '0.05 L/cmH2O')");
        overlay_compartment(*c, m.compartments[i], initial);
        c->finish();
      }
      compartments->finish();
    }
  }
  if (auto r = n.optional_quantity("resistance", kind::resistance)) {
    if (!(*r > 0) && model == "single") n.fail_at("resistance", "expected a positive resistance");
    if (!(*r >= 0)) n.fail_at("resistance", "expected a resistance >= 0");
    m.airway_resistance_pa_s_per_m3 = *r > 0.0 ? in_range(n, "resistance", *r, kResistance) : *r;
  } else if (initial) {
    n.fail_missing("missing key 'resistance' (expected a resistance such as '2 cmH2O*s/L')");
  }
  // The single model's expiration: its own resistance, a flow limitation (Starling resistor).
  for (const char* key : {"expiratory_resistance", "flow_limitation"}) {
    if (n.has(key) && model != "single") n.fail_at(key, "only the single model takes this");
  }
  if (n.has("expiratory_resistance"))
    m.expiratory_airway_resistance_pa_s_per_m3 = in_range(
        n, "expiratory_resistance", n.positive_quantity("expiratory_resistance", kind::resistance), kResistance);
  if (auto f = n.optional_map("flow_limitation")) {
    m.critical_pressure_pa =
        in_range(*f, "critical_pressure", f->quantity("critical_pressure", kind::pressure), kDriverPressure);
    // Upstream of the choke point: by default the whole expiratory resistance.
    const double expiratory = m.expiratory_airway_resistance_pa_s_per_m3 > 0.0
                                  ? m.expiratory_airway_resistance_pa_s_per_m3
                                  : m.airway_resistance_pa_s_per_m3;
    m.upstream_resistance_pa_s_per_m3 =
        f->has("upstream_resistance")
            ? in_range(*f, "upstream_resistance", f->positive_quantity("upstream_resistance", kind::resistance),
                       kResistance)
            : expiratory;
    f->finish();
  }
}

// effort: {rate, ie_ratio, muscle_pressure, release}: the patient's own effort on a ventilated
// patient, patched key by key over `effort`.
physiology::PatientEffort overlay_effort(const scenario::Node& n, physiology::PatientEffort effort,
                                         const physiology::Driver& driver) {
  auto e = n.optional_map("effort");
  if (!e) return effort;
  if (e->has("rate")) effort.rate_hz = in_range(*e, "rate", e->quantity("rate", kind::rate), kBreathingRate);
  if (auto r = e->optional_ratio("ie_ratio")) {
    if (!(*r > 0.0)) e->fail_at("ie_ratio", "expected a positive ratio such as '1:2'");
    effort.ie_ratio = *r;
  }
  if (auto p = e->optional_quantity("muscle_pressure", kind::pressure)) {
    if (!(*p >= 0.0))
      e->fail_at("muscle_pressure", "expected a pressure >= 0, got '" + e->string("muscle_pressure") + "'");
    effort.amplitude_pa = *p;
  }
  if (auto r = e->optional_quantity("release", kind::fraction)) {
    if (!(*r > 0.0 && *r <= 1.0))
      e->fail_at("release",
                 "expected a share of the expiration above 0 and at most 100 %, got '" + e->string("release") + "'");
    effort.release_share = *r;
  }
  e->finish();
  if (effort.active() && !(effort.rate_hz > 0.0))
    e->fail_missing("missing key 'rate' (expected a rate such as '15 /min')");
  if (effort.active() && !physiology::is_ventilator(driver))
    n.fail_at("effort",
              "a patient effort acts on a ventilated patient; spontaneous mode is the patient's own breathing");
  return effort;
}

scenario::Node with_preset(const scenario::Node& section, const std::filesystem::path& config_dir) {
  auto preset = section.optional_string("preset");
  if (!preset) return section;
  std::filesystem::path file;
  if (preset->find('/') != std::string::npos || preset->ends_with(".yaml")) {
    file = section.directory("preset") / *preset;
  } else {
    file = config_dir / "physiology" / (*preset + ".yaml");
  }
  if (!path_exists(file)) {
    section.fail_at("preset", "no preset '" + *preset + "' (looked for " + file.string() + "; shipped presets: " +
                                  join_names(file_stems(config_dir / "physiology", ".yaml")) + ")");
  }
  return section.with_fallback(scenario::Node::load_file(file), "preset");
}

// The keys of the lumped model, which a trace replaces.
const std::vector<std::string> kLumpedKeys{"preset",
                                           "model",
                                           "compliance",
                                           "pressure_volume_curve",
                                           "resistance",
                                           "expiratory_resistance",
                                           "flow_limitation",
                                           "compartments",
                                           "transpulmonary_pressure_at_rest",
                                           "chest_wall_fraction",
                                           "actions",
                                           "solver"};

physiology::TraceSignal signal_from(const std::string& name) {
  if (name == "flow") return physiology::TraceSignal::flow;
  if (name == "amplitude") return physiology::TraceSignal::amplitude;
  return physiology::TraceSignal::volume;
}

// `calibration: {spirometry: file.csv}`: a volume or flow CSV (trace.h), processed as a volume
// trace is (FRC at 0, a flow's drift removed).
physiology::Trace read_spirometry(const scenario::Node& calibration) {
  const std::filesystem::path file = calibration.directory("spirometry") / calibration.string("spirometry");
  if (const std::string why = missing_reason(file); !why.empty())
    calibration.fail_at("spirometry", why + ": " + file.string());
  physiology::TraceOptions options;
  const physiology::RawTrace raw = physiology::read_trace_file(file, options);
  if (raw.signal == physiology::TraceSignal::amplitude)
    calibration.fail_at(
        "spirometry", "expected a volume or flow trace (such as 'time_s,volume_mL'), got the amplitude '" + raw.column +
                          "' of " + file.filename().string());
  return physiology::process_trace(raw, options);
}

// `driver: {mode: trace, file: ..., ...}`: the file read and processed here, so that a bad trace
// fails when the scenario is loaded. Errors in the file name the file and line; errors of the
// keys name the scenario's key.
physiology::Trace read_trace_driver(const scenario::Node& n, double duration_s) {
  physiology::TraceOptions o;
  const std::filesystem::path file = n.directory("file") / n.string("file");
  if (const std::string why = missing_reason(file); !why.empty()) n.fail_at("file", why + ": " + file.string());
  std::string format = n.has("format") ? n.choice("format", {"auto", "csv", "rpm"}) : "auto";
  if (format == "auto") {
    std::string ext = file.extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    format = ext == ".vxp" || ext == ".dat" ? "rpm" : "csv";
  }
  o.format = format == "rpm" ? physiology::TraceFormat::rpm : physiology::TraceFormat::csv;
  if (n.has("signal")) {
    o.signal = signal_from(n.choice("signal", {"volume", "flow", "amplitude"}));
    if (o.format == physiology::TraceFormat::rpm && o.signal != physiology::TraceSignal::amplitude)
      n.fail_at("signal", "an RPM file holds an amplitude");
  }
  if (n.has("column")) {
    if (o.format == physiology::TraceFormat::rpm)
      n.fail_at("column", "an RPM file has one amplitude column; 'column' is for CSV");
    o.column = n.string("column");
  }
  if (n.has("detrend")) o.detrend = n.boolean("detrend", true);
  o.invert = n.boolean("invert", false);
  if (auto start = n.optional_quantity("start", kind::duration)) {
    if (!(*start >= 0.0)) n.fail_at("start", "expected a time >= 0 s");
    o.start_s = *start;
  }
  std::optional<scenario::Node> calibration = n.optional_map("calibration");
  if (calibration) {
    const int given = static_cast<int>(calibration->has("tidal_volume")) +
                      static_cast<int>(calibration->has("volume_per_unit")) +
                      static_cast<int>(calibration->has("spirometry"));
    if (given != 1)
      calibration->fail(
          "expected one of 'tidal_volume' (such as '500 mL'), 'volume_per_unit' (the volume of one amplitude unit, "
          "such as '400 mL') or 'spirometry' (a volume or flow CSV recorded at the same time)");
    if (calibration->has("tidal_volume")) {
      o.calibration.tidal_volume_m3 = calibration->positive_quantity("tidal_volume", kind::volume);
    } else if (calibration->has("volume_per_unit")) {
      o.calibration.volume_per_unit_m3 = calibration->positive_quantity("volume_per_unit", kind::volume);
    } else {
      o.calibration.spirometry = std::make_shared<const physiology::Trace>(read_spirometry(*calibration));
      if (auto offset = calibration->optional_quantity("offset", kind::duration)) {
        if (!std::isfinite(*offset)) calibration->fail_at("offset", "expected a finite time, such as '2.5 s'");
        o.calibration.spirometry_offset_s = *offset;
      }
    }
    calibration->finish();
  } else if (n.has("offset")) {
    n.fail_at("offset", "the spirometry's 'offset' goes inside 'calibration: {spirometry: ..., offset: ...}'");
  }
  n.finish();
  const physiology::RawTrace raw = physiology::read_trace_file(file, o);
  if (raw.signal == physiology::TraceSignal::amplitude && !calibration)
    n.fail("an amplitude trace ('" + raw.column + "' of " + file.filename().string() +
           ") needs 'calibration: {tidal_volume: 500 mL}', 'calibration: {volume_per_unit: 400 mL}' or "
           "'calibration: {spirometry: spirometer.csv}'");
  if (raw.signal != physiology::TraceSignal::amplitude && calibration)
    n.fail_at("calibration", std::string("only an amplitude trace is calibrated; this one holds a ") +
                                 physiology::signal_name(raw.signal));
  if (raw.signal != physiology::TraceSignal::amplitude && n.has("invert"))
    n.fail_at("invert", "only an amplitude trace can be inverted");
  physiology::Trace trace = physiology::process_trace(raw, o);
  const double covered = trace.end_s() - trace.time_s.front() - o.start_s;
  if (covered < duration_s - 1e-9) {
    n.fail_at("file", fmt::format("the trace covers {:.6g} s{}, less than the scenario's duration of {:.6g} s",
                                  std::max(covered, 0.0), o.start_s > 0.0 ? " after 'start'" : "", duration_s));
  }
  physiology::check_gaps_in_run(trace, duration_s);
  return trace;
}

}  // namespace

std::filesystem::path default_config_dir() {
  if (const char* dir = std::getenv("PNEUMA_CONFIG_DIR"); dir && *dir) return dir;
  const std::filesystem::path binary = running_binary();
  if (binary.empty()) return PNEUMA_SOURCE_CONFIG_DIR;
  // An installed pneuma: <prefix>/share/pneuma/configs, reached from bin/pneuma or from the Python
  // module's folder (the relative paths come from the install rules).
  std::vector<std::filesystem::path> installed;
  for (const char* relative : {PNEUMA_CONFIGS_FROM_BIN, PNEUMA_CONFIGS_FROM_PYTHON}) {
    installed.push_back((binary.parent_path() / relative).lexically_normal());
    if (path_exists(installed.back() / "physiology")) return installed.back();
  }
  // A binary in the build tree it was built in (tests, `make demo`) reads the source tree's
  // presets; a binary anywhere else never does, so a copied or installed one without its presets
  // names the installed folder in its messages instead of silently using a checkout.
  std::error_code ec;
  const std::filesystem::path build = std::filesystem::weakly_canonical(PNEUMA_BUILD_DIR, ec);
  if (!ec && std::mismatch(build.begin(), build.end(), binary.begin(), binary.end()).first == build.end())
    return PNEUMA_SOURCE_CONFIG_DIR;
  // Not found: where this binary's install would have put them (the executable's, else the module's).
  const bool executable = std::filesystem::equivalent(binary, "/proc/self/exe", ec) && !ec;
  return executable ? installed[0] : installed[1];
}

// A setting whose driver cannot work with its mechanics or circuit (PAV), at the key that set it.
void check_setting(const scenario::Node& n, const physiology::Setting& setting) {
  try {
    physiology::validate(setting);
  } catch (const ValueError& e) {
    for (const char* key : {"circuit", "gain", "assisted_resistance", "resistance", "mode"}) {
      if (n.has(key)) n.fail_at(key, e.what());
    }
    n.fail(e.what());
  }
}

PhysiologyConfig read_physiology(const scenario::Node& raw_section, double duration_s,
                                 const std::filesystem::path& config_dir) {
  PhysiologyConfig out;
  out.options.duration_s = duration_s;
  if (auto driver = raw_section.optional_map("driver"); driver && driver->optional_string("mode") == "trace") {
    for (const std::string& key : kLumpedKeys) {
      if (raw_section.has(key)) raw_section.fail_at(key, "not used with a trace driver (the trace gives the volume)");
    }
    driver->accept("mode");
    out.trace = read_trace_driver(*driver, duration_s);
    out.options.output_rate_hz =
        raw_section.has("output_rate") ? raw_section.positive_quantity("output_rate", kind::rate) : 100.0;
    raw_section.finish();
    return out;
  }
  const scenario::Node section = with_preset(raw_section, config_dir);

  // Mechanics at t = 0.
  const std::string model = section.has("model") ? section.choice("model", kModels) : "single";
  Mechanics mechanics;
  if (model == "single") {
    mechanics.compartments = {physiology::Compartment{"lung", physiology::LinearCompliance{}, 0.0}};
  } else {
    mechanics.compartments = {physiology::Compartment{"upper", physiology::LinearCompliance{}, 0.0},
                              physiology::Compartment{"lower", physiology::LinearCompliance{}, 0.0}};
  }
  overlay_mechanics(section, model, mechanics, true);
  if (auto p = section.optional_quantity("transpulmonary_pressure_at_rest", kind::pressure))
    mechanics.transpulmonary_pressure_at_rest_pa = *p;
  if (auto f = section.optional_quantity("chest_wall_fraction", kind::fraction)) {
    if (!(*f >= 0 && *f <= 1)) section.fail_at("chest_wall_fraction", "expected a fraction from 0 to 1");
    mechanics.chest_wall_fraction = *f;
  }

  // Driver at t = 0.
  const scenario::Node driver_node = section.map("driver");
  const std::string mode = driver_node.choice("mode", kModesWithTrace);
  if (mode == "trace") driver_node.fail_at("mode", "a trace driver takes no preset");
  DriverFields fields;
  overlay_driver(driver_node, mode, fields);
  const Driver driver = build_driver(driver_node, mode, fields);
  if (!physiology::is_ventilator(driver)) {
    for (const char* key : {"circuit", "alarms"}) {
      if (driver_node.has(key)) driver_node.fail_at(key, "a ventilator's setting; the patient breathes spontaneously");
    }
  }
  const physiology::Circuit circuit = overlay_circuit(driver_node, {});
  const physiology::Alarms alarms = overlay_alarms(driver_node, {});
  driver_node.finish();
  const physiology::PatientEffort effort = overlay_effort(section, {}, driver);
  out.protocol.settings.push_back(physiology::Setting{0.0, mechanics, driver, effort, circuit, alarms});
  check_setting(driver_node, out.protocol.settings.back());

  // Timed actions, each a patch over the setting before it.
  double previous_time = 0.0;
  for (const scenario::Node& action : section.sequence("actions")) {
    const double at = action.quantity("at", kind::duration);
    if (!(at > previous_time)) action.fail_at("at", "expected a time after the previous action's and after 0 s");
    if (at >= duration_s) action.fail_at("at", "expected a time within the scenario's duration");
    previous_time = at;
    // An expiratory hold is a manoeuvre at the next end of expiration, not a setting.
    if (action.has("expiratory_hold")) {
      const double hold = action.positive_quantity("expiratory_hold", kind::duration);
      if (!physiology::is_ventilator(out.protocol.settings.back().driver) && !action.has("mode"))
        action.fail_at("expiratory_hold", "an expiratory hold needs a ventilator; the patient breathes spontaneously");
      out.protocol.holds.push_back({at, hold});
      const auto keys = action.keys();
      if (std::all_of(keys.begin(), keys.end(),
                      [](const std::string& k) { return k == "at" || k == "expiratory_hold"; })) {
        action.finish();
        continue;
      }
    }
    physiology::Setting next = out.protocol.settings.back();
    next.start_time_s = at;
    std::string next_mode = physiology::mode_name(next.driver);
    if (action.has("mode")) next_mode = action.choice("mode", kModes);
    DriverFields f = fields_of(next.driver);
    bool driver_changed = action.has("mode");
    for (const auto& key : kDriverKeys) driver_changed = driver_changed || action.has(key);
    if (driver_changed) {
      overlay_driver(action, next_mode, f);
      next.driver = build_driver(action, next_mode, f);
    }
    overlay_mechanics(action, model, next.mechanics, false);
    next.circuit = overlay_circuit(action, next.circuit);
    next.alarms = overlay_alarms(action, next.alarms);
    if (!physiology::is_ventilator(next.driver)) {
      next.circuit = {};  // the machine is off the patient
      next.alarms = {};
      for (const char* key : {"circuit", "alarms"}) {
        if (action.has(key)) action.fail_at(key, "a ventilator's setting; the patient breathes spontaneously");
      }
    }
    if (action.has("effort") || driver_changed) next.effort = overlay_effort(action, next.effort, next.driver);
    if (next.effort.active() && !physiology::is_ventilator(next.driver))
      action.fail_at(action.has("mode") ? "mode" : "at",
                     "a patient effort acts on a ventilated patient; set effort: {muscle_pressure: 0 cmH2O} first");
    if (action.has("expiratory_hold") && !physiology::is_ventilator(next.driver))
      action.fail_at("expiratory_hold", "an expiratory hold needs a ventilator; the patient breathes spontaneously");
    action.finish();
    check_setting(action, next);
    out.protocol.settings.push_back(next);
  }

  out.options.output_rate_hz =
      section.has("output_rate") ? section.positive_quantity("output_rate", kind::rate) : 100.0;
  if (auto solver = section.optional_map("solver")) {
    out.options.solver.relative_tolerance =
        in_range(*solver, "relative_tolerance", solver->positive_quantity("relative_tolerance", kind::number),
                 kRelativeTolerance);
    out.options.solver.absolute_tolerance_m3 =
        in_range(*solver, "absolute_tolerance", solver->positive_quantity("absolute_tolerance", kind::volume),
                 kAbsoluteTolerance);
    if (auto h = solver->optional_quantity("max_step", kind::duration))
      out.options.solver.max_step_s = in_range(*solver, "max_step", *h, kMaxStep);
    solver->finish();
  }
  section.accept("preset");
  section.finish();
  return out;
}

}  // namespace pneuma::scenario
