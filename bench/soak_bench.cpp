// A 24 h soak of simulated breathing (physiology only): does the lung drift over a day of
// breaths? Each shipped scenario's physiology (its preset, driver and timed actions) runs for
// 24 h; the counters report, over the breaths after the last action has settled (the second
// hour on):
//   eev_drift_mL_per_h   slope of a least-squares line through the end-expiratory volumes
//   eev_range_mL / _std  spread of the end-expiratory volume (stability)
//   vt_range_mL          spread of the tidal volume
//   volume_drift_mL_per_h  change of the mean lung volume of an hour, first to last hour
// Baseline in the same run: a 3 h soak, so the wall-time ratio shows whether a long run slows
// down (24 h should cost ~8x the 3 h run).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "pneuma/runner/output_registry.h"
#include "pneuma/scenario/scenario.h"

namespace {

using namespace pneuma;

constexpr double kHour = 3600.0;

scenario::Scenario scenario_for(const char* name, double duration_s) {
  scenario::Scenario s = runner::load_scenario(std::string(PNEUMA_BENCH_SOURCE_DIR) + "/scenarios/" + name + ".yaml");
  s.physiology.options.duration_s = duration_s;
  return s;
}

// Least-squares slope of y against x.
double slope(const std::vector<double>& x, const std::vector<double>& y) {
  const double n = static_cast<double>(x.size());
  const double mx = std::accumulate(x.begin(), x.end(), 0.0) / n, my = std::accumulate(y.begin(), y.end(), 0.0) / n;
  double sxy = 0.0, sxx = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
  }
  return sxy / sxx;
}

double mean_volume_between(const physiology::TimeSeries& series, double from_s, double to_s) {
  double sum = 0.0;
  std::size_t n = 0;
  for (std::size_t k = 0; k < series.size(); ++k) {
    if (series.time_s[k] >= from_s && series.time_s[k] < to_s) {
      sum += series.volume_m3[k];
      ++n;
    }
  }
  return sum / static_cast<double>(n);
}

void soak(benchmark::State& state, const char* name, double hours) {
  const scenario::Scenario s = scenario_for(name, hours * kHour);
  physiology::SimulationResult r;
  for (auto _ : state) {
    r = scenario::simulate_physiology(s, 10.0);  // 10 Hz: 864,000 samples a day
    benchmark::DoNotOptimize(r.series.volume_m3.data());
  }
  std::vector<double> t, eev, vt;
  for (const auto& b : r.breaths) {
    if (b.start_s < kHour) continue;  // past every action and its transient
    t.push_back(b.start_s / kHour);
    eev.push_back(b.end_expiratory_volume_m3 * 1e6);
    vt.push_back(b.tidal_volume_m3 * 1e6);
  }
  state.counters["breaths"] = static_cast<double>(r.breaths.size());
  state.counters["simulated_h_per_wall_s"] =
      benchmark::Counter(hours * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  if (t.size() < 2) return;
  const double mean = std::accumulate(eev.begin(), eev.end(), 0.0) / static_cast<double>(eev.size());
  double var = 0.0;
  for (double v : eev) var += (v - mean) * (v - mean);
  const auto [eev_lo, eev_hi] = std::minmax_element(eev.begin(), eev.end());
  const auto [vt_lo, vt_hi] = std::minmax_element(vt.begin(), vt.end());
  state.counters["eev_mean_mL"] = mean;
  state.counters["eev_drift_mL_per_h"] = slope(t, eev);
  state.counters["eev_range_mL"] = *eev_hi - *eev_lo;
  state.counters["eev_std_mL"] = std::sqrt(var / static_cast<double>(eev.size()));
  state.counters["vt_range_mL"] = *vt_hi - *vt_lo;
  const double first = mean_volume_between(r.series, kHour, 2 * kHour);
  const double last = mean_volume_between(r.series, (hours - 1) * kHour, hours * kHour);
  state.counters["volume_drift_mL_per_h"] = (last - first) * 1e6 / (hours - 2.0);
}

void BM_SoakQuietBreathing(benchmark::State& s) { soak(s, "quiet-breathing", static_cast<double>(s.range(0))); }
void BM_SoakVentilatedPatient(benchmark::State& s) { soak(s, "ventilated-patient", static_cast<double>(s.range(0))); }

}  // namespace

// 3 h: the baseline (an hour after the settling hour, and the last); 24 h: the soak.
BENCHMARK(BM_SoakQuietBreathing)->Arg(3)->Arg(24)->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK(BM_SoakVentilatedPatient)->Arg(3)->Arg(24)->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK_MAIN();
