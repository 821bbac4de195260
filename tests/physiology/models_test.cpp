// Model-level invariants: equal halves, sigmoid saturation, targets, timed actions.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "physiology_fixture.h"
#include "pneuma/core/error.h"

using namespace pneuma::physiology;
using namespace pneuma::test;

namespace {

Mechanics two_halves(double compliance_l_per_cmh2o, double airway, double branch) {
  Mechanics m;
  m.airway_resistance_pa_s_per_m3 = airway * kCmH2OsPerL;
  const LinearCompliance half{compliance_l_per_cmh2o / 2 * kLPerCmH2O};
  m.compartments = {{"upper", half, branch * kCmH2OsPerL}, {"lower", half, branch * kCmH2OsPerL}};
  return m;
}

}  // namespace

TEST(Models, TwoEqualHalvesEqualTheSingleModel) {
  // Parallel halves: C = 2 C_i, R = R_aw + R_i / 2.
  const Mechanics single = single_linear(0.08, 1.0 + 4.0 / 2.0);
  const Mechanics halves = two_halves(0.08, 1.0, 4.0);
  for (const Driver& driver :
       {Driver{PressureControl{0.25, 12 * kCmH2O, 1.0, 5 * kCmH2O}},
        Driver{VolumeControl{0.25, 0.45e-3, 1.1, 0.2, 5 * kCmH2O}}, Driver{Spontaneous{0.2, 0.5, 6 * kCmH2O, 0.0}}}) {
    const auto a = simulate(just(single, driver), tight(12.0));
    const auto b = simulate(just(halves, driver), tight(12.0));
    ASSERT_EQ(a.series.size(), b.series.size());
    for (std::size_t k = 0; k < a.series.size(); ++k) {
      EXPECT_NEAR(b.series.volume_m3[k], a.series.volume_m3[k], 1e-9 * 0.5e-3) << mode_name(driver);
      EXPECT_NEAR(b.series.airway_pressure_pa[k], a.series.airway_pressure_pa[k], 1e-6) << mode_name(driver);
      EXPECT_NEAR(b.series.compartment_volume_m3[0][k], b.series.compartment_volume_m3[1][k], 1e-12);
    }
  }
}

TEST(Models, SigmoidVolumeSaturatesTowardTotalLungCapacity) {
  // Venegas: V(P) = a + b / (1 + exp(-(P - c)/d)). Held long enough at P_rest + dP, the lung
  // reaches exactly that volume; raising dP tenfold cannot pass a + b.
  const SigmoidCompliance s{1.0e-3, 5.0e-3, 10 * kCmH2O, 5 * kCmH2O, 2.5e-3};
  Mechanics m;
  m.airway_resistance_pa_s_per_m3 = 2 * kCmH2OsPerL;
  m.compartments = {{"lung", s, 0.0}};
  const double p_rest = s.inflection_pressure_pa - s.width_pa * std::log(s.volume_range_m3 / (2.5e-3 - 1.0e-3) - 1);
  for (double dp_cmh2o : {10.0, 100.0}) {
    const double dp = dp_cmh2o * kCmH2O;
    const auto r = simulate(just(m, PressureControl{0.05, dp, 15.0, 0.0}), tight(20.0, 10.0));
    const double equilibrium =
        s.lower_volume_m3 + s.volume_range_m3 / (1 + std::exp(-(p_rest + dp - s.inflection_pressure_pa) / s.width_pa));
    const double absolute = s.relaxed_volume_m3 + r.breaths[0].tidal_volume_m3;
    EXPECT_NEAR(absolute, equilibrium, 1e-6 * equilibrium) << dp_cmh2o << " cmH2O";
    EXPECT_LT(absolute, s.lower_volume_m3 + s.volume_range_m3);
  }
  // Compliance at rest follows the curve's slope: VT for a small pressure is ~ C(0) dP.
  const double c0 = compliance_at(s, 0.0);
  EXPECT_NEAR(elastic_pressure(s, 1e-10), 1e-10 / c0, 1e-5 * 1e-10 / c0);
}

TEST(Models, SpontaneousTargetTidalVolumeIsReached) {
  for (const Mechanics& m : {single_linear(0.1, 2.0), single_linear(0.12, 15.0)}) {
    const auto r = simulate(just(m, Spontaneous{0.2, 0.5, 0.0, 0.5e-3}), tight(60.0, 10.0));
    ASSERT_GE(r.breaths.size(), 12u);
    EXPECT_NEAR(r.breaths.back().tidal_volume_m3, 0.5e-3, 1e-6 * 0.5e-3);
    EXPECT_GT(r.breaths.back().muscle_amplitude_pa, 0.0);
  }
}

TEST(Models, UnreachableTidalVolumeIsAClearError) {
  const SigmoidCompliance s{1.0e-3, 5.0e-3, 10 * kCmH2O, 5 * kCmH2O, 2.5e-3};
  Mechanics m;
  m.airway_resistance_pa_s_per_m3 = 2 * kCmH2OsPerL;
  m.compartments = {{"lung", s, 0.0}};
  try {
    simulate(just(m, Spontaneous{0.2, 0.5, 0.0, 4.0e-3}), tight(10.0, 0.0));  // beyond TLC
    FAIL() << "a tidal volume beyond total lung capacity was accepted";
  } catch (const pneuma::Error& e) {
    EXPECT_EQ(e.code(), pneuma::ExitCode::bad_input);
    EXPECT_NE(std::string(e.what()).find("4000 mL cannot be reached"), std::string::npos) << e.what();
  }
}

TEST(Models, ActionsChangeMechanicsAtOnceAndTheDriverAtTheNextBreath) {
  // Compliance halves at t = 10 s: the pressure-control tidal volume (long Ti, so complete
  // filling) follows C dP; the rate change at t = 21 s applies from the breath at 25 s.
  const double dp = 10 * kCmH2O;
  Protocol p = just(single_linear(0.05, 5.0), PressureControl{0.2, dp, 2.5, 0.0});
  Setting stiff = p.settings[0];
  stiff.start_time_s = 10.0;
  stiff.mechanics = single_linear(0.025, 5.0);
  Setting faster = stiff;
  faster.start_time_s = 21.0;
  faster.driver = PressureControl{0.25, dp, 2.0, 0.0};
  p.settings = {p.settings[0], stiff, faster};
  const auto r = simulate(p, tight(37.0, 10.0));
  ASSERT_EQ(r.breaths.size(), 8u);  // 5 of 5 s (to 25 s), then 3 of 4 s (to 37 s)
  const double tau1 = 0.05 * kLPerCmH2O * 5 * kCmH2OsPerL, tau2 = tau1 / 2;
  EXPECT_NEAR(r.breaths[0].tidal_volume_m3, 0.05 * kLPerCmH2O * dp * (1 - std::exp(-2.5 / tau1)), 1e-9);
  EXPECT_NEAR(r.breaths[3].tidal_volume_m3, 0.025 * kLPerCmH2O * dp * (1 - std::exp(-2.5 / tau2)), 1e-9);
  EXPECT_DOUBLE_EQ(r.breaths[4].duration_s, 5.0);
  EXPECT_DOUBLE_EQ(r.breaths[5].start_s, 25.0);
  EXPECT_DOUBLE_EQ(r.breaths[5].duration_s, 4.0);
}

TEST(Models, InvalidSettingsAreRefusedByName) {
  EXPECT_THROW(simulate(just(single_linear(-0.1, 2.0), PressureControl{0.2, 1000, 1.0, 0}), tight(5)),
               pneuma::ValueError);
  EXPECT_THROW(simulate(just(single_linear(0.1, 2.0), PressureControl{0.2, 1000, 6.0, 0}), tight(5)),
               pneuma::ValueError);
}

TEST(Models, TidalVolumeIsTheSwingOfTheSampledVolume) {
  // Spontaneous breathing: the volume keeps rising after the inspiratory phase ends (the muscle
  // relaxes slowly), so the tidal volume is max - min over the breath, not the inspired volume.
  const auto r = simulate(just(single_linear(0.1, 2.0), Spontaneous{0.2, 0.5, 0.0, 0.5e-3}), tight(30.0, 1000.0));
  ASSERT_GE(r.breaths.size(), 4u);
  for (std::size_t k = 1; k < r.breaths.size(); ++k) {
    const auto& b = r.breaths[k];
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (std::size_t i = 0; i < r.series.size(); ++i) {
      const double t = r.series.time_s[i];
      if (t < b.start_s - 1e-9 || t > b.start_s + b.duration_s + 1e-9) continue;
      lo = std::min(lo, r.series.volume_m3[i]);
      hi = std::max(hi, r.series.volume_m3[i]);
    }
    EXPECT_NEAR(b.tidal_volume_m3, hi - lo, 1e-5 * b.tidal_volume_m3) << k;
    EXPECT_NEAR(b.set_tidal_volume_m3, 0.5e-3, 1e-15);
    EXPECT_GE(b.tidal_volume_m3, b.inspired_volume_m3);
  }
  EXPECT_NEAR(r.breaths.back().tidal_volume_m3, 0.5e-3, 1e-6 * 0.5e-3);  // the target is the swing
}
