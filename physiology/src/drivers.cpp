#include "pneuma/physiology/drivers.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include "pneuma/core/error.h"

namespace pneuma::physiology {
namespace {

struct PlanOf {
  BreathPlan operator()(const Spontaneous& s) const {
    const double period = 1.0 / s.rate_hz;
    const double ti = period * s.ie_ratio / (1.0 + s.ie_ratio);
    const double relax = ti + 0.5 * (period - ti);
    return BreathPlan{{Phase{ti, true}, Phase{relax, false}, Phase{period, false}}, 3};
  }
  BreathPlan operator()(const VolumeControl& v) const {
    const double period = 1.0 / v.rate_hz;
    if (v.pause_time_s > 0.0) {
      return BreathPlan{
          {Phase{v.inspiratory_time_s - v.pause_time_s, true}, Phase{v.inspiratory_time_s, true}, Phase{period, false}},
          3};
    }
    return BreathPlan{{Phase{v.inspiratory_time_s, true}, Phase{period, false}, Phase{}}, 2};
  }
  BreathPlan operator()(const PressureControl& p) const {
    return BreathPlan{{Phase{p.inspiratory_time_s, true}, Phase{1.0 / p.rate_hz, false}, Phase{}}, 2};
  }
  // The mandatory breath as set (no trigger, no cycle event): for information only.
  BreathPlan operator()(const Assisted& a) const {
    const double period = a.rate_hz > 0.0 ? 1.0 / a.rate_hz : std::numeric_limits<double>::infinity();
    return BreathPlan{{Phase{a.inspiratory_time_s, true}, Phase{period, false}, Phase{}}, 2};
  }
};

struct DriveOf {
  int phase;
  double t;
  Drive operator()(const Spontaneous& s) const {
    const BreathPlan plan = PlanOf{}(s);
    const double ti = plan.phases[0].end_s, relax = plan.phases[1].end_s - ti;
    Drive d;
    if (phase == 0) {
      d.muscle_pressure_pa = s.amplitude_pa * 0.5 * (1.0 - std::cos(std::numbers::pi * t / ti));
    } else if (phase == 1) {
      d.muscle_pressure_pa = s.amplitude_pa * 0.5 * (1.0 + std::cos(std::numbers::pi * (t - ti) / relax));
    }
    return d;
  }
  Drive operator()(const VolumeControl& v) const {
    Drive d;
    d.peep_pa = v.peep_pa;
    if (phase == 0) {
      d.flow_controlled = true;
      d.flow_m3_per_s = v.tidal_volume_m3 / (v.inspiratory_time_s - v.pause_time_s);
    } else if (phase == 1 && v.pause_time_s > 0.0) {
      d.flow_controlled = true;  // valves closed: no flow at the airway opening
    } else {
      d.airway_pressure_pa = v.peep_pa;
    }
    return d;
  }
  Drive operator()(const PressureControl& p) const {
    Drive d;
    d.peep_pa = p.peep_pa;
    d.airway_pressure_pa = phase == 0 ? p.peep_pa + p.inspiratory_pressure_pa : p.peep_pa;
    return d;
  }
  Drive operator()(const Assisted& a) const {
    Drive d;
    d.peep_pa = a.peep_pa;
    switch (phase) {
      case kAssistFlow: {
        const double flow_time = a.inspiratory_time_s - a.pause_time_s;
        d.flow_controlled = true;
        d.flow_m3_per_s = a.waveform == FlowWaveform::square
                              ? a.tidal_volume_m3 / flow_time
                              : 2.0 * a.tidal_volume_m3 / flow_time * (1.0 - t / flow_time);
        break;
      }
      case kAssistPause:
      case kAssistOccluded:
        d.flow_controlled = true;  // valves closed: no flow at the airway opening
        break;
      case kAssistPressure:
        if (a.mode == AssistMode::pav) {
          d.airway_pressure_pa = a.peep_pa;
          d.assist_gain = a.pav_gain;
          d.assist_resistance_pa_s_per_m3 = a.pav_resistance_pa_s_per_m3;
          d.assist_elastance_pa_per_m3 = a.pav_elastance_pa_per_m3;
        } else if (a.rise_time_s > 0.0) {
          const double k = 3.0 / a.rise_time_s;
          d.airway_pressure_pa = a.peep_pa + a.inspiratory_pressure_pa * (1.0 - std::exp(-k * t));
          d.airway_pressure_rate_pa_per_s = a.inspiratory_pressure_pa * k * std::exp(-k * t);
        } else {
          d.airway_pressure_pa = a.peep_pa + a.inspiratory_pressure_pa;
        }
        break;
      default: d.airway_pressure_pa = a.peep_pa;
    }
    return d;
  }
};

// The effort's profile within one period: the spontaneous driver's, at the effort's rate.
struct EffortShape {
  double period, ti, relax;
  explicit EffortShape(const PatientEffort& e)
      : period(1.0 / e.rate_hz),
        ti(period * e.ie_ratio / (1.0 + e.ie_ratio)),
        relax(ti + e.release_share * (period - ti)) {}
  double within(double t) const { return t - period * std::floor(t / period); }
};

void require(bool ok, const std::string& what) {
  if (!ok) throw ValueError(what);
}

}  // namespace

double effort_pressure(const PatientEffort& e, double t) {
  if (!e.active() || t < 0.0) return 0.0;
  const EffortShape s(e);
  const double u = s.within(t);
  if (u < s.ti) return e.amplitude_pa * 0.5 * (1.0 - std::cos(std::numbers::pi * u / s.ti));
  if (u < s.relax) return e.amplitude_pa * 0.5 * (1.0 + std::cos(std::numbers::pi * (u - s.ti) / (s.relax - s.ti)));
  return 0.0;
}

double effort_pressure_rate(const PatientEffort& e, double t) {
  if (!e.active() || t < 0.0) return 0.0;
  const EffortShape s(e);
  const double u = s.within(t);
  if (u < s.ti) return e.amplitude_pa * 0.5 * std::numbers::pi / s.ti * std::sin(std::numbers::pi * u / s.ti);
  if (u < s.relax) {
    const double w = std::numbers::pi / (s.relax - s.ti);
    return -e.amplitude_pa * 0.5 * w * std::sin(w * (u - s.ti));
  }
  return 0.0;
}

double next_effort_boundary(const PatientEffort& e, double t) {
  if (!e.active()) return std::numeric_limits<double>::infinity();
  const EffortShape s(e);
  if (t < 0.0) return 0.0;
  const double start = t - s.within(t);  // the current period's onset
  for (double b : {s.ti, s.relax, s.period}) {
    if (start + b > t) return start + b;
  }
  return start + s.period + s.ti;
}

BreathPlan plan_breath(const Driver& driver) { return std::visit(PlanOf{}, driver); }

Drive drive_at(const Driver& driver, int phase, double t) { return std::visit(DriveOf{phase, t}, driver); }

double peep_of(const Driver& driver) {
  return std::visit(
      [](const auto& d) {
        if constexpr (requires { d.peep_pa; }) return d.peep_pa;
        else return 0.0;
      },
      driver);
}

bool is_ventilator(const Driver& driver) { return !std::holds_alternative<Spontaneous>(driver); }

bool is_simv(const Assisted& a) { return a.mode == AssistMode::simv_volume || a.mode == AssistMode::simv_pressure; }

bool is_bilevel(const Assisted& a) { return a.mode == AssistMode::aprv && a.support_pa > 0.0; }

double default_trigger_window_s(double rate_hz) { return std::min(0.6 / rate_hz, 10.0); }

Assisted simv_breath(const Assisted& a, bool mandatory) {
  if (!is_simv(a) && !is_bilevel(a)) return a;
  Assisted b = a;
  if (mandatory) {
    b.mode = a.mode == AssistMode::simv_volume ? AssistMode::volume : AssistMode::pressure;
    b.cycle = CycleKind::time;
  } else {
    b.mode = AssistMode::pressure_support;
    b.rate_hz = 0.0;  // no backup of its own: the SIMV clock is the driver's
    b.inspiratory_pressure_pa = a.support_pa;
    b.inspiratory_time_s = kLongestSupportedInspiration_s;
  }
  return b;
}

Assisted apnea_backup(const Assisted& a) {
  Assisted b = a;
  b.mode = AssistMode::pressure;
  b.rate_hz = a.backup_rate_hz;
  b.inspiratory_pressure_pa = a.backup_pressure_pa;
  b.inspiratory_time_s = a.backup_inspiratory_time_s;
  b.cycle = CycleKind::time;
  b.apnea_time_s = 0.0;
  return b;
}

double leak_flow(const Leak& leak, double pressure_pa) {
  if (leak.law == LeakLaw::linear) return leak.coefficient * pressure_pa;
  return std::copysign(leak.coefficient * std::sqrt(std::abs(pressure_pa)), pressure_pa);
}

double leak_coefficient(LeakLaw law, double flow_m3_per_s, double pressure_pa) {
  return law == LeakLaw::linear ? flow_m3_per_s / pressure_pa : flow_m3_per_s / std::sqrt(pressure_pa);
}

void validate(const Circuit& c) {
  require(c.tubing_compliance_m3_per_pa >= 0.0 && std::isfinite(c.tubing_compliance_m3_per_pa),
          "the tubing compliance must not be negative");
  require(c.tubing_resistance_pa_s_per_m3 >= 0.0 && std::isfinite(c.tubing_resistance_pa_s_per_m3),
          "the tubing resistance must not be negative");
  require(c.tubing_compliance_m3_per_pa == 0.0 || c.tubing_resistance_pa_s_per_m3 > 0.0,
          "a tubing compliance fills through the tubing: give the tubing resistance too");
  for (const Leak* l : {&c.port, &c.patient})
    require(l->coefficient >= 0.0 && std::isfinite(l->coefficient), "a leak must not be negative");
}

const char* mode_name(const Driver& driver) {
  if (const auto* a = std::get_if<Assisted>(&driver)) {
    static constexpr const char* kAssisted[] = {"vc_ac",   "pc_ac", "cpap_psv", "vc_simv",
                                                "pc_simv", "prvc",  "aprv",     "pav"};
    return kAssisted[static_cast<int>(a->mode)];
  }
  static constexpr const char* kNames[] = {"spontaneous", "volume_control", "pressure_control"};
  return kNames[driver.index()];
}

void validate(const PatientEffort& e) {
  if (!e.active()) {
    require(e.amplitude_pa == 0.0, "the effort's muscle pressure must not be negative");
    return;
  }
  require(e.rate_hz > 0.0 && std::isfinite(e.rate_hz), "the effort's rate must be positive");
  require(e.ie_ratio > 0.0 && std::isfinite(e.ie_ratio), "the effort's I:E ratio must be positive");
  require(e.release_share > 0.0 && e.release_share <= 1.0,
          "the effort's release must be a share of the expiration above 0 and at most 100 %");
}

void validate(const Driver& driver) {
  if (const auto* a = std::get_if<Assisted>(&driver)) {
    const bool support = a->mode == AssistMode::pressure_support || a->mode == AssistMode::pav;
    const bool simv = is_simv(*a);
    if (a->mode == AssistMode::aprv) {
      require((a->cycle == CycleKind::time || a->support_pa > 0.0) && a->volume_limit_m3 == 0.0,
              "APRV changes levels on time only");
      require(a->support_pa >= 0.0, "the pressure support must not be negative");
      require(a->trigger_window_s == 0.0, "APRV's high phases are on the clock: no trigger window");
      if (a->support_pa > 0.0) validate(Driver{simv_breath(*a, false)});
      require(a->inspiratory_pressure_pa > 0.0, "the high pressure must be above the low pressure");
    }
    if (a->mode == AssistMode::pav) {
      require(a->pav_gain > 0.0 && a->pav_gain < 1.0, "the assist gain must lie between 0 and 100 %");
      require(a->pav_resistance_pa_s_per_m3 > 0.0 && std::isfinite(a->pav_resistance_pa_s_per_m3),
              "the assisted resistance must be positive");
      require(a->pav_elastance_pa_per_m3 > 0.0 && std::isfinite(a->pav_elastance_pa_per_m3),
              "the assisted compliance must be positive");
    }
    if (support) require(a->rate_hz == 0.0, "pressure support and PAV have no backup rate");
    else require(a->rate_hz > 0.0 && std::isfinite(a->rate_hz), "the rate must be positive");
    require(a->apnea_time_s == 0.0 || a->mode == AssistMode::pressure_support, "only cpap_psv has an apnea backup");
    if (a->apnea_time_s > 0.0) {
      require(std::isfinite(a->apnea_time_s), "the apnea time must be finite");
      require(a->backup_rate_hz > 0.0 && std::isfinite(a->backup_rate_hz), "the backup rate must be positive");
      require(a->backup_inspiratory_time_s > 0.0 && a->backup_inspiratory_time_s < 1.0 / a->backup_rate_hz,
              "the backup inspiratory time must be positive and shorter than one backup breath (60 / rate)");
      require(a->backup_pressure_pa >= 0.0, "the backup pressure must not be negative");
    }
    if (a->mode == AssistMode::prvc) {
      require(a->tidal_volume_m3 > 0.0, "the target tidal volume must be positive");
      require(a->prvc_step_pa > 0.0 && std::isfinite(a->prvc_step_pa), "the pressure step must be positive");
      require(a->pressure_limit_pa == 0.0 || a->pressure_limit_pa > a->peep_pa + a->inspiratory_pressure_pa,
              "the pressure limit must be above PEEP plus the first breath's inspiratory pressure");
    }
    require(a->peep_pa >= 0.0, "PEEP must not be negative");
    require(a->inspiratory_time_s > 0.0 && (support || a->inspiratory_time_s < 1.0 / a->rate_hz),
            "the inspiratory time must be positive and shorter than one breath (60 / rate)");
    require(a->trigger_threshold > 0.0 && std::isfinite(a->trigger_threshold),
            "the trigger threshold must be positive");
    if (simv) {
      require(a->trigger_window_s > 0.0 && a->trigger_window_s <= 1.0 / a->rate_hz,
              "the trigger window must be positive and at most one cycle (60 / rate)");
      require(a->support_pa >= 0.0, "the pressure support must not be negative");
      require(a->cycle != CycleKind::flow || (a->cycle_fraction > 0.0 && a->cycle_fraction < 1.0) ||
                  (a->cycle_fraction == 0.0 && a->cycle_flow_m3_per_s > 0.0),
              "the flow cycle fraction must lie between 0 and 1 (or the cycle flow be positive)");
      require(a->cycle != CycleKind::volume || a->cycle_volume_m3 > 0.0, "the cycle volume must be positive");
      require(a->rise_time_s < kLongestSupportedInspiration_s,
              "the rise time must be shorter than the longest supported inspiration (3 s)");
      for (bool mandatory : {true, false}) validate(Driver{simv_breath(*a, mandatory)});
      return;
    }
    if (a->mode == AssistMode::volume) {
      require(a->tidal_volume_m3 > 0.0, "the tidal volume must be positive");
      require(a->pause_time_s >= 0.0 && a->pause_time_s < a->inspiratory_time_s,
              "the pause must be shorter than the inspiratory time");
      require(a->cycle == CycleKind::time, "a volume mode cycles on time");
      require(a->pressure_limit_pa == 0.0 || a->pressure_limit_pa > a->peep_pa,
              "the pressure limit must be above PEEP");
    } else {
      require(a->inspiratory_pressure_pa >= 0.0, "the inspiratory pressure must not be negative");
      require(a->rise_time_s >= 0.0, "the rise time must not be negative");
      require(a->rise_time_s < a->inspiratory_time_s, "the rise time must be shorter than the inspiratory time");
      require(a->cycle != CycleKind::flow || (a->cycle_fraction > 0.0 && a->cycle_fraction < 1.0) ||
                  (a->cycle_fraction == 0.0 && a->cycle_flow_m3_per_s > 0.0),
              "the flow cycle fraction must lie between 0 and 1 (or the cycle flow be positive)");
      require(a->cycle != CycleKind::volume || a->cycle_volume_m3 > 0.0, "the cycle volume must be positive");
      require(a->volume_limit_m3 >= 0.0, "the volume limit must not be negative");
    }
    return;
  }
  std::visit(
      [](const auto& d) {
        using T = std::decay_t<decltype(d)>;
        if constexpr (std::is_same_v<T, Assisted>) return;
        else {
          require(d.rate_hz > 0.0 && std::isfinite(d.rate_hz), "the rate must be positive");
          if constexpr (std::is_same_v<T, Spontaneous>) {
            require(d.ie_ratio > 0.0, "the I:E ratio must be positive");
            require(d.amplitude_pa >= 0.0 && d.target_tidal_volume_m3 >= 0.0,
                    "the muscle pressure amplitude and tidal volume must not be negative");
          } else {
            require(d.peep_pa >= 0.0, "PEEP must not be negative");
            require(d.inspiratory_time_s > 0.0 && d.inspiratory_time_s < 1.0 / d.rate_hz,
                    "the inspiratory time must be positive and shorter than one breath (60 / rate)");
            if constexpr (std::is_same_v<T, VolumeControl>) {
              require(d.tidal_volume_m3 > 0.0, "the tidal volume must be positive");
              require(d.pause_time_s >= 0.0 && d.pause_time_s < d.inspiratory_time_s,
                      "the pause must be shorter than the inspiratory time");
            } else {
              require(d.inspiratory_pressure_pa >= 0.0, "the inspiratory pressure must not be negative");
            }
          }
        }
      },
      driver);
}

}  // namespace pneuma::physiology
