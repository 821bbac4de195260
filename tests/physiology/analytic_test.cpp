// Closed-form oracles of the linear single-compartment model.
#include <gtest/gtest.h>

#include <cmath>

#include "physiology_fixture.h"

using namespace pneuma::physiology;
using namespace pneuma::test;

namespace {

double relative_error(double actual, double expected) { return std::abs(actual - expected) / std::abs(expected); }

}  // namespace

TEST(Analytic, VolumeControlAirwayPressureIsPeepPlusResistivePlusElastic) {
  const double C = 0.05 * kLPerCmH2O, R = 10 * kCmH2OsPerL, peep = 5 * kCmH2O;
  const double vt = 0.5 * kLitre, ti = 1.0;
  const double q = vt / ti;
  const auto result = simulate(just(single_linear(0.05, 10), VolumeControl{0.2, vt, ti, 0.0, peep}), tight(5.0));
  const auto& s = result.series;
  int checked = 0;
  for (std::size_t k = 0; k < s.size(); ++k) {
    const double t = s.time_s[k];
    if (t <= 0.0 || t >= ti) continue;
    EXPECT_LT(relative_error(s.airway_pressure_pa[k], peep + R * q + q * t / C), 1e-6) << "t = " << t;
    EXPECT_LT(relative_error(s.volume_m3[k], C * peep + q * t), 1e-6) << "t = " << t;
    ++checked;
  }
  EXPECT_EQ(checked, 99);
}

TEST(Analytic, PassiveExpirationDecaysWithTimeConstantRC) {
  const double C = 0.05 * kLPerCmH2O, R = 10 * kCmH2OsPerL, tau = R * C;  // 0.5 s
  const double vt = 0.5 * kLitre, ti = 1.0;
  const auto result = simulate(just(single_linear(0.05, 10), VolumeControl{0.2, vt, ti, 0.0, 0.0}), tight(5.0));
  const auto& s = result.series;
  for (std::size_t k = 0; k < s.size(); ++k) {
    const double t = s.time_s[k];
    if (t < ti || t >= 5.0) continue;
    EXPECT_LT(relative_error(s.volume_m3[k], vt * std::exp(-(t - ti) / tau)), 1e-6) << "t = " << t;
  }
}

TEST(Analytic, PressureControlVolumeRisesAsOneMinusExponential) {
  const double C = 0.05 * kLPerCmH2O, R = 8 * kCmH2OsPerL, dp = 15 * kCmH2O, ti = 1.2;
  const auto result = simulate(just(single_linear(0.05, 8), PressureControl{0.2, dp, ti, 5 * kCmH2O}), tight(5.0));
  const auto& s = result.series;
  int checked = 0;
  for (std::size_t k = 0; k < s.size(); ++k) {
    const double t = s.time_s[k];
    if (t <= 0.0 || t >= ti) continue;
    const double above_peep = s.volume_m3[k] - C * 5 * kCmH2O;  // PEEP 5 holds C * PEEP at rest
    EXPECT_LT(relative_error(above_peep, C * dp * (1 - std::exp(-t / (R * C)))), 1e-6) << "t = " << t;
    ++checked;
  }
  EXPECT_GT(checked, 100);
}

TEST(Analytic, EndExpiratoryVolumeDoesNotDriftOverAThousandBreaths) {
  // Pressure control with incomplete expiration (Te = 2 tau): the periodic end-expiratory
  // volume is V_ee = b C dP (1 - a) / (1 - a b), a = exp(-Ti/tau), b = exp(-Te/tau).
  const double C = 0.05 * kLPerCmH2O, R = 20 * kCmH2OsPerL, tau = R * C;  // 1 s
  const double dp = 10 * kCmH2O, rate = 20.0 / 60.0, ti = 1.0, te = 1.0 / rate - ti;
  const double a = std::exp(-ti / tau), b = std::exp(-te / tau);
  const double expected = b * C * dp * (1 - a) / (1 - a * b);
  auto options = tight(1000.0 / rate + 1e-6, 0.0);
  options.solver.relative_tolerance = 1e-10;
  const auto result = simulate(just(single_linear(0.05, 20), PressureControl{rate, dp, ti, 0.0}), options);
  ASSERT_EQ(result.breaths.size(), 1000u);
  EXPECT_LT(relative_error(result.breaths[49].end_expiratory_volume_m3, expected), 1e-6);
  EXPECT_LT(relative_error(result.breaths[999].end_expiratory_volume_m3, expected), 1e-6);
  EXPECT_LT(std::abs(result.breaths[999].end_expiratory_volume_m3 - result.breaths[49].end_expiratory_volume_m3),
            1e-9 * expected * 1000);
}

TEST(Analytic, VolumeControlBreathMetricsMatchTheirDefinitions) {
  // With an end-inspiratory pause the flow stops, so the plateau is PEEP + VT / C exactly.
  const double C = 0.04 * kLPerCmH2O, R = 12 * kCmH2OsPerL, peep = 8 * kCmH2O;
  const double vt = 0.4 * kLitre, ti = 1.2, pause = 0.3, q = vt / (ti - pause);
  const auto result =
      simulate(just(single_linear(0.04, 12), VolumeControl{0.25, vt, ti, pause, peep}), tight(8.0, 50.0));
  ASSERT_EQ(result.breaths.size(), 2u);
  const auto& b = result.breaths[0];
  EXPECT_LT(relative_error(b.tidal_volume_m3, vt), 1e-9);
  EXPECT_LT(relative_error(b.plateau_pressure_pa, peep + vt / C), 1e-9);
  EXPECT_LT(relative_error(b.peak_pressure_pa, peep + R * q + vt / C), 1e-9);
  EXPECT_LT(relative_error(b.dynamic_compliance_m3_per_pa, vt / (R * q + vt / C)), 1e-9);
  EXPECT_LT(relative_error(b.minute_ventilation_m3_per_s, vt * 0.25), 1e-9);
  EXPECT_DOUBLE_EQ(b.duration_s, 4.0);
}
