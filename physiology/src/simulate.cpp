#include "pneuma/physiology/simulate.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cvode_integrator.h"
#include "pneuma/core/error.h"
#include "pneuma/core/units.h"

namespace pneuma::physiology {
namespace {

constexpr int kMaxCompartments = 8;
// The state: each compartment's volume, then with a circuit the volume leaked so far and the gas
// volume the tubing holds (Ct Py).
constexpr int kMaxStates = kMaxCompartments + 2;

// What the right-hand side needs: the mechanics and the drive of the current segment.
// The events an assisted breath watches for, each a root of a smooth function of (t, V).
enum class RootKind {
  trigger_flow,      // flow into the patient - threshold (rising)
  occlude,           // flow at the airway (rising through 0: the patient pulls, the circuit closes)
  trigger_pressure,  // (PEEP - Paw) - threshold in the occluded circuit (rising)
  reopen,            // Paw - PEEP in the occluded circuit (rising: the expiratory valve opens)
  flow_peak,         // dQ/dt (falling through 0: a local maximum of the inspiratory flow)
  flow_cycle,        // Q - fraction * peak flow so far (falling)
  volume_cycle,      // delivered volume - cycle volume (rising)
  volume_limit,      // delivered volume - volume limit (rising)
  pressure_limit,    // Paw - pressure limit (rising)
};
constexpr int kMaxRoots = 4;

// What the right-hand side needs: the mechanics and the drive of the current segment.
struct SegmentContext {
  const Mechanics* mechanics = nullptr;
  const Driver* driver = nullptr;
  int phase = 0;
  double breath_start_s = 0.0;
  const PatientEffort* effort = nullptr;  // null: no effort (always, for the mandatory modes without one)
  double effort_anchor_s = 0.0;
  // Root finding (assisted breaths only).
  std::array<RootKind, kMaxRoots> roots{};
  int root_count = 0;
  double flow_peak = 0.0;            // highest inspiratory flow of the breath so far
  double start_volume = 0.0;         // total volume at the start of inspiration
  bool occluded = false;             // an expiratory hold: both valves closed, whatever the driver
  const Circuit* circuit = nullptr;  // the circuit in force; null when the run has none (no extra states)
  int states = 0;                    // the state's size
};

struct Instant {
  double flow = 0.0;
  double airway_pressure = 0.0;
  double muscle_pressure = 0.0;
  double peep = 0.0;
  double driving_pressure_rate = 0.0;  // d(Paw + Pmus)/dt where the airway pressure is set
  double ventilator_flow = 0.0;        // what the machine delivers (the patient's flow without a circuit)
};

// The root of g, decreasing, near `guess`: bracketed by doubling steps, then bisected to the last bit.
template <class F>
double decreasing_root(const F& g, double guess) {
  double lo = guess, hi = guess, step = 100.0;  // Pa
  if (g(guess) > 0.0) {
    for (int i = 0; i < 64 && g(hi) > 0.0; ++i, step *= 2.0) {
      lo = hi;
      hi = guess + step;
    }
  } else {
    for (int i = 0; i < 64 && !(g(lo) > 0.0); ++i, step *= 2.0) {
      hi = lo;
      lo = guess - step;
    }
  }
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (mid <= lo || mid >= hi) break;
    (g(mid) > 0.0 ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// The drive through the circuit: the Y-piece pressure Py the patient sees, from the tubing's gas
// volume (a tubing compliance), from the set pressure (none, no tubing resistance), or else where
// the flows balance: what enters the Y-piece = the patient's flow + the leaks.
Instant through_circuit(const SegmentContext& c, const Drive& d, const double* y, double* ydot, Instant out) {
  const Mechanics& m = *c.mechanics;
  const Circuit& k = *c.circuit;
  const std::size_t n = m.compartments.size();
  const double pmus = d.muscle_pressure_pa;
  const auto patient = [&](double py) { return compartment_flows(m, py + pmus, y, ydot); };
  const auto leaks = [&](double py) { return leak_flow(k.port, py) + leak_flow(k.patient, py); };
  const auto inflow = [&](double py) {
    return d.flow_controlled ? d.flow_m3_per_s : (d.airway_pressure_pa - py) / k.tubing_resistance_pa_s_per_m3;
  };
  double py = d.airway_pressure_pa;
  if (k.tubing_compliance_m3_per_pa > 0.0) {
    py = y[n + 1] / k.tubing_compliance_m3_per_pa;
  } else if (d.flow_controlled || k.tubing_resistance_pa_s_per_m3 > 0.0) {
    const double guess =
        d.flow_controlled ? driving_pressure_for_flow(m, d.flow_m3_per_s, y) - pmus : d.airway_pressure_pa;
    py = decreasing_root([&](double p) { return inflow(p) - patient(p) - leaks(p); }, guess);
  }
  out.flow = patient(py);
  const double leak = leaks(py);
  out.ventilator_flow = k.tubing_compliance_m3_per_pa > 0.0 ? inflow(py) : out.flow + leak;
  out.airway_pressure = py;
  ydot[n] = leak;
  ydot[n + 1] = out.ventilator_flow - out.flow - leak;
  return out;
}

double total(const double* v, std::size_t n);

// PAV's airway pressure: the p with p = PEEP + gain (R_set Q(p) + E_set dV), dV the volume since
// the breath's start. Q rises with p at the slope 1 / R (the patient's inspiratory resistance), so
// p - PEEP - gain (...) rises at 1 - gain R_set / R > 0 (validated): secant steps, the first exact
// for linear mechanics; NaN (CVODE retries) if the assist would run away.
double proportional_assist_pressure(const SegmentContext& c, const Drive& d, const double* volumes, double* flows) {
  const Mechanics& m = *c.mechanics;
  const double dv = total(volumes, m.compartments.size()) - c.start_volume;
  const auto excess = [&](double p) {
    const double q = compartment_flows(m, p + d.muscle_pressure_pa, volumes, flows);
    return p - d.peep_pa - d.assist_gain * (d.assist_resistance_pa_s_per_m3 * q + d.assist_elastance_pa_per_m3 * dv);
  };
  double p0 = d.peep_pa, f0 = excess(p0);
  double p1 = p0 + 100.0, f1 = excess(p1);  // 100 Pa: about 1 cmH2O
  for (int i = 0; i < 8 && f1 != 0.0; ++i) {
    const double slope = (f1 - f0) / (p1 - p0);
    if (!(slope > 0.0)) return std::numeric_limits<double>::quiet_NaN();
    const double p2 = p1 - f1 / slope;
    p0 = p1;
    f0 = f1;
    p1 = p2;
    f1 = excess(p1);
    if (std::abs(p1 - p0) <= 1e-12 * std::max(1.0, std::abs(p1))) break;
  }
  return p1;
}

// Flows into every compartment at (t, volumes); returns the pressures at that instant.
Instant evaluate(const SegmentContext& c, double t, const double* volumes, double* flows) {
  Drive d = drive_at(*c.driver, c.phase, t - c.breath_start_s);
  if (c.effort) {
    d.muscle_pressure_pa += effort_pressure(*c.effort, t - c.effort_anchor_s);
    d.airway_pressure_rate_pa_per_s += effort_pressure_rate(*c.effort, t - c.effort_anchor_s);
  }
  if (c.occluded) {
    d.flow_controlled = true;
    d.flow_m3_per_s = 0.0;
  }
  Instant out;
  out.muscle_pressure = d.muscle_pressure_pa;
  out.peep = d.peep_pa;
  out.driving_pressure_rate = d.airway_pressure_rate_pa_per_s;
  if (d.assist_gain > 0.0 && !d.flow_controlled)
    d.airway_pressure_pa = proportional_assist_pressure(c, d, volumes, flows);
  if (c.circuit) return through_circuit(c, d, volumes, flows, out);
  if (d.flow_controlled) {
    const double pd = driving_pressure_for_flow(*c.mechanics, d.flow_m3_per_s, volumes);
    out.flow = compartment_flows(*c.mechanics, pd, volumes, flows);
    out.airway_pressure = pd - d.muscle_pressure_pa;
  } else {
    const double pd = d.airway_pressure_pa + d.muscle_pressure_pa;
    out.flow = compartment_flows(*c.mechanics, pd, volumes, flows);
    out.airway_pressure = d.airway_pressure_pa;
  }
  out.ventilator_flow = out.flow;
  return out;
}

int right_hand_side(double t, N_Vector y, N_Vector ydot, void* user_data) {
  const auto& c = *static_cast<const SegmentContext*>(user_data);
  const double* v = N_VGetArrayPointer(y);
  double* q = N_VGetArrayPointer(ydot);
  evaluate(c, t, v, q);
  const auto n = c.mechanics->compartments.size();
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(q[i])) return 1;  // outside the sigmoid's domain: CVODE retries a smaller step
  }
  return 0;
}

// CVODE's root functions for the assisted breaths' events (see RootKind). Each is smooth within
// a segment, so CVODE locates its zero to its root tolerance (~100 ulp of t): trigger and cycle
// instants are found exactly, not at the next output sample.
// d(ventilator flow)/dt along the trajectory through (t, y): a central difference (the circuit's
// flow has no closed-form derivative; without one, flow_rate_of_change gives it exactly).
double ventilator_flow_rate(const SegmentContext& c, double t, const double* y) {
  std::array<double, kMaxStates> dy{}, ahead{}, behind{}, scratch{};
  evaluate(c, t, y, dy.data());
  constexpr double h = 1e-6;  // s
  for (int i = 0; i < c.states; ++i) {
    ahead[static_cast<std::size_t>(i)] = y[i] + h * dy[static_cast<std::size_t>(i)];
    behind[static_cast<std::size_t>(i)] = y[i] - h * dy[static_cast<std::size_t>(i)];
  }
  return (evaluate(c, t + h, ahead.data(), scratch.data()).ventilator_flow -
          evaluate(c, t - h, behind.data(), scratch.data()).ventilator_flow) /
         (2.0 * h);
}

int root_function(double t, N_Vector y, double* g, void* user_data) {
  const auto& c = *static_cast<const SegmentContext*>(user_data);
  const double* v = N_VGetArrayPointer(y);
  std::array<double, kMaxStates> q{};
  const Instant now = evaluate(c, t, v, q.data());
  const auto& a = std::get<Assisted>(*c.driver);
  const double delivered = total(v, c.mechanics->compartments.size()) - c.start_volume;
  for (int i = 0; i < c.root_count; ++i) {
    switch (c.roots[static_cast<std::size_t>(i)]) {
      case RootKind::trigger_flow: g[i] = now.ventilator_flow - a.trigger_threshold; break;
      case RootKind::occlude: g[i] = now.ventilator_flow; break;
      case RootKind::trigger_pressure: g[i] = a.peep_pa - now.airway_pressure - a.trigger_threshold; break;
      case RootKind::reopen: g[i] = now.airway_pressure - a.peep_pa; break;
      case RootKind::flow_peak:
        g[i] = c.circuit || a.mode == AssistMode::pav
                   ? ventilator_flow_rate(c, t, v)
                   : flow_rate_of_change(*c.mechanics, now.driving_pressure_rate, v, q.data());
        break;
      case RootKind::flow_cycle:
        g[i] = now.ventilator_flow - a.cycle_fraction * c.flow_peak - a.cycle_flow_m3_per_s;
        break;
      case RootKind::volume_cycle: g[i] = delivered - a.cycle_volume_m3; break;
      case RootKind::volume_limit: g[i] = delivered - a.volume_limit_m3; break;
      case RootKind::pressure_limit: g[i] = now.airway_pressure - a.pressure_limit_pa; break;
    }
  }
  return 0;
}

int root_direction(RootKind k) { return k == RootKind::flow_peak || k == RootKind::flow_cycle ? -1 : 1; }

std::string fmt_seconds(double t) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%g", t);
  return buffer;
}

double total(const double* v, std::size_t n) {
  double s = 0.0;
  for (std::size_t i = 0; i < n; ++i) s += v[i];
  return s;
}

class Simulation {
 public:
  Simulation(const Protocol& protocol, const SimulationOptions& options)
      : protocol_(protocol),
        options_(options),
        n_(protocol.settings.front().mechanics.compartments.size()),
        extra_(std::any_of(protocol.settings.begin(), protocol.settings.end(),
                           [](const Setting& s) { return s.circuit.active(); })
                   ? 2
                   : 0),
        integrator_(static_cast<int>(n_ + extra_), right_hand_side, &context_, options.solver) {
    context_.states = static_cast<int>(n_ + extra_);
    // An effort repeats from the time it was last changed.
    for (std::size_t i = 0; i < protocol_.settings.size(); ++i) {
      const bool same = i > 0 && protocol_.settings[i].effort == protocol_.settings[i - 1].effort;
      effort_anchor_.push_back(same ? effort_anchor_.back() : protocol_.settings[i].start_time_s);
    }
  }

  SimulationResult run() {
    SimulationResult result;
    for (const auto& c : protocol_.settings.front().mechanics.compartments) result.compartment_names.push_back(c.name);
    result.series.compartment_volume_m3.resize(n_);
    series_ = options_.output_rate_hz > 0.0 ? &result.series : nullptr;
    if (series_) reserve(result.series);

    // Start at rest: each compartment at the volume its first PEEP holds.
    std::array<double, kMaxStates> y{};
    const Setting& first = protocol_.settings.front();
    for (std::size_t i = 0; i < n_; ++i) {
      y[i] = volume_at_pressure(first.mechanics.compartments[i].elasticity, peep_of(first.driver));
    }
    if (extra_) y[n_ + 1] = first.circuit.tubing_compliance_m3_per_pa * peep_of(first.driver);
    double t = 0.0;
    const double end = options_.duration_s;
    while (t < end) {
      const std::size_t setting = setting_at(t);
      current_driver_ = resolved_driver(setting);
      if (std::holds_alternative<Assisted>(current_driver_)) {
        if (!assisted_breath(t, y.data(), result)) break;
        continue;
      }
      pending_.reset();
      simv_due_ = std::numeric_limits<double>::quiet_NaN();
      const Driver& driver = current_driver_;
      const BreathPlan plan = plan_breath(driver);
      BreathMetrics breath;
      breath.start_s = t;
      breath.mode = mode_name(driver);
      breath.peep_pa = peep_of(driver);
      if (is_ventilator(driver)) {
        breath.trigger = "time";
        breath.cycle = "time";
        breath.breath_type = "mandatory";
      }
      if (const auto* s = std::get_if<Spontaneous>(&driver)) breath.muscle_amplitude_pa = s->amplitude_pa;
      const double start_volume = total(y.data(), n_);
      begin_breath(start_volume, y.data());
      if (const auto* pc = std::get_if<PressureControl>(&driver))
        breath.set_inspiratory_pressure_pa = pc->inspiratory_pressure_pa;
      if (const auto* sp = std::get_if<Spontaneous>(&protocol_.settings[setting].driver))
        breath.set_tidal_volume_m3 = sp->target_tidal_volume_m3;
      else if (const auto* vc = std::get_if<VolumeControl>(&driver)) breath.set_tidal_volume_m3 = vc->tidal_volume_m3;
      double end_inspiration_volume = start_volume;
      double peak_airway = -std::numeric_limits<double>::infinity();
      double peak_drive = -std::numeric_limits<double>::infinity();
      bool complete = true;

      context_.driver = &driver;
      context_.breath_start_s = t;
      context_.root_count = 0;
      for (int p = 0; p < plan.count && complete; ++p) {
        context_.phase = p;
        const double phase_end = breath.start_s + plan.phases[static_cast<std::size_t>(p)].end_s;
        Instant last;
        // Flow starvation: the patient pulling against the set flow (volume control's flow phase).
        starvation_ = p == 0 && std::holds_alternative<VolumeControl>(driver);
        while (t < phase_end) {
          const double segment_end = std::min({phase_end, next_change_after(t), end, next_effort_break(t)});
          use_setting_at(t);
          integrate_segment(t, segment_end, y.data(), peak_airway, peak_drive, last);
          t = segment_end;
          if (t >= end && t < phase_end) {
            complete = false;
            break;
          }
        }
        starvation_ = false;
        if (!complete) break;
        if (plan.phases[static_cast<std::size_t>(p)].inspiratory &&
            (p + 1 == plan.count || !plan.phases[static_cast<std::size_t>(p) + 1].inspiratory)) {
          end_inspiration_volume = total(y.data(), n_);
          end_inspiration(breath, y.data());
          breath.plateau_pressure_pa = alveolar_pressure(*context_.mechanics, last.airway_pressure, last.flow);
          if (is_ventilator(driver)) breath.inspiratory_time_s = plan.phases[static_cast<std::size_t>(p)].end_s;
        }
      }
      if (!complete) break;
      if (is_ventilator(driver) && !expiratory_hold(t, y.data(), breath, peak_airway, peak_drive)) break;
      breath.inspired_volume_m3 = end_inspiration_volume - start_volume;
      breath.peak_pressure_pa = peak_airway;
      finish_breath(breath, t, peak_drive, y.data(), result);
    }
    // A sample exactly at the end time belongs to no segment: record it from the final state.
    if (series_ && next_output_ < output_count_) record(end, y.data());
    count_triggers(result);
    result.stats = integrator_.stats();
    return result;
  }

 private:
  // What started a breath that an assisted expiration has ended.
  struct Start {
    const char* trigger = "time";
    double delay_s = std::numeric_limits<double>::quiet_NaN();
    bool patient = false;
  };
  // What stopped an assisted phase.
  enum class Stopped { time, root, end_of_run, driver_change };

  std::size_t setting_at(double t) const {
    std::size_t s = 0;
    for (std::size_t i = 1; i < protocol_.settings.size(); ++i) {
      if (protocol_.settings[i].start_time_s <= t) s = i;
    }
    return s;
  }

  double next_change_after(double t) const {
    for (const Setting& s : protocol_.settings) {
      if (s.start_time_s > t) return s.start_time_s;
    }
    return std::numeric_limits<double>::infinity();
  }

  // The next boundary of the patient's effort profile (its Pmus is smooth between them).
  double next_effort_break(double t) const {
    const std::size_t s = setting_at(t);
    const PatientEffort& e = protocol_.settings[s].effort;
    if (!e.active()) return std::numeric_limits<double>::infinity();
    // Strictly after t also once the anchor is added back: anchor + (t - anchor) can round to
    // below t, and a boundary at t would stop the integration there for ever.
    const double anchor = effort_anchor_[s];
    double relative = t - anchor, boundary = t;
    while (boundary <= t) {
      relative = next_effort_boundary(e, relative);
      boundary = anchor + relative;
    }
    return boundary;
  }

  // The mechanics and the patient's effort in force at t.
  void use_setting_at(double t) {
    const std::size_t s = setting_at(t);
    context_.mechanics = &protocol_.settings[s].mechanics;
    context_.effort = protocol_.settings[s].effort.active() ? &protocol_.settings[s].effort : nullptr;
    context_.effort_anchor_s = effort_anchor_[s];
    context_.circuit = extra_ ? &protocol_.settings[s].circuit : nullptr;
  }

  // The volume the ventilator has delivered since the run began, up to a constant: the patient's,
  // the leaks' and the tubing's (the patient's alone without a circuit).
  double ventilator_volume(const double* y) const {
    const double v = total(y, n_);
    return extra_ ? v + y[n_] + y[n_ + 1] : v;
  }

  void begin_breath(double start_volume, const double* y) {
    min_volume_ = max_volume_ = start_volume;
    starvation_dip_ = std::numeric_limits<double>::quiet_NaN();
    paw_integral_ = 0.0;
    start_delivered_ = ventilator_volume(y);
  }

  // VTi: what the ventilator delivered since the breath began.
  void end_inspiration(BreathMetrics& breath, const double* y) {
    end_inspiration_delivered_ = ventilator_volume(y);
    if (is_ventilator(current_driver_)) breath.vti_m3 = end_inspiration_delivered_ - start_delivered_;
  }

  // The alarms a completed ventilator breath raises (the limits in force at its start).
  void check_alarms(BreathMetrics& breath, const SimulationResult& result) const {
    const Alarms& limits = protocol_.settings[setting_at(breath.start_s)].alarms;
    const auto raise = [&](const char* name) {
      if (!breath.alarms.empty()) breath.alarms += ';';
      breath.alarms += name;
    };
    if (limits.high_pressure_pa > 0.0 && breath.peak_pressure_pa > limits.high_pressure_pa) raise("high_pressure");
    if (limits.low_pressure_pa > 0.0 && breath.peak_pressure_pa < limits.low_pressure_pa) raise("low_pressure");
    if (limits.low_tidal_volume_m3 > 0.0 && breath.vte_m3 < limits.low_tidal_volume_m3) raise("low_tidal_volume");
    if (limits.low_minute_volume_m3_per_s > 0.0) {
      // The volume breathed out over the last minute (over the run so far during its first minute).
      const double end = breath.start_s + breath.duration_s, from = end - 60.0;
      double expired = breath.vte_m3;
      for (auto b = result.breaths.rbegin(); b != result.breaths.rend() && b->start_s + b->duration_s > from; ++b) {
        if (!std::isnan(b->vte_m3)) expired += b->vte_m3;
      }
      if (expired / std::min(60.0, end) < limits.low_minute_volume_m3_per_s) raise("low_minute_volume");
    }
    if (limits.disconnection_leak_fraction > 0.0 && breath.vti_m3 > 0.0 &&
        (breath.vti_m3 - breath.vte_m3) / breath.vti_m3 >= limits.disconnection_leak_fraction)
      raise("disconnection");
  }

  // The metrics every breath has, at its end t with state y.
  void finish_breath(BreathMetrics& breath, double t, double peak_drive, const double* y, SimulationResult& result) {
    breath.duration_s = t - breath.start_s;
    breath.tidal_volume_m3 = max_volume_ - min_volume_;
    breath.minute_ventilation_m3_per_s = breath.tidal_volume_m3 / breath.duration_s;
    breath.dynamic_compliance_m3_per_pa = peak_drive - breath.peep_pa > 0.0
                                              ? breath.tidal_volume_m3 / (peak_drive - breath.peep_pa)
                                              : std::numeric_limits<double>::quiet_NaN();
    breath.end_expiratory_volume_m3 = total(y, n_);
    breath.mean_airway_pressure_pa = paw_integral_ / breath.duration_s;
    if (is_ventilator(current_driver_)) {
      breath.vte_m3 = end_inspiration_delivered_ - ventilator_volume(y);
      check_alarms(breath, result);
      cycling(breath);
      breath.flow_starvation_pa = starvation_dip_;
      breath.flow_starvation = starvation_dip_ > kFlowStarvation_pa;
    }
    // An end-expiratory hold: the pressure measured at its end when one was made (expiratory_hold),
    // else the pressure the recoil holds with the airway occluded at once (no redistribution).
    if (!std::isnan(breath.total_peep_pa)) breath.intrinsic_peep_pa = breath.total_peep_pa - breath.peep_pa;
    else if (is_ventilator(current_driver_))
      breath.intrinsic_peep_pa = driving_pressure_for_flow(*context_.mechanics, 0.0, y) - breath.peep_pa;
    result.breaths.push_back(breath);
  }

  // Cycling against the effort in progress at the end of inspiration (the latest onset at or
  // before it), when its neural inspiration (the effort's rise) overlaps the breath's inspiration.
  // APRV's high phases have no cycle to judge: its levels change on the clock, the patient
  // breathes at both (BiLevel's supported breaths at P_low are judged).
  void cycling(BreathMetrics& breath) const {
    if (const auto* a = std::get_if<Assisted>(&current_driver_);
        a && a->mode == AssistMode::aprv && std::string_view(breath.breath_type) == "mandatory")
      return;
    const double cycle = breath.start_s + breath.inspiratory_time_s;
    const std::size_t s = setting_at(cycle);
    const PatientEffort& e = protocol_.settings[s].effort;
    if (!e.active() || cycle < effort_anchor_[s]) return;
    const double period = 1.0 / e.rate_hz, neural = period * e.ie_ratio / (1.0 + e.ie_ratio);
    const double onset = effort_anchor_[s] + period * std::floor((cycle - effort_anchor_[s]) / period);
    if (onset + neural <= breath.start_s) return;  // it ended before the breath began
    breath.cycle_delay_s = cycle - (onset + neural);
    breath.early_cycling = breath.cycle_delay_s < 0.0;
    breath.late_cycling = breath.cycle_delay_s > kLateCyclingShare * neural;
  }

  // Flow starvation: how far the airway pressure at (t, y) lies below the passive lung's (the
  // same state and drive, the effort removed); tracked only while starvation_ is set.
  void track_starvation(double t, const double* y, double airway_pressure) {
    if (!starvation_ || !context_.effort) return;
    SegmentContext passive = context_;
    passive.effort = nullptr;
    std::array<double, kMaxStates> q{};
    const double dip = evaluate(passive, t, y, q.data()).airway_pressure - airway_pressure;
    starvation_dip_ = std::isnan(starvation_dip_) ? dip : std::max(starvation_dip_, dip);
  }

  // When an assisted expiration that began a breath at `breath_start` ends on the clock: the
  // backup timer (VC-AC, PC-AC), the next scheduled mandatory breath (SIMV), never (CPAP).
  double deadline(const Assisted& a, double breath_start) {
    if (a.apnea_time_s > 0.0) return breath_start + a.apnea_time_s;
    if (is_simv(a) || is_bilevel(a)) {
      if (std::isnan(simv_due_)) simv_due_ = breath_start + 1.0 / a.rate_hz;  // a switch into SIMV
      return simv_due_;
    }
    return a.rate_hz > 0.0 ? breath_start + 1.0 / a.rate_hz : std::numeric_limits<double>::infinity();
  }

  // SIMV: whether the breath starting at t is the cycle's mandatory one, advancing the schedule.
  // The first breath of the mode, a machine start (the scheduled time reached) and the first
  // patient trigger within the window before the scheduled time are mandatory.
  bool simv_mandatory(const Assisted& a, double t, const Start& start) {
    const double period = 1.0 / a.rate_hz;
    if (std::isnan(simv_due_)) {
      simv_due_ = t + period;
      return true;
    }
    if (start.patient && t < simv_due_ - a.trigger_window_s) return false;
    simv_due_ += period;
    while (simv_due_ <= t) simv_due_ += period;
    return true;
  }

  // An expiratory hold due at the end of this breath (the first action at or before t not yet
  // made): both valves closed for its duration, the patient's effort going on; the airway
  // pressure at its end is the total PEEP. The next breath waits for it. Returns false when the
  // run ends during the hold.
  bool expiratory_hold(double& t, double* y, BreathMetrics& breath, double& peak_airway, double& peak_drive) {
    if (next_hold_ >= protocol_.holds.size() || protocol_.holds[next_hold_].at_s > t) return true;
    const double duration = protocol_.holds[next_hold_++].duration_s;
    const double until = t + duration, end = options_.duration_s;
    context_.occluded = true;
    context_.root_count = 0;
    Instant last;
    while (t < until) {
      if (t >= end) break;
      const double b = std::min({until, next_change_after(t), end, next_effort_break(t)});
      use_setting_at(t);
      integrate_segment(t, b, y, peak_airway, peak_drive, last);
      t = b;
    }
    context_.occluded = false;
    if (t < until) return false;
    breath.expiratory_hold_s = duration;
    breath.total_peep_pa = last.airway_pressure;
    return true;
  }

  // One assisted breath from t (its trigger in pending_, or none: the first of its mode). Returns
  // false when the run ends before the breath does (the incomplete breath is not reported).
  bool assisted_breath(double& t, double* y, SimulationResult& result) {
    Assisted a = std::get<Assisted>(current_driver_);
    if (a.apnea_time_s <= 0.0) apnea_ = false;
    if (apnea_) {
      a = apnea_backup(a);  // until the patient triggers
      current_driver_ = a;
    }
    context_.driver = &current_driver_;
    if (!is_simv(a) && !is_bilevel(a)) simv_due_ = std::numeric_limits<double>::quiet_NaN();
    if (a.mode != AssistMode::prvc) prvc_pressure_ = std::numeric_limits<double>::quiet_NaN();
    if (!pending_) {
      if (a.mode == AssistMode::pressure_support || a.mode == AssistMode::pav) {
        // No backup rate: wait at CPAP for the patient's first trigger (not a breath), or the apnea time.
        context_.breath_start_s = t;
        double unused_peak = -std::numeric_limits<double>::infinity(), unused_drive = unused_peak;
        min_volume_ = max_volume_ = total(y, n_);
        const Stopped s = expiration(t, y, a, deadline(a, t), unused_peak, unused_drive);
        if (s == Stopped::end_of_run) return false;
        if (s == Stopped::driver_change) return true;
        if (s == Stopped::time) {
          apnea_ = apnea_alarm_ = true;
          pending_ = Start{};
          return true;
        }
      } else {
        pending_ = Start{};
      }
    }
    // The breath it gives: SIMV's mandatory or spontaneous one, or the mode's own.
    const bool mandatory = is_simv(a) || is_bilevel(a)
                               ? simv_mandatory(a, t, *pending_)
                               : a.mode != AssistMode::pressure_support && a.mode != AssistMode::pav;
    Assisted shape = simv_breath(a, mandatory);
    if (a.mode == AssistMode::aprv && mandatory) shape.mode = AssistMode::pressure;  // P_high for T_high, on the clock
    if (a.mode == AssistMode::prvc) {
      if (std::isnan(prvc_pressure_)) prvc_pressure_ = a.inspiratory_pressure_pa;  // the test breath
      shape.mode = AssistMode::pressure;
      shape.inspiratory_pressure_pa = prvc_pressure_;
    }
    current_driver_ = shape;
    BreathMetrics breath;
    breath.start_s = t;
    breath.mode = mode_name(Driver{a});
    breath.breath_type = mandatory ? "mandatory" : "spontaneous";
    breath.peep_pa = a.peep_pa;
    breath.trigger = pending_->trigger;
    breath.trigger_delay_s = pending_->delay_s;
    if (apnea_alarm_) breath.alarms = "apnea";
    apnea_alarm_ = false;
    if (shape.mode == AssistMode::volume || a.mode == AssistMode::prvc) breath.set_tidal_volume_m3 = a.tidal_volume_m3;
    if (shape.mode != AssistMode::volume && shape.mode != AssistMode::pav)
      breath.set_inspiratory_pressure_pa = shape.inspiratory_pressure_pa;
    pending_.reset();
    const double start_volume = total(y, n_);
    begin_breath(start_volume, y);
    context_.breath_start_s = t;
    context_.start_volume = start_volume;
    double peak_airway = -std::numeric_limits<double>::infinity();
    double peak_drive = -std::numeric_limits<double>::infinity();
    Instant last;

    // Inspiration.
    breath.cycle = "time";
    if (shape.mode == AssistMode::volume) {
      const double flow_end = breath.start_s + shape.inspiratory_time_s - shape.pause_time_s;
      std::vector<RootKind> roots;
      if (shape.pressure_limit_pa > 0.0) roots.push_back(RootKind::pressure_limit);
      int root = -1;
      starvation_ = true;
      const Stopped s = phase(kAssistFlow, t, flow_end, y, roots, false, peak_airway, peak_drive, last, root);
      starvation_ = false;
      if (s == Stopped::end_of_run) return false;
      if (s == Stopped::root) {
        breath.cycle = "pressure_limit";
      } else if (shape.pause_time_s > 0.0) {
        const Stopped p = phase(kAssistPause, t, breath.start_s + shape.inspiratory_time_s, y, {}, false, peak_airway,
                                peak_drive, last, root);
        if (p == Stopped::end_of_run) return false;
      }
    } else {
      std::vector<RootKind> roots;
      if (shape.cycle == CycleKind::flow) roots = {RootKind::flow_peak, RootKind::flow_cycle};
      if (shape.cycle == CycleKind::volume) roots.push_back(RootKind::volume_cycle);
      if (shape.volume_limit_m3 > 0.0) roots.push_back(RootKind::volume_limit);
      if (shape.mode == AssistMode::pav && shape.pressure_limit_pa > 0.0) roots.push_back(RootKind::pressure_limit);
      std::array<double, kMaxStates> q{};
      context_.phase = kAssistPressure;
      use_setting_at(t);
      context_.flow_peak = evaluate(context_, t, y, q.data()).ventilator_flow;  // the flow just after the step
      const double time_cycle = breath.start_s + shape.inspiratory_time_s;
      for (;;) {
        int root = -1;
        const Stopped s = phase(kAssistPressure, t, time_cycle, y, roots, false, peak_airway, peak_drive, last, root);
        if (s == Stopped::end_of_run) return false;
        if (s == Stopped::time) break;
        const RootKind k = roots[static_cast<std::size_t>(root)];
        if (k == RootKind::flow_peak) {
          context_.flow_peak = std::max(context_.flow_peak, last.ventilator_flow);
          continue;
        }
        breath.cycle = k == RootKind::flow_cycle     ? "flow"
                       : k == RootKind::volume_cycle ? "volume"
                       : k == RootKind::volume_limit ? "volume_limit"
                                                     : "pressure_limit";
        break;
      }
    }
    breath.inspiratory_time_s = t - breath.start_s;
    breath.inspired_volume_m3 = total(y, n_) - start_volume;
    breath.plateau_pressure_pa = alveolar_pressure(*context_.mechanics, last.airway_pressure, last.flow);
    end_inspiration(breath, y);
    if (a.mode == AssistMode::prvc) prvc_pressure_ = next_prvc_pressure(a, breath.vti_m3);

    // Expiration, until the next trigger, the backup timer or SIMV's next mandatory breath.
    current_driver_ = a;
    const Stopped s = expiration(t, y, a, deadline(a, breath.start_s), peak_airway, peak_drive, breath.start_s);
    if (s == Stopped::end_of_run) return false;
    if (s == Stopped::time) {
      pending_ = Start{};
      // A cpap_psv expiration that outlasts the apnea time: backup breaths from now on.
      if (const auto* now = std::get_if<Assisted>(&current_driver_); now && now->apnea_time_s > 0.0)
        apnea_ = apnea_alarm_ = true;
    }
    if (s == Stopped::root) apnea_ = false;  // the patient breathes: back to the set mode
    if (next_hold_ < protocol_.holds.size() && protocol_.holds[next_hold_].at_s <= t) {
      if (!expiratory_hold(t, y, breath, peak_airway, peak_drive)) return false;
      // After the hold the machine starts over: a mandatory breath at once (CPAP: the patient's).
      // A trigger that the hold preempted started nothing: its effort counts as missed.
      if (s == Stopped::root) patient_triggers_.pop_back();
      pending_.reset();
      simv_due_ = std::numeric_limits<double>::quiet_NaN();
    }
    breath.peak_pressure_pa = peak_airway;
    finish_breath(breath, t, peak_drive, y, result);
    return true;
  }

  // PRVC's pressure for the next breath: the step the breath's compliance (VTi / dP) asks for to
  // reach the target, bounded by the step and the pressure limit.
  double next_prvc_pressure(const Assisted& a, double vti) const {
    const double p = prvc_pressure_;
    const double wanted = vti > 0.0 ? p * (a.tidal_volume_m3 / vti - 1.0) : a.prvc_step_pa;
    const double highest =
        a.pressure_limit_pa > 0.0 ? a.pressure_limit_pa - a.peep_pa : std::numeric_limits<double>::infinity();
    return std::clamp(p + std::clamp(wanted, -a.prvc_step_pa, a.prvc_step_pa), 0.0, highest);
  }

  // Expiration at PEEP from t until a patient trigger (pending_ set), `backup` (Stopped::time),
  // a new driver (Stopped::driver_change) or the run's end.
  // In a breath (`breath_start` given), new assist settings take over the expiration at once
  // (trigger, PEEP, backup rate counted from the breath's start); a mandatory or spontaneous
  // driver ends the breath.
  Stopped expiration(double& t, double* y, Assisted a, double backup, double& peak_airway, double& peak_drive,
                     std::optional<double> breath_start = std::nullopt) {
    Instant last;
    // APRV's release is on the clock: the patient breathes at P_low through the demand valve.
    // BiLevel watches for the patient's triggers at P_low, to support them.
    const auto watches = [](const Assisted& x) { return x.mode != AssistMode::aprv || is_bilevel(x); };
    bool by_flow = a.trigger == TriggerKind::flow;
    int phase_kind = kAssistExpiration;
    // Pressure trigger: a patient already pulling when expiration begins finds the circuit closed.
    if (!by_flow && watches(a)) {
      std::array<double, kMaxStates> q{};
      context_.phase = kAssistExpiration;
      use_setting_at(t);
      if (evaluate(context_, t, y, q.data()).flow >= 0.0) phase_kind = kAssistOccluded;
    }
    for (;;) {
      std::vector<RootKind> roots;
      if (!watches(a)) roots = {};
      else if (by_flow) roots = {RootKind::trigger_flow};
      else if (phase_kind == kAssistExpiration) roots = {RootKind::occlude};
      else roots = {RootKind::trigger_pressure, RootKind::reopen};
      int root = -1;
      const Stopped s = phase(phase_kind, t, backup, y, roots, true, peak_airway, peak_drive, last, root);
      if (s == Stopped::driver_change && breath_start) {
        const Driver& next = protocol_.settings[setting_at(t)].driver;
        if (const auto* assisted = std::get_if<Assisted>(&next)) {
          current_driver_ = next;
          a = *assisted;
          by_flow = a.trigger == TriggerKind::flow;
          if (by_flow || !watches(a)) phase_kind = kAssistExpiration;
          backup = deadline(a, *breath_start);
          if (backup <= t) return Stopped::time;
          continue;
        }
      }
      if (s != Stopped::root) return s;
      const RootKind k = roots[static_cast<std::size_t>(root)];
      if (k == RootKind::occlude) {
        phase_kind = kAssistOccluded;
      } else if (k == RootKind::reopen) {
        phase_kind = kAssistExpiration;
      } else {
        Start start;
        start.trigger = by_flow ? "patient_flow" : "patient_pressure";
        start.patient = true;
        const std::size_t setting = setting_at(t);
        const PatientEffort& e = protocol_.settings[setting].effort;
        if (e.active()) {
          const double since = t - effort_anchor_[setting], period = 1.0 / e.rate_hz;
          start.delay_s = since - period * std::floor(since / period);
        }
        pending_ = start;
        patient_triggers_.push_back(t);
        return Stopped::root;
      }
    }
  }

  // Integrates one assisted phase from t to `until` (or an event among `roots`), split at
  // setting changes and effort boundaries; the integrator restarts at each (the drive is smooth
  // only between them). With `driver_change`, a new driver taking effect ends the phase.
  Stopped phase(int kind, double& t, double until, double* y, const std::vector<RootKind>& roots, bool driver_change,
                double& peak_airway, double& peak_drive, Instant& last, int& root) {
    const double end = options_.duration_s;
    context_.phase = kind;
    context_.root_count = static_cast<int>(roots.size());
    std::copy(roots.begin(), roots.end(), context_.roots.begin());
    while (t < until) {
      if (t >= end) return Stopped::end_of_run;
      const double b = std::min({until, next_change_after(t), end, next_effort_break(t)});
      use_setting_at(t);
      const std::size_t before = setting_at(t);
      t = integrate_segment(t, b, y, peak_airway, peak_drive, last, &root);
      if (root >= 0) return Stopped::root;
      if (t >= until) break;
      if (t >= end) return Stopped::end_of_run;
      const std::size_t after = setting_at(t);
      if (driver_change && after != before && !(protocol_.settings[after].driver == protocol_.settings[before].driver))
        return Stopped::driver_change;
    }
    return Stopped::time;
  }

  // Missed triggers (efforts that started in a breath and triggered nothing) and double
  // triggers (two breaths from one effort), from the efforts' onsets and the trigger times
  // (both in increasing order: binary searches, so an hour of breaths costs milliseconds).
  void count_triggers(SimulationResult& result) const {
    const auto& triggers = patient_triggers_;
    auto& breaths = result.breaths;
    // A patient-triggered breath whose effort (onset = start - delay) triggered a breath before it.
    for (BreathMetrics& b : breaths) {
      if (!(b.trigger_delay_s == b.trigger_delay_s)) continue;  // no effort behind this breath
      const auto first = std::lower_bound(triggers.begin(), triggers.end(), b.start_s - b.trigger_delay_s);
      b.double_triggered = first != triggers.end() && *first < b.start_s;
    }
    const double end = options_.duration_s;
    for (std::size_t s = 0; s < protocol_.settings.size(); ++s) {
      const PatientEffort& e = protocol_.settings[s].effort;
      if (!e.active()) continue;
      // APRV: the patient breathes at either level through the demand valve; nothing is missed.
      if (const auto* a = std::get_if<Assisted>(&protocol_.settings[s].driver); a && a->mode == AssistMode::aprv)
        continue;
      const double from = protocol_.settings[s].start_time_s;
      const double to = s + 1 < protocol_.settings.size() ? protocol_.settings[s + 1].start_time_s : end;
      const double period = 1.0 / e.rate_hz, anchor = effort_anchor_[s];
      for (double k = std::ceil((from - anchor) / period - 1e-12);; k += 1.0) {
        const double onset = anchor + k * period;
        if (onset >= to) break;
        const double effort_end = std::min(onset + period, to);
        const auto first = std::lower_bound(triggers.begin(), triggers.end(), onset);
        if (first != triggers.end() && *first < effort_end) continue;  // it triggered
        // The breath that holds the onset, if any (breaths tile time from the first one).
        const auto after = std::upper_bound(breaths.begin(), breaths.end(), onset,
                                            [](double t, const BreathMetrics& b) { return t < b.start_s; });
        if (after == breaths.begin()) continue;
        BreathMetrics& holder = *std::prev(after);
        if (onset < holder.start_s + holder.duration_s) ++holder.missed_triggers;
      }
    }
  }

  void reserve(TimeSeries& s) {
    output_count_ = static_cast<std::size_t>(std::floor(options_.duration_s * options_.output_rate_hz + 1e-9)) + 1;
    for (auto* column : {&s.time_s, &s.volume_m3, &s.flow_m3_per_s, &s.airway_pressure_pa, &s.alveolar_pressure_pa,
                         &s.pleural_pressure_pa, &s.muscle_pressure_pa}) {
      column->reserve(output_count_);
    }
    for (auto& column : s.compartment_volume_m3) column.reserve(output_count_);
  }

  double output_time(std::size_t k) const { return static_cast<double>(k) / options_.output_rate_hz; }

  void record(double t, const double* y) {
    std::array<double, kMaxStates> q{};
    const Instant now = evaluate(context_, t, y, q.data());
    const Mechanics& m = *context_.mechanics;
    // A flow limitation's choke point takes the drop beyond R Q: the alveolar pressure is Pel - Pmus.
    const double alveolar = m.flow_limited()
                                ? elastic_pressure(m.compartments[0].elasticity, y[0]) - now.muscle_pressure
                                : alveolar_pressure(m, now.airway_pressure, now.flow);
    TimeSeries& s = *series_;
    s.time_s.push_back(t);
    s.volume_m3.push_back(total(y, n_));
    s.flow_m3_per_s.push_back(now.flow);
    s.airway_pressure_pa.push_back(now.airway_pressure);
    s.alveolar_pressure_pa.push_back(alveolar);
    // Ppl = -Ptp_rest + f Pel - Pmus, with Pel = Palv + Pmus at the branch point.
    s.pleural_pressure_pa.push_back(-m.transpulmonary_pressure_at_rest_pa +
                                    m.chest_wall_fraction * (alveolar + now.muscle_pressure) - now.muscle_pressure);
    s.muscle_pressure_pa.push_back(now.muscle_pressure);
    for (std::size_t i = 0; i < n_; ++i) s.compartment_volume_m3[i].push_back(y[i]);
    ++next_output_;
  }

  // The airway pressure's integral over the breath (trapezoids between the visited points,
  // 1 ms apart at most; a segment's start opens a new run, the pressure may jump there).
  void accumulate_paw(double t, double paw, bool segment_start) {
    if (!segment_start) paw_integral_ += 0.5 * (paw + last_paw_) * (t - last_paw_t_);
    last_paw_t_ = t;
    last_paw_ = paw;
  }

  // Integrates [a, b) with one smooth drive, recording the output samples that fall in it.
  // With root functions in the context (and `root` given), stops at the first event instead:
  // returns the time reached (b, or the event's) and sets *root to the event's index or -1.
  double integrate_segment(double a, double b, double* y, double& peak_airway, double& peak_drive, Instant& last,
                           int* root = nullptr) {
    if (root) *root = -1;
    std::array<double, kMaxStates> q{};
    Instant first = evaluate(context_, a, y, q.data());
    peak_airway = std::max(peak_airway, first.airway_pressure);
    peak_drive = std::max(peak_drive, first.airway_pressure + first.muscle_pressure);
    accumulate_paw(a, first.airway_pressure, true);
    track_starvation(a, y, first.airway_pressure);
    if (b - a <= 1e-12 * std::max(1.0, b)) {
      last = first;
      return b;
    }
    integrator_.restart(a, y, b);
    std::array<int, kMaxRoots> directions{};
    const int roots = root ? context_.root_count : 0;
    for (int i = 0; i < roots; ++i)
      directions[static_cast<std::size_t>(i)] = root_direction(context_.roots[static_cast<std::size_t>(i)]);
    integrator_.set_roots(roots, root_function, directions.data());
    std::array<double, kMaxStates> sample{};
    track_volume(total(y, n_));
    // Output samples, and probes every kProbeInterval (interpolated by CVODE, cheap) so that the
    // breath's volume extremes are found whatever the output rate (even with no output at all).
    std::size_t probes = 1;
    int found = -1;
    double reached = b;
    for (;;) {
      const bool output = series_ && next_output_ < output_count_ && output_time(next_output_) < b;
      const double probe = a + static_cast<double>(probes) * kProbeInterval;
      if (output && output_time(next_output_) <= probe) {
        const double t = output_time(next_output_);
        // A sample a rounding error after the segment's start takes the start state (CVODE
        // refuses a first step that small, and the state cannot differ measurably).
        if (t <= a + 1e-12 * std::max(1.0, a)) {
          record(t, y);
          continue;
        }
        const double at = integrator_.advance(t, sample.data(), &found);
        if (found >= 0) {
          reached = at;
          break;
        }
        record(t, sample.data());
        track_volume(total(sample.data(), n_));
        const Instant now = evaluate(context_, t, sample.data(), q.data());
        peak_airway = std::max(peak_airway, now.airway_pressure);
        peak_drive = std::max(peak_drive, now.airway_pressure + now.muscle_pressure);
        accumulate_paw(t, now.airway_pressure, false);
        track_starvation(t, sample.data(), now.airway_pressure);
      } else if (probe < b) {
        const double at = integrator_.advance(probe, sample.data(), &found);
        if (found >= 0) {
          reached = at;
          break;
        }
        track_volume(total(sample.data(), n_));
        const double paw = evaluate(context_, probe, sample.data(), q.data()).airway_pressure;
        accumulate_paw(probe, paw, false);
        track_starvation(probe, sample.data(), paw);
        ++probes;
      } else {
        break;
      }
    }
    if (found >= 0) {
      for (std::size_t i = 0; i < n_; ++i) y[i] = sample[i];
      if (root) *root = found;
    } else {
      integrator_.advance(b, y);
    }
    track_volume(total(y, n_));
    last = evaluate(context_, reached, y, q.data());  // the left limit at the end, still in this phase
    peak_airway = std::max(peak_airway, last.airway_pressure);
    peak_drive = std::max(peak_drive, last.airway_pressure + last.muscle_pressure);
    accumulate_paw(reached, last.airway_pressure, false);
    track_starvation(reached, y, last.airway_pressure);
    return reached;
  }

  // The driver of `setting`, with a spontaneous target tidal volume turned into an amplitude.
  Driver resolved_driver(std::size_t setting);

  const Protocol& protocol_;
  const SimulationOptions& options_;
  std::size_t n_;
  std::size_t extra_;  // 2 with a circuit: the volume leaked and the tubing's gas volume
  SegmentContext context_;
  Driver current_driver_;  // the breath in progress; context_ points at it
  detail::CvodeIntegrator integrator_;
  TimeSeries* series_ = nullptr;
  void track_volume(double v) {
    min_volume_ = std::min(min_volume_, v);
    max_volume_ = std::max(max_volume_, v);
  }
  static constexpr double kProbeInterval = 1e-3;  // s: the volume extremes to ~1e-6 of the swing
  double min_volume_ = 0.0, max_volume_ = 0.0;    // over the current breath
  double paw_integral_ = 0.0, last_paw_t_ = 0.0, last_paw_ = 0.0;
  bool starvation_ = false;  // in a flow-controlled inspiration: track the airway pressure's dip
  double starvation_dip_ = std::numeric_limits<double>::quiet_NaN();  // the largest this breath, NaN: none
  std::size_t next_output_ = 0;
  std::size_t output_count_ = 0;
  std::map<std::size_t, Driver> calibrated_;
  std::vector<double> effort_anchor_;                                // per setting: when its effort's breaths began
  std::optional<Start> pending_;                                     // the next assisted breath's start, when found
  double simv_due_ = std::numeric_limits<double>::quiet_NaN();       // SIMV: the next scheduled mandatory breath
  std::size_t next_hold_ = 0;                                        // the first expiratory hold not yet made
  std::vector<double> patient_triggers_;                             // times of every patient trigger
  double start_delivered_ = 0.0, end_inspiration_delivered_ = 0.0;   // ventilator_volume at those times
  double prvc_pressure_ = std::numeric_limits<double>::quiet_NaN();  // PRVC: the next breath's pressure
  bool apnea_ = false;        // cpap_psv: backup breaths until the patient triggers
  bool apnea_alarm_ = false;  // the next breath is the first of a backup
};

// Periodic steady-state tidal volume of a spontaneous driver with a given amplitude.
double steady_tidal_volume(const Mechanics& mechanics, Spontaneous driver, double amplitude,
                           const SolverOptions& solver) {
  driver.amplitude_pa = amplitude;
  driver.target_tidal_volume_m3 = 0.0;
  constexpr int kBreaths = 8;  // enough for the slowest preset (time constant 1 s, breath 5 s)
  SimulationOptions options;
  options.duration_s = kBreaths / driver.rate_hz;
  options.output_rate_hz = 0.0;
  options.solver = solver;
  const SimulationResult r = simulate(Protocol{{Setting{0.0, mechanics, driver}}}, options);
  return r.breaths.back().tidal_volume_m3;
}

Driver Simulation::resolved_driver(std::size_t setting) {
  const Setting& s = protocol_.settings[setting];
  const auto* spontaneous = std::get_if<Spontaneous>(&s.driver);
  if (!spontaneous || spontaneous->target_tidal_volume_m3 <= 0.0) return s.driver;
  if (auto it = calibrated_.find(setting); it != calibrated_.end()) return it->second;

  // Secant iteration on the amplitude; one proportional step is exact for linear mechanics.
  const double target = spontaneous->target_tidal_volume_m3;
  double compliance = 0.0;
  for (const auto& c : s.mechanics.compartments) compliance += compliance_at(c.elasticity, 0.0);
  constexpr double kMaxAmplitude = 100.0 * units::pa_per_cmh2o;  // 100 cmH2O: far beyond any real effort
  auto unreachable = [&] {
    return Error(ExitCode::bad_input,
                 "physiology: a tidal volume of " + std::to_string(std::lround(target * units::ml_per_m3)) +
                     " mL cannot be reached by spontaneous breathing with these mechanics (setting from t = " +
                     fmt_seconds(s.start_time_s) + " s)");
  };
  // Quasi-static bound: no breath can exceed the volume the largest effort holds at rest.
  double static_limit = 0.0;
  for (const auto& c : s.mechanics.compartments) static_limit += volume_at_pressure(c.elasticity, kMaxAmplitude);
  if (target >= static_limit) throw unreachable();
  double a0 = std::min(target / compliance, kMaxAmplitude);
  double f0 = steady_tidal_volume(s.mechanics, *spontaneous, a0, options_.solver) - target;
  double a1 = std::min(a0 * target / (f0 + target), kMaxAmplitude);
  double f1 = steady_tidal_volume(s.mechanics, *spontaneous, a1, options_.solver) - target;
  for (int i = 0; i < 40 && std::abs(f1) > 1e-9 * target; ++i) {
    if (f1 == f0) break;
    const double a2 = std::clamp(a1 - f1 * (a1 - a0) / (f1 - f0), 0.0, kMaxAmplitude);
    a0 = a1;
    f0 = f1;
    a1 = a2;
    f1 = steady_tidal_volume(s.mechanics, *spontaneous, a1, options_.solver) - target;
  }
  if (std::abs(f1) > 1e-6 * target) throw unreachable();
  Spontaneous resolved = *spontaneous;
  resolved.amplitude_pa = a1;
  resolved.target_tidal_volume_m3 = 0.0;
  return calibrated_.emplace(setting, resolved).first->second;
}

void validate(const Protocol& protocol, const SimulationOptions& options) {
  if (protocol.settings.empty()) throw ValueError("the protocol has no settings");
  if (protocol.settings.front().start_time_s != 0.0) throw ValueError("the first setting must start at 0 s");
  const std::size_t n = protocol.settings.front().mechanics.compartments.size();
  if (n > kMaxCompartments) throw ValueError("at most 8 compartments are supported");
  double previous = -1.0;
  for (const Setting& s : protocol.settings) {
    if (!(s.start_time_s > previous)) throw ValueError("settings must start at increasing times");
    previous = s.start_time_s;
    if (s.mechanics.compartments.size() != n)
      throw ValueError("every setting must keep the same number of compartments");
    validate(s.mechanics);
    validate(s);
  }
  double previous_hold = -1.0;
  for (const ExpiratoryHold& h : protocol.holds) {
    if (!(h.at_s > previous_hold) || !std::isfinite(h.at_s))
      throw ValueError("expiratory holds must come at increasing times from 0 s");
    previous_hold = h.at_s;
    if (!(h.duration_s > 0.0) || !std::isfinite(h.duration_s))
      throw ValueError("an expiratory hold must last a positive time");
  }
  if (!(options.duration_s > 0.0) || !std::isfinite(options.duration_s))
    throw ValueError("the duration must be positive");
  if (!(options.output_rate_hz >= 0.0)) throw ValueError("the output rate must not be negative");
  if (!(options.solver.relative_tolerance > 0.0) || !(options.solver.absolute_tolerance_m3 > 0.0))
    throw ValueError("solver tolerances must be positive");
}

}  // namespace

void validate(const Setting& s) {
  validate(s.driver);
  const auto* a = std::get_if<Assisted>(&s.driver);
  if (!a || a->mode != AssistMode::pav) return;
  if (s.circuit.active()) throw ValueError("PAV assists the patient's own flow: it takes no circuit");
  // The smallest resistance the inspiratory flow meets: the airway's, then the branches in parallel.
  double conductance = 0.0;
  bool open_branch = false;
  for (const auto& c : s.mechanics.compartments) {
    if (c.resistance_pa_s_per_m3 > 0.0) conductance += 1.0 / c.resistance_pa_s_per_m3;
    else open_branch = true;
  }
  const double resistance =
      s.mechanics.airway_resistance_pa_s_per_m3 + (open_branch || conductance == 0.0 ? 0.0 : 1.0 / conductance);
  if (!(a->pav_gain * a->pav_resistance_pa_s_per_m3 < resistance))
    throw ValueError("the assist gain times the assisted resistance must stay below the patient's resistance (" +
                     fmt_seconds(resistance / units::pa_s_per_m3_per_cmh2o_s_per_l) +
                     " cmH2O*s/L): the assist would run away");
}

SimulationResult simulate(const Protocol& protocol, const SimulationOptions& options) {
  validate(protocol, options);
  Simulation simulation(protocol, options);
  return simulation.run();
}

}  // namespace pneuma::physiology
