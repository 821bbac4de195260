#include "pneuma/physiology/phases.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "pneuma/core/error.h"
#include "pneuma/physiology/trace.h"

namespace pneuma::physiology {
namespace {

struct Turn {
  double time_s = 0.0;
  double volume_m3 = 0.0;
};

// The extreme at sample p refined by the parabola through p - 1, p, p + 1 (exact for a
// quadratic; for a sampled sinusoid the peak time to a small fraction of the interval).
Turn refine(const std::vector<double>& t, const std::vector<double>& v, std::size_t p) {
  if (p == 0 || p + 1 >= v.size()) return {t[p], v[p]};
  const double curvature = v[p - 1] - 2.0 * v[p] + v[p + 1];
  if (curvature == 0.0) return {t[p], v[p]};
  const double delta = std::clamp(0.5 * (v[p - 1] - v[p + 1]) / curvature, -0.5, 0.5);  // in samples
  const double step = delta >= 0.0 ? t[p + 1] - t[p] : t[p] - t[p - 1];
  return {t[p] + delta * step, v[p] - 0.25 * (v[p - 1] - v[p + 1]) * delta};
}

}  // namespace

const char* binning_method_name(BinningMethod method) {
  return method == BinningMethod::amplitude ? "amplitude" : "phase";
}

PhaseBinning bin_phases(const std::vector<double>& time_s, const std::vector<double>& volume_m3,
                        const PhaseBinningOptions& options) {
  if (options.bins < 2 || options.bins > 100)
    throw ValueError("phase bins: expected 2 to 100, got " + std::to_string(options.bins));
  if (time_s.size() != volume_m3.size()) throw ValueError("phase bins: times and volumes differ in length");
  const auto n = static_cast<std::size_t>(options.bins);
  PhaseBinning out;
  out.method = options.method;
  out.bins.resize(n);
  for (std::size_t b = 0; b < n; ++b)
    out.bins[b].centre_percent = 100.0 * static_cast<double>(b) / static_cast<double>(n);
  out.position.assign(time_s.size(), std::nan(""));
  out.bin_of.assign(time_s.size(), -1);

  const std::vector<TurningPoint> turns = find_turning_points(volume_m3);
  // A cycle: from a peak to the next, through the trough between them.
  struct Cycle {
    Turn first, last;
    std::size_t trough = 0;
    double amplitude_m3 = 0.0;
  };
  std::vector<Cycle> cycles;
  for (std::size_t i = 0; i + 2 < turns.size(); ++i) {
    if (!turns[i].peak || turns[i + 1].peak || !turns[i + 2].peak) continue;
    Cycle c{refine(time_s, volume_m3, turns[i].index), refine(time_s, volume_m3, turns[i + 2].index),
            turns[i + 1].index, 0.0};
    const double trough = volume_m3[c.trough];
    c.amplitude_m3 = 0.5 * ((c.first.volume_m3 - trough) + (c.last.volume_m3 - trough));
    cycles.push_back(c);
  }
  out.cycles = cycles.size();
  std::vector<double> amplitudes;
  amplitudes.reserve(cycles.size());
  for (const Cycle& c : cycles) amplitudes.push_back(c.amplitude_m3);
  std::sort(amplitudes.begin(), amplitudes.end());
  const double median = amplitudes.empty() ? 0.0
                        : amplitudes.size() % 2
                            ? amplitudes[amplitudes.size() / 2]
                            : 0.5 * (amplitudes[amplitudes.size() / 2 - 1] + amplitudes[amplitudes.size() / 2]);

  std::size_t k = 0;
  for (std::size_t ci = 0; ci < cycles.size(); ++ci) {
    const Cycle& c = cycles[ci];
    const double ratio = median > 0.0 ? c.amplitude_m3 / median : 0.0;
    const bool irregular = !(ratio >= options.min_amplitude_ratio && ratio <= options.max_amplitude_ratio);
    if (irregular) ++out.irregular_cycles;
    while (k < time_s.size() && time_s[k] < c.first.time_s) ++k;
    for (; k < time_s.size() && time_s[k] < c.last.time_s; ++k) {
      if (irregular) continue;
      double position = 0.0;
      if (options.method == BinningMethod::phase) {
        position = (time_s[k] - c.first.time_s) / (c.last.time_s - c.first.time_s);
      } else {
        const double trough = volume_m3[c.trough];
        const bool expiring = k < c.trough;
        const double peak = expiring ? c.first.volume_m3 : c.last.volume_m3;
        const double a = std::clamp((volume_m3[k] - trough) / (peak - trough), 0.0, 1.0);
        position = expiring ? 0.5 * (1.0 - a) : 0.5 + 0.5 * a;
      }
      auto b = static_cast<std::size_t>(std::floor(position * static_cast<double>(n) + 0.5));
      if (b >= n) b -= n;
      out.position[k] = position >= 1.0 ? position - 1.0 : position;
      out.bin_of[k] = static_cast<int>(b);
      PhaseBin& bin = out.bins[b];
      bin.samples.push_back(k);
      if (bin.cycles.empty() || bin.cycles.back() != ci) bin.cycles.push_back(ci);
    }
  }
  for (int b : out.bin_of) out.unassigned_samples += b < 0 ? 1 : 0;
  for (PhaseBin& bin : out.bins) {
    if (bin.samples.empty()) {
      bin.mean_volume_m3 = bin.min_volume_m3 = bin.max_volume_m3 = std::nan("");
      continue;
    }
    double sum = 0.0;
    bin.min_volume_m3 = bin.max_volume_m3 = volume_m3[bin.samples.front()];
    for (std::size_t s : bin.samples) {
      sum += volume_m3[s];
      bin.min_volume_m3 = std::min(bin.min_volume_m3, volume_m3[s]);
      bin.max_volume_m3 = std::max(bin.max_volume_m3, volume_m3[s]);
    }
    bin.mean_volume_m3 = sum / static_cast<double>(bin.samples.size());
  }
  return out;
}

}  // namespace pneuma::physiology
