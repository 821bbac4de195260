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
};

// Volume control: constant inspiratory flow delivering the set tidal volume, an optional
// end-inspiratory pause, then passive expiration to PEEP.
struct VolumeControl {
  double rate_hz = 0.2;
  double tidal_volume_m3 = 0.0;
  double inspiratory_time_s = 1.0;  // flow time + pause time
  double pause_time_s = 0.0;
  double peep_pa = 0.0;
};

// Pressure control: airway pressure PEEP + set pressure during inspiration (a square wave).
struct PressureControl {
  double rate_hz = 0.2;
  double inspiratory_pressure_pa = 0.0;  // above PEEP
  double inspiratory_time_s = 1.0;
  double peep_pa = 0.0;
};

using Driver = std::variant<Spontaneous, VolumeControl, PressureControl>;

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
  bool flow_controlled = false;     // true: total flow is set, airway pressure follows
  double flow_m3_per_s = 0.0;       // when flow_controlled
  double airway_pressure_pa = 0.0;  // when pressure controlled
  double muscle_pressure_pa = 0.0;
  double peep_pa = 0.0;
};

BreathPlan plan_breath(const Driver& driver);
// The drive in `phase` at `t_in_breath` seconds after the breath's start.
Drive drive_at(const Driver& driver, int phase, double t_in_breath_s);
double peep_of(const Driver& driver);
bool is_ventilator(const Driver& driver);
const char* mode_name(const Driver& driver);

// Throws ValueError naming the first setting that cannot work.
void validate(const Driver& driver);

}  // namespace pneuma::physiology
