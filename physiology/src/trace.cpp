// A measured trace turned into the volume above FRC (trace.h), breaths found on it, and the run's
// physiology sampled from it.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>

#include "pneuma/core/error.h"
#include "pneuma/core/units.h"
#include "pneuma/physiology/trace.h"

namespace pneuma::physiology {
namespace {

// A processed volume beyond these is not a breath of a lung: inspiratory capacity is about
// 3.5 L and expiratory reserve about 1.2 L in a large adult (Quanjer et al., ERS 1993); twice
// that is a wrong unit or calibration, never a patient.
constexpr double kMaxAboveFrcM3 = 6e-3;
constexpr double kMaxBelowFrcM3 = 3e-3;
// Hysteresis of the breath finder, as a share of the signal's half swing (5th to 95th percentile).
constexpr double kHysteresis = 0.25;
// A spirometry calibration whose fit explains less of the volume than this is refused: the two
// traces are not of the same breaths (a wrong offset) or the surrogate does not follow the volume.
constexpr double kMinCalibrationR2 = 0.8;

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double x = q * static_cast<double>(v.size() - 1);
  const auto i = static_cast<std::size_t>(std::floor(x));
  const std::size_t j = std::min(i + 1, v.size() - 1);
  return v[i] + (x - static_cast<double>(i)) * (v[j] - v[i]);
}

double median(std::vector<double> v) { return quantile(std::move(v), 0.5); }

// Least-squares line y = a + b t through the points; b = 0 for a single point.
std::pair<double, double> fit_line(const std::vector<double>& t, const std::vector<double>& y) {
  const double n = static_cast<double>(t.size());
  const double tm = std::accumulate(t.begin(), t.end(), 0.0) / n;
  const double ym = std::accumulate(y.begin(), y.end(), 0.0) / n;
  double stt = 0.0, sty = 0.0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    stt += (t[i] - tm) * (t[i] - tm);
    sty += (t[i] - tm) * (y[i] - ym);
  }
  const double b = stt > 0.0 ? sty / stt : 0.0;
  return {ym - b * tm, b};
}

std::string ml(double m3) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.0f mL", m3 * units::ml_per_m3);
  return buffer;
}

std::string where(const std::filesystem::path& file, std::size_t line) {
  std::string out = file.string();
  if (line > 0) out.append(":").append(std::to_string(line));
  return out.append(": ");
}

// Linear interpolation of (t, v) at x, with `hint` the segment found last (x rising).
double interpolate(const std::vector<double>& t, const std::vector<double>& v, double x, std::size_t& hint) {
  if (x <= t.front()) return v.front();
  if (x >= t.back()) return v.back();
  if (hint >= t.size() - 1 || t[hint] > x) hint = 0;
  while (t[hint + 1] < x) ++hint;
  const double w = (x - t[hint]) / (t[hint + 1] - t[hint]);
  return v[hint] + w * (v[hint + 1] - v[hint]);
}

// A spirometry calibration's least-squares fit: volume = scale * amplitude + c.
struct SpirometryFit {
  double scale = 0.0, r2 = 0.0, span_s = 0.0;
};

// `amplitude` is the surrogate with its drift removed and its FRC level at 0 (the spirometry has
// had the same done to its volume), on its own clock; the spirometry's samples are taken at
// their times + offset. Throws InputError when the two share less than one whole breath.
SpirometryFit fit_spirometry(const Trace& spirometry, double offset_s, const Trace& amplitude,
                             const std::vector<BreathCycle>& breaths) {
  const double lo = std::max(amplitude.time_s.front(), spirometry.time_s.front() + offset_s);
  const double hi = std::min(amplitude.end_s(), spirometry.end_s() + offset_s);
  const bool whole_breath = std::any_of(breaths.begin(), breaths.end(), [&](const BreathCycle& b) {
    return amplitude.time_s[b.start] >= lo && amplitude.time_s[b.end] <= hi;
  });
  if (!whole_breath) {
    char buffer[200];
    std::snprintf(buffer, sizeof buffer,
                  "the spirometry (%.1f to %.1f s on this trace's clock) covers no whole breath of the trace (%.1f to "
                  "%.1f s); check its 'offset'",
                  spirometry.time_s.front() + offset_s, spirometry.end_s() + offset_s, amplitude.time_s.front(),
                  amplitude.end_s());
    throw InputError(where(spirometry.file, 0) + buffer);
  }
  std::vector<double> a, y;
  std::size_t hint = 0;
  for (std::size_t k = 0; k < spirometry.time_s.size(); ++k) {
    const double x = spirometry.time_s[k] + offset_s;
    if (x < lo || x > hi) continue;
    a.push_back(interpolate(amplitude.time_s, amplitude.volume_m3, x, hint));
    y.push_back(spirometry.volume_m3[k]);
  }
  const auto [c, scale] = fit_line(a, y);
  double ss_res = 0.0, ss_tot = 0.0;
  const double y_mean = std::accumulate(y.begin(), y.end(), 0.0) / static_cast<double>(y.size());
  for (std::size_t k = 0; k < y.size(); ++k) {
    ss_res += (y[k] - c - scale * a[k]) * (y[k] - c - scale * a[k]);
    ss_tot += (y[k] - y_mean) * (y[k] - y_mean);
  }
  return {scale, ss_tot > 0.0 ? 1.0 - ss_res / ss_tot : 0.0, hi - lo};
}

}  // namespace

std::vector<TurningPoint> find_turning_points(const std::vector<double>& volume) {
  std::vector<TurningPoint> turns;
  if (volume.size() < 3) return turns;
  const double centre = median(volume);
  const double half_swing = 0.5 * (quantile(volume, 0.95) - quantile(volume, 0.05));
  if (!(half_swing > 0.0)) return turns;
  const double band = kHysteresis * half_swing;
  // Alternating extremes, each of a stretch entered by a crossing (a stretch the signal starts
  // in, or ends in, may be cut: its extreme is not a turning point).
  enum class State { unknown, below, above };
  State state = State::unknown;
  bool entered = false;
  std::size_t extreme = 0;
  for (std::size_t k = 0; k < volume.size(); ++k) {
    const double v = volume[k];
    if (v < centre - band && state != State::below) {
      if (state == State::above && entered) turns.push_back({extreme, true});
      entered = state != State::unknown;
      state = State::below;
      extreme = k;
    } else if (v > centre + band && state != State::above) {
      if (state == State::below && entered) turns.push_back({extreme, false});
      entered = state != State::unknown;
      state = State::above;
      extreme = k;
    }
    if ((state == State::below && v < volume[extreme]) || (state == State::above && v > volume[extreme])) extreme = k;
  }
  // The stretch the signal ends in counts where the signal has since turned back by the band: its
  // extreme is behind it (an 8 s run of 12 /min breaths ends 1.1 s after its second peak, which
  // closes its one whole cycle).
  const double last = volume.back();
  if (entered && ((state == State::above && last < volume[extreme] - band) ||
                  (state == State::below && last > volume[extreme] + band)))
    turns.push_back({extreme, state == State::above});
  return turns;
}

std::vector<BreathCycle> find_breaths(const std::vector<double>& volume) {
  const std::vector<TurningPoint> turns = find_turning_points(volume);
  std::vector<BreathCycle> breaths;
  for (std::size_t i = 0; i + 2 < turns.size(); ++i) {
    if (!turns[i].peak && turns[i + 1].peak && !turns[i + 2].peak)
      breaths.push_back({turns[i].index, turns[i + 1].index, turns[i + 2].index});
  }
  return breaths;
}

Trace process_trace(const RawTrace& raw, const TraceOptions& options) {
  Trace out;
  out.file = raw.file;
  out.signal = raw.signal;
  out.column = raw.column;
  TraceReport& report = out.report;
  report.samples = raw.time_s.size();

  // The valid samples.
  std::vector<double> values;
  for (std::size_t k = 0; k < raw.time_s.size(); ++k) {
    if (!raw.valid[k]) {
      ++report.invalid_samples;
      continue;
    }
    out.time_s.push_back(raw.time_s[k]);
    values.push_back(raw.value[k]);
    out.line.push_back(raw.line[k]);
  }
  if (out.time_s.size() < 3)
    throw InputError(where(raw.file, 0) + "only " + std::to_string(out.time_s.size()) +
                     " valid samples (a trace needs at least a few breaths)");

  // Gaps: longer than 3 sample intervals (nominal, else the median), bridged by a straight line.
  std::vector<double> intervals;
  for (std::size_t k = 1; k < out.time_s.size(); ++k) intervals.push_back(out.time_s[k] - out.time_s[k - 1]);
  const double interval = raw.nominal_interval_s > 0.0 ? raw.nominal_interval_s : median(intervals);
  for (double dt : intervals) {
    if (dt > 3.0 * interval * (1.0 + 1e-9)) {
      ++report.gaps;
      report.longest_gap_s = std::max(report.longest_gap_s, dt);
    }
  }

  // To a volume-like signal.
  std::vector<double>& v = out.volume_m3;
  if (raw.signal == TraceSignal::flow) {
    v.assign(values.size(), 0.0);
    for (std::size_t k = 1; k < values.size(); ++k)
      v[k] = v[k - 1] + 0.5 * (values[k] + values[k - 1]) * (out.time_s[k] - out.time_s[k - 1]);
  } else {
    v = values;
    if (raw.signal == TraceSignal::amplitude && options.invert) {
      for (double& x : v) x = -x;
    }
  }

  // Breaths, found on the signal with its overall trend removed (a drifting flow integral may
  // leave the median band otherwise); then the drift: the line through the troughs.
  const bool detrend = options.detrend.value_or(raw.signal != TraceSignal::volume);
  std::vector<double> levelled = v;
  if (detrend) {
    const auto [a, b] = fit_line(out.time_s, v);
    for (std::size_t k = 0; k < v.size(); ++k) levelled[k] = v[k] - (a + b * out.time_s[k]);
  }
  const std::vector<BreathCycle> breaths = find_breaths(levelled);
  if (breaths.empty())
    throw InputError(where(raw.file, 0) + "no breath found in column '" + raw.column +
                     "' (expected at least one trough-to-trough cycle of a breathing signal)");
  std::vector<std::size_t> troughs{breaths.front().start};
  for (const BreathCycle& b : breaths) troughs.push_back(b.end);
  if (detrend) {
    std::vector<double> tt, tv;
    for (std::size_t i : troughs) {
      tt.push_back(out.time_s[i]);
      tv.push_back(v[i]);
    }
    const auto [a, b] = fit_line(tt, tv);
    for (std::size_t k = 0; k < v.size(); ++k) v[k] -= a + b * out.time_s[k];
    report.drift_m3_per_s = b;  // in the signal's units per second (amplitude: scaled below)
  }

  // FRC at 0: the median end-expiratory level.
  std::vector<double> ends;
  ends.reserve(troughs.size());
  for (std::size_t i : troughs) ends.push_back(v[i]);
  const double reference = median(ends);
  for (double& x : v) x -= reference;
  report.reference_m3 = reference;
  report.breaths = breaths.size();

  // A surrogate's calibration to volume.
  if (raw.signal == TraceSignal::amplitude) {
    double scale = options.calibration.volume_per_unit_m3;
    if (options.calibration.spirometry) {
      const SpirometryFit fit =
          fit_spirometry(*options.calibration.spirometry, options.calibration.spirometry_offset_s, out, breaths);
      scale = fit.scale;
      report.calibration_r2 = fit.r2;
      report.calibration_span_s = fit.span_s;
      if (!(scale > 0.0))
        throw InputError(where(raw.file, 0) + "the amplitude falls as the spirometer's volume rises (slope " +
                         std::to_string(scale * units::ml_per_m3) +
                         " mL per unit; a marker that moves down needs 'invert: true')");
      if (fit.r2 < kMinCalibrationR2) {
        char buffer[200];
        std::snprintf(buffer, sizeof buffer,
                      "the amplitude and the spirometer's volume agree poorly over their common %.1f s (r^2 = %.2f, "
                      "expected at least %.2f; is the spirometry's 'offset' right?)",
                      fit.span_s, fit.r2, kMinCalibrationR2);
        throw InputError(where(raw.file, 0) + buffer);
      }
    }
    if (options.calibration.tidal_volume_m3 > 0.0) {
      std::vector<double> swings;
      swings.reserve(breaths.size());
      for (const BreathCycle& b : breaths) swings.push_back(v[b.peak] - v[b.start]);
      const double swing = median(swings);
      if (!(swing > 0.0))
        throw InputError(where(raw.file, 0) + "the breaths have no amplitude to calibrate to a tidal volume");
      scale = options.calibration.tidal_volume_m3 / swing;
    }
    if (!(scale > 0.0))
      throw InputError(where(raw.file, 0) +
                       "an amplitude trace needs a calibration (a tidal volume or a volume per unit)");
    for (double& x : v) x *= scale;
    report.scale_m3_per_unit = scale;
    report.drift_m3_per_s *= scale;
    report.reference_m3 *= scale;
  }

  // A volume a lung cannot hold.
  for (std::size_t k = 0; k < v.size(); ++k) {
    if (v[k] > kMaxAboveFrcM3 || v[k] < -kMaxBelowFrcM3)
      throw InputError(where(raw.file, out.line[k]) + "the volume reaches " + ml(v[k]) +
                       " from FRC there, far beyond a lung's range (" + ml(-kMaxBelowFrcM3) + " to +" +
                       ml(kMaxAboveFrcM3) + "; check the unit or the calibration)");
  }
  out.start_s = options.start_s;
  return out;
}

void check_gaps_in_run(const Trace& trace, double duration_s) {
  const double t0 = trace.time_s.front() + trace.start_s, t1 = t0 + duration_s;
  for (std::size_t k = 1; k < trace.time_s.size(); ++k) {
    const double gap = trace.time_s[k] - trace.time_s[k - 1];
    if (trace.time_s[k] > t0 && trace.time_s[k - 1] < t1 && gap > kMaxGapInRunS) {
      char buffer[240];
      std::snprintf(buffer, sizeof buffer,
                    "no sample for %.6g s before this one, inside the run (trace time %.6g to %.6g s): expected gaps "
                    "of at most %g s (a few breaths); start the run after it with the trace's 'start'",
                    gap, t0 - trace.time_s.front(), t1 - trace.time_s.front(), kMaxGapInRunS);
      throw InputError(where(trace.file, trace.line[k]) + buffer);
    }
  }
}

SimulationResult trace_result(const Trace& trace, double duration_s, double rate_hz) {
  if (!(rate_hz > 0.0)) throw ValueError("the trace's output rate must be positive");
  const double t0 = trace.time_s.front() + trace.start_s;
  if (t0 + duration_s > trace.end_s() * (1.0 + 1e-12) + 1e-9) {
    char buffer[160];
    std::snprintf(buffer, sizeof buffer,
                  "the trace covers %.3f s from its start at %.3f s, less than the duration %.3f s", trace.end_s() - t0,
                  t0 - trace.time_s.front(), duration_s);
    throw ValueError(buffer);
  }
  SimulationResult r;
  r.compartment_names = {"lung"};
  TimeSeries& s = r.series;
  const auto n = static_cast<std::size_t>(std::floor(duration_s * rate_hz + 1e-9)) + 1;
  const double h = 1.0 / rate_hz;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::size_t hint = 0, before = 0, after = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) / rate_hz;
    const double x = t0 + t;
    s.time_s.push_back(t);
    s.volume_m3.push_back(interpolate(trace.time_s, trace.volume_m3, x, hint));
    const double a = std::max(trace.time_s.front(), x - h), b = std::min(trace.end_s(), x + h);
    s.flow_m3_per_s.push_back(
        (interpolate(trace.time_s, trace.volume_m3, b, after) - interpolate(trace.time_s, trace.volume_m3, a, before)) /
        (b - a));
    s.airway_pressure_pa.push_back(0.0);
    s.alveolar_pressure_pa.push_back(nan);
    s.pleural_pressure_pa.push_back(nan);
    s.muscle_pressure_pa.push_back(nan);
  }
  s.compartment_volume_m3 = {s.volume_m3};
  for (const BreathCycle& c : find_breaths(s.volume_m3)) {
    BreathMetrics b;
    b.start_s = s.time_s[c.start];
    b.duration_s = s.time_s[c.end] - s.time_s[c.start];
    b.mode = "trace";
    const auto [lo, hi] = std::minmax_element(s.volume_m3.begin() + static_cast<std::ptrdiff_t>(c.start),
                                              s.volume_m3.begin() + static_cast<std::ptrdiff_t>(c.end) + 1);
    b.tidal_volume_m3 = *hi - *lo;
    b.inspired_volume_m3 = s.volume_m3[c.peak] - s.volume_m3[c.start];
    b.minute_ventilation_m3_per_s = b.tidal_volume_m3 / b.duration_s;
    b.peak_pressure_pa = b.plateau_pressure_pa = b.dynamic_compliance_m3_per_pa = b.muscle_amplitude_pa = nan;
    b.peep_pa = 0.0;
    b.end_expiratory_volume_m3 = s.volume_m3[c.end];
    r.breaths.push_back(b);
  }
  return r;
}

}  // namespace pneuma::physiology
