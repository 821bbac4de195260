// One hour of breathing at 100 Hz output (the goal: under 0.5 s of wall time).
// Baseline in the same run: filling the same number of samples with the closed-form solution
// of the linear pressure-control model, i.e. the cost of producing the output alone.
#include <benchmark/benchmark.h>

#include <cmath>

#include "pneuma/physiology/simulate.h"

namespace {

using namespace pneuma::physiology;
constexpr double kCmH2O = 98.0665;

Protocol protocol(const Driver& driver, int compartments) {
  Mechanics m;
  m.airway_resistance_pa_s_per_m3 = 2 * kCmH2O / 1e-3;
  if (compartments == 1) {
    m.compartments = {{"lung", LinearCompliance{0.1e-3 / kCmH2O}, 0.0}};
  } else {
    m.compartments = {{"upper", LinearCompliance{0.04e-3 / kCmH2O}, 1 * kCmH2O / 1e-3},
                      {"lower", LinearCompliance{0.06e-3 / kCmH2O}, 1 * kCmH2O / 1e-3}};
  }
  return Protocol{{Setting{0.0, m, driver}}};
}

void run_hour(benchmark::State& state, const Driver& driver, int compartments) {
  const Protocol p = protocol(driver, compartments);
  SimulationOptions o;
  o.duration_s = 3600.0;
  o.output_rate_hz = 100.0;
  for (auto _ : state) {
    auto r = simulate(p, o);
    benchmark::DoNotOptimize(r.series.volume_m3.data());
    state.counters["steps"] = static_cast<double>(r.stats.steps);
  }
  state.counters["simulated_s_per_wall_s"] =
      benchmark::Counter(3600.0 * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

void BM_HourSpontaneousSingle(benchmark::State& s) { run_hour(s, Spontaneous{0.2, 0.5, 5 * kCmH2O, 0.0}, 1); }
void BM_HourVolumeControlSingle(benchmark::State& s) {
  run_hour(s, VolumeControl{0.25, 0.5e-3, 1.0, 0.2, 5 * kCmH2O}, 1);
}
void BM_HourPressureControlTwo(benchmark::State& s) {
  run_hour(s, PressureControl{0.25, 12 * kCmH2O, 1.0, 5 * kCmH2O}, 2);
}

// Baseline: the closed-form pressure-control volume written into the same 360,001 samples.
void BM_HourClosedFormBaseline(benchmark::State& state) {
  const double tau = 0.2, c_dp = 1.2e-3, period = 4.0, ti = 1.0;
  for (auto _ : state) {
    std::vector<double> t(360001), v(360001);
    for (std::size_t k = 0; k < t.size(); ++k) {
      t[k] = static_cast<double>(k) / 100.0;
      const double phase = std::fmod(t[k], period);
      v[k] = phase < ti ? c_dp * (1 - std::exp(-phase / tau))
                        : c_dp * (1 - std::exp(-ti / tau)) * std::exp(-(phase - ti) / tau);
    }
    benchmark::DoNotOptimize(v.data());
  }
}

}  // namespace

BENCHMARK(BM_HourClosedFormBaseline)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_HourSpontaneousSingle)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_HourVolumeControlSingle)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_HourPressureControlTwo)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
