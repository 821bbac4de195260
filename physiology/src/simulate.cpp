#include "pneuma/physiology/simulate.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <string>

#include "cvode_integrator.h"
#include "pneuma/core/error.h"

namespace pneuma::physiology {
namespace {

constexpr int kMaxCompartments = 8;

// What the right-hand side needs: the mechanics and the drive of the current segment.
struct SegmentContext {
  const Mechanics* mechanics = nullptr;
  const Driver* driver = nullptr;
  int phase = 0;
  double breath_start_s = 0.0;
};

struct Instant {
  double flow = 0.0;
  double airway_pressure = 0.0;
  double muscle_pressure = 0.0;
  double peep = 0.0;
};

// Flows into every compartment at (t, volumes); returns the pressures at that instant.
Instant evaluate(const SegmentContext& c, double t, const double* volumes, double* flows) {
  const Drive d = drive_at(*c.driver, c.phase, t - c.breath_start_s);
  Instant out;
  out.muscle_pressure = d.muscle_pressure_pa;
  out.peep = d.peep_pa;
  if (d.flow_controlled) {
    const double pd = driving_pressure_for_flow(*c.mechanics, d.flow_m3_per_s, volumes);
    out.flow = compartment_flows(*c.mechanics, pd, volumes, flows);
    out.airway_pressure = pd - d.muscle_pressure_pa;
  } else {
    const double pd = d.airway_pressure_pa + d.muscle_pressure_pa;
    out.flow = compartment_flows(*c.mechanics, pd, volumes, flows);
    out.airway_pressure = d.airway_pressure_pa;
  }
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
        integrator_(static_cast<int>(n_), right_hand_side, &context_, options.solver) {}

  SimulationResult run() {
    SimulationResult result;
    for (const auto& c : protocol_.settings.front().mechanics.compartments) result.compartment_names.push_back(c.name);
    result.series.compartment_volume_m3.resize(n_);
    series_ = options_.output_rate_hz > 0.0 ? &result.series : nullptr;
    if (series_) reserve(result.series);

    // Start at rest: each compartment at the volume its first PEEP holds.
    std::array<double, kMaxCompartments> y{};
    const Setting& first = protocol_.settings.front();
    for (std::size_t i = 0; i < n_; ++i) {
      y[i] = volume_at_pressure(first.mechanics.compartments[i].elasticity, peep_of(first.driver));
    }
    double t = 0.0;
    const double end = options_.duration_s;
    while (t < end) {
      const std::size_t setting = setting_at(t);
      current_driver_ = resolved_driver(setting);
      const Driver& driver = current_driver_;
      const BreathPlan plan = plan_breath(driver);
      BreathMetrics breath;
      breath.start_s = t;
      breath.mode = mode_name(driver);
      breath.peep_pa = peep_of(driver);
      if (const auto* s = std::get_if<Spontaneous>(&driver)) breath.muscle_amplitude_pa = s->amplitude_pa;
      const double start_volume = total(y.data(), n_);
      min_volume_ = max_volume_ = start_volume;
      if (const auto* sp = std::get_if<Spontaneous>(&protocol_.settings[setting].driver))
        breath.set_tidal_volume_m3 = sp->target_tidal_volume_m3;
      else if (const auto* vc = std::get_if<VolumeControl>(&driver)) breath.set_tidal_volume_m3 = vc->tidal_volume_m3;
      double end_inspiration_volume = start_volume;
      double peak_airway = -std::numeric_limits<double>::infinity();
      double peak_drive = -std::numeric_limits<double>::infinity();
      bool complete = true;

      context_.driver = &driver;
      context_.breath_start_s = t;
      for (int p = 0; p < plan.count && complete; ++p) {
        context_.phase = p;
        const double phase_end = breath.start_s + plan.phases[static_cast<std::size_t>(p)].end_s;
        Instant last;
        while (t < phase_end) {
          const double segment_end = std::min({phase_end, next_change_after(t), end});
          context_.mechanics = &protocol_.settings[setting_at(t)].mechanics;
          integrate_segment(t, segment_end, y.data(), peak_airway, peak_drive, last);
          t = segment_end;
          if (t >= end && t < phase_end) {
            complete = false;
            break;
          }
        }
        if (!complete) break;
        if (plan.phases[static_cast<std::size_t>(p)].inspiratory &&
            (p + 1 == plan.count || !plan.phases[static_cast<std::size_t>(p + 1)].inspiratory)) {
          end_inspiration_volume = total(y.data(), n_);
          breath.plateau_pressure_pa = alveolar_pressure(*context_.mechanics, last.airway_pressure, last.flow);
        }
      }
      if (!complete) break;
      breath.duration_s = t - breath.start_s;
      breath.inspired_volume_m3 = end_inspiration_volume - start_volume;
      breath.tidal_volume_m3 = max_volume_ - min_volume_;
      breath.minute_ventilation_m3_per_s = breath.tidal_volume_m3 / breath.duration_s;
      breath.peak_pressure_pa = peak_airway;
      breath.dynamic_compliance_m3_per_pa = peak_drive - breath.peep_pa > 0.0
                                                ? breath.tidal_volume_m3 / (peak_drive - breath.peep_pa)
                                                : std::numeric_limits<double>::quiet_NaN();
      breath.end_expiratory_volume_m3 = total(y.data(), n_);
      result.breaths.push_back(breath);
    }
    // A sample exactly at the end time belongs to no segment: record it from the final state.
    if (series_ && next_output_ < output_count_) record(end, y.data());
    result.stats = integrator_.stats();
    return result;
  }

 private:
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
    std::array<double, kMaxCompartments> q{};
    const Instant now = evaluate(context_, t, y, q.data());
    const Mechanics& m = *context_.mechanics;
    const double alveolar = alveolar_pressure(m, now.airway_pressure, now.flow);
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

  // Integrates [a, b) with one smooth drive, recording the output samples that fall in it.
  void integrate_segment(double a, double b, double* y, double& peak_airway, double& peak_drive, Instant& last) {
    std::array<double, kMaxCompartments> q{};
    Instant first = evaluate(context_, a, y, q.data());
    peak_airway = std::max(peak_airway, first.airway_pressure);
    peak_drive = std::max(peak_drive, first.airway_pressure + first.muscle_pressure);
    if (b - a <= 1e-12 * std::max(1.0, b)) {
      last = first;
      return;
    }
    integrator_.restart(a, y, b);
    std::array<double, kMaxCompartments> sample{};
    track_volume(total(y, n_));
    // Output samples, and probes every kProbeInterval (interpolated by CVODE, cheap) so that the
    // breath's volume extremes are found whatever the output rate (even with no output at all).
    std::size_t probes = 1;
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
        integrator_.advance(t, sample.data());
        record(t, sample.data());
        track_volume(total(sample.data(), n_));
        const Instant now = evaluate(context_, t, sample.data(), q.data());
        peak_airway = std::max(peak_airway, now.airway_pressure);
        peak_drive = std::max(peak_drive, now.airway_pressure + now.muscle_pressure);
      } else if (probe < b) {
        integrator_.advance(probe, sample.data());
        track_volume(total(sample.data(), n_));
        ++probes;
      } else {
        break;
      }
    }
    integrator_.advance(b, y);
    track_volume(total(y, n_));
    last = evaluate(context_, b, y, q.data());  // the left limit at b, still in this phase
    peak_airway = std::max(peak_airway, last.airway_pressure);
    peak_drive = std::max(peak_drive, last.airway_pressure + last.muscle_pressure);
  }

  // The driver of `setting`, with a spontaneous target tidal volume turned into an amplitude.
  Driver resolved_driver(std::size_t setting);

  const Protocol& protocol_;
  const SimulationOptions& options_;
  std::size_t n_;
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
  std::size_t next_output_ = 0;
  std::size_t output_count_ = 0;
  std::map<std::size_t, Driver> calibrated_;
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
  constexpr double kMaxAmplitude = 100.0 * 98.0665;  // 100 cmH2O: far beyond any real effort
  auto unreachable = [&] {
    return Error(ExitCode::bad_input,
                 "physiology: a tidal volume of " + std::to_string(std::lround(target * 1e6)) +
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
    validate(s.driver);
  }
  if (!(options.duration_s > 0.0) || !std::isfinite(options.duration_s))
    throw ValueError("the duration must be positive");
  if (!(options.output_rate_hz >= 0.0)) throw ValueError("the output rate must not be negative");
  if (!(options.solver.relative_tolerance > 0.0) || !(options.solver.absolute_tolerance_m3 > 0.0))
    throw ValueError("solver tolerances must be positive");
}

}  // namespace

SimulationResult simulate(const Protocol& protocol, const SimulationOptions& options) {
  validate(protocol, options);
  Simulation simulation(protocol, options);
  return simulation.run();
}

}  // namespace pneuma::physiology
