#include "pneuma/physiology/drivers.h"

#include <cmath>
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
};

void require(bool ok, const std::string& what) {
  if (!ok) throw ValueError(what);
}

}  // namespace

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

const char* mode_name(const Driver& driver) {
  static constexpr const char* kNames[] = {"spontaneous", "volume_control", "pressure_control"};
  return kNames[driver.index()];
}

void validate(const Driver& driver) {
  std::visit(
      [](const auto& d) {
        require(d.rate_hz > 0.0 && std::isfinite(d.rate_hz), "the rate must be positive");
        using T = std::decay_t<decltype(d)>;
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
      },
      driver);
}

}  // namespace pneuma::physiology
