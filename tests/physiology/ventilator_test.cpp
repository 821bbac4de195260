// Assisted ventilation against closed-form oracles of the linear one-compartment (RC) lung:
// plateau, cycle instants (flow, volume, pressure limit), trigger instants of a known effort.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <string>

#include "physiology_fixture.h"

using namespace pneuma::physiology;
using namespace pneuma::test;

namespace {

double relative_error(double actual, double expected) { return std::abs(actual - expected) / std::abs(expected); }

// The root of f on [a, b] (f(a), f(b) of opposite signs), by bisection to the last bit.
double bisect(const std::function<double(double)>& f, double a, double b) {
  const double fa = f(a);
  for (int i = 0; i < 200; ++i) {
    const double m = 0.5 * (a + b);
    if ((f(m) > 0) == (fa > 0)) a = m;
    else b = m;
  }
  return 0.5 * (a + b);
}

Assisted vc_ac(double rate_hz, double vt_m3, double ti_s, double pause_s, double peep_pa) {
  Assisted a;
  a.mode = AssistMode::volume;
  a.rate_hz = rate_hz;
  a.tidal_volume_m3 = vt_m3;
  a.inspiratory_time_s = ti_s;
  a.pause_time_s = pause_s;
  a.peep_pa = peep_pa;
  a.trigger_threshold = 2 * kLitre / 60;
  return a;
}

Assisted pressure_mode(AssistMode mode, double rate_hz, double dp_pa, double ti_s, double peep_pa) {
  Assisted a;
  a.mode = mode;
  a.rate_hz = rate_hz;
  a.inspiratory_pressure_pa = dp_pa;
  a.inspiratory_time_s = ti_s;
  a.peep_pa = peep_pa;
  a.trigger_threshold = 2 * kLitre / 60;
  return a;
}

Protocol with_effort(const Mechanics& m, const Driver& d, PatientEffort effort) {
  return Protocol{{Setting{0.0, m, d, effort}}};
}

}  // namespace

TEST(Ventilator, VolumeAssistPlateauIsPeepPlusTidalVolumeOverCompliance) {
  // Passive patient: every breath on the backup timer. With the pause the flow stops, so the
  // plateau is PEEP + VT / C; the expiration leaves VT e^(-Te/tau) behind (intrinsic PEEP).
  const double C = 0.05 * kLPerCmH2O, R = 10 * kCmH2OsPerL, tau = R * C, peep = 5 * kCmH2O;
  const double vt = 0.5 * kLitre, ti = 1.2, pause = 0.3, tf = ti - pause, q = vt / tf, rate = 0.25;
  const double te = 1 / rate - ti;
  const auto r = simulate(just(single_linear(0.05, 10), vc_ac(rate, vt, ti, pause, peep)), tight(12.0));
  ASSERT_EQ(r.breaths.size(), 3u);
  const auto& b = r.breaths[0];
  EXPECT_STREQ(b.mode, "vc_ac");
  EXPECT_STREQ(b.trigger, "time");
  EXPECT_STREQ(b.cycle, "time");
  EXPECT_LT(relative_error(b.plateau_pressure_pa, peep + vt / C), 1e-9);
  EXPECT_LT(relative_error(b.peak_pressure_pa, peep + R * q + vt / C), 1e-9);
  EXPECT_LT(relative_error(b.inspired_volume_m3, vt), 1e-9);
  EXPECT_DOUBLE_EQ(b.inspiratory_time_s, ti);
  EXPECT_DOUBLE_EQ(b.duration_s, 4.0);
  EXPECT_LT(relative_error(b.intrinsic_peep_pa, vt / C * std::exp(-te / tau)), 1e-6);
  // Mean airway pressure: Paw is linear in the flow phase, constant in the pause and expiration.
  const double integral = tf * (peep + R * q) + q * tf * tf / (2 * C) + pause * (peep + vt / C) + te * peep;
  EXPECT_LT(relative_error(b.mean_airway_pressure_pa, integral / 4.0), 1e-9);
}

TEST(Ventilator, PassiveVolumeAssistBreathesAsVolumeControl) {
  // No effort, no trigger: VC-AC is VC-CMV, sample for sample.
  const Mechanics m = single_linear(0.04, 12);
  const auto a = simulate(just(m, VolumeControl{0.25, 0.4e-3, 1.2, 0.3, 8 * kCmH2O}), tight(12.0));
  const auto b = simulate(just(m, vc_ac(0.25, 0.4e-3, 1.2, 0.3, 8 * kCmH2O)), tight(12.0));
  ASSERT_EQ(a.series.size(), b.series.size());
  for (std::size_t k = 0; k < a.series.size(); ++k) {
    EXPECT_NEAR(b.series.volume_m3[k], a.series.volume_m3[k], 1e-12 * 0.4e-3);
    EXPECT_NEAR(b.series.airway_pressure_pa[k], a.series.airway_pressure_pa[k], 1e-9 * kCmH2O);
  }
  ASSERT_EQ(a.breaths.size(), b.breaths.size());
  EXPECT_NEAR(b.breaths[1].plateau_pressure_pa, a.breaths[1].plateau_pressure_pa, 1e-9 * kCmH2O);
}

TEST(Ventilator, DeceleratingRampDeliversTheTidalVolume) {
  const double C = 0.05 * kLPerCmH2O, peep = 5 * kCmH2O, vt = 0.45 * kLitre;
  Assisted a = vc_ac(0.25, vt, 1.0, 0.2, peep);
  a.waveform = FlowWaveform::decelerating;
  const auto r = simulate(just(single_linear(0.05, 10), a), tight(8.0));
  ASSERT_EQ(r.breaths.size(), 2u);
  EXPECT_LT(relative_error(r.breaths[0].inspired_volume_m3, vt), 1e-9);
  EXPECT_LT(relative_error(r.breaths[0].plateau_pressure_pa, peep + vt / C), 1e-9);
  // The flow starts at twice the mean flow and falls linearly to 0.
  EXPECT_LT(relative_error(r.series.flow_m3_per_s[10], 2 * vt / 0.8 * (1 - 0.1 / 0.8)), 1e-9);
}

TEST(Ventilator, FlowCycleEndsAStepBreathAtTauLnOneOverFraction) {
  // A pressure step on an RC lung: Q = (P/R) e^(-t/tau), highest at the step, so the flow falls
  // to f times its peak at t = tau ln(1/f), when the lung holds C P (1 - f).
  const double C = 0.05 * kLPerCmH2O, R = 10 * kCmH2OsPerL, tau = R * C, dp = 15 * kCmH2O;
  for (double f : {0.25, 0.1, 0.5}) {
    Assisted a = pressure_mode(AssistMode::pressure, 0.2, dp, 2.5, 5 * kCmH2O);
    a.cycle = CycleKind::flow;
    a.cycle_fraction = f;
    const auto r = simulate(just(single_linear(0.05, 10), a), tight(10.0));
    ASSERT_EQ(r.breaths.size(), 2u);
    EXPECT_STREQ(r.breaths[0].cycle, "flow");
    const double expected = tau * std::log(1 / f);
    EXPECT_NEAR(r.breaths[0].inspiratory_time_s, expected, 1e-9) << f;
    EXPECT_LT(relative_error(r.breaths[0].inspired_volume_m3, C * dp * (1 - f)), 1e-8) << f;
  }
}

TEST(Ventilator, FlowCycleWithARiseTimeFindsThePeakFlowFirst) {
  // Paw = PEEP + P (1 - e^(-kt)), k = 3 / rise: x = C P (1 - e^(-t/tau)) - C P (e^(-kt) - e^(-t/tau)) / (1 - k tau),
  // Q = dx/dt rises to a peak, then falls; the breath cycles where Q = f * peak.
  const double C = 0.05 * kLPerCmH2O, R = 10 * kCmH2OsPerL, tau = R * C, dp = 12 * kCmH2O, rise = 0.3;
  const double k = 3 / rise, f = 0.3;
  const auto flow = [&](double t) {
    return C * dp / tau * std::exp(-t / tau) -
           C * dp / (1 - k * tau) * (-k * std::exp(-k * t) + std::exp(-t / tau) / tau);
  };
  const auto dflow = [&](double t) {
    return -C * dp / (tau * tau) * std::exp(-t / tau) -
           C * dp / (1 - k * tau) * (k * k * std::exp(-k * t) - std::exp(-t / tau) / (tau * tau));
  };
  const double t_peak = bisect(dflow, 1e-6, 2.0);
  const double peak = flow(t_peak);
  const double t_cycle = bisect([&](double t) { return flow(t) - f * peak; }, t_peak, 3.0);
  Assisted a = pressure_mode(AssistMode::pressure, 0.2, dp, 2.5, 5 * kCmH2O);
  a.cycle = CycleKind::flow;
  a.cycle_fraction = f;
  a.rise_time_s = rise;
  const auto r = simulate(just(single_linear(0.05, 10), a), tight(10.0));
  ASSERT_EQ(r.breaths.size(), 2u);
  EXPECT_NEAR(r.breaths[0].inspiratory_time_s, t_cycle, 1e-8);
}

TEST(Ventilator, VolumeCycleAndLimits) {
  const double C = 0.05 * kLPerCmH2O, R = 10 * kCmH2OsPerL, tau = R * C, dp = 15 * kCmH2O, peep = 5 * kCmH2O;
  // Volume cycle: C P (1 - e^(-t/tau)) = Vc.
  Assisted a = pressure_mode(AssistMode::pressure, 0.2, dp, 2.5, peep);
  a.cycle = CycleKind::volume;
  a.cycle_volume_m3 = 0.4 * kLitre;
  auto r = simulate(just(single_linear(0.05, 10), a), tight(10.0));
  ASSERT_EQ(r.breaths.size(), 2u);
  EXPECT_STREQ(r.breaths[0].cycle, "volume");
  EXPECT_NEAR(r.breaths[0].inspiratory_time_s, -tau * std::log(1 - 0.4 * kLitre / (C * dp)), 1e-9);
  // The same volume as a limit on a time-cycled breath.
  a.cycle = CycleKind::time;
  a.volume_limit_m3 = 0.4 * kLitre;
  r = simulate(just(single_linear(0.05, 10), a), tight(10.0));
  EXPECT_STREQ(r.breaths[0].cycle, "volume_limit");
  EXPECT_NEAR(r.breaths[0].inspiratory_time_s, -tau * std::log(1 - 0.4 * kLitre / (C * dp)), 1e-9);
  // Pressure limit on a square flow: Paw = PEEP + R q + q t / C reaches the limit at
  // t = (limit - PEEP - R q) C / q; the breath ends there, without its pause.
  const double vt = 0.6 * kLitre, q = vt / 0.8, limit = 20 * kCmH2O;
  Assisted v = vc_ac(0.25, vt, 1.0, 0.2, peep);
  v.pressure_limit_pa = limit;
  r = simulate(just(single_linear(0.05, 10), v), tight(8.0));
  ASSERT_EQ(r.breaths.size(), 2u);
  EXPECT_STREQ(r.breaths[0].cycle, "pressure_limit");
  EXPECT_NEAR(r.breaths[0].inspiratory_time_s, (limit - peep - R * q) * C / q, 1e-9);
  EXPECT_LT(relative_error(r.breaths[0].peak_pressure_pa, limit), 1e-9);
}

TEST(Ventilator, FlowTriggerOfAKnownEffort) {
  // From rest at PEEP, the effort Pmus = A/2 (1 - cos(w t)), w = pi / Ti, drives the RC lung:
  // x = (A C / 2)(1 - e^(-t/tau)) - (A C / 2)(cos wt + w tau sin wt - e^(-t/tau)) / (1 + (w tau)^2),
  // and the breath starts where Q = dx/dt reaches the trigger threshold.
  const double C = 0.05 * kLPerCmH2O, R = 10 * kCmH2OsPerL, tau = R * C;
  const double A = 6 * kCmH2O, rate = 0.25, ti_effort = 4.0 / 3.0, w = std::numbers::pi / ti_effort;
  const double threshold = 3 * kLitre / 60;  // 3 L/min
  const auto flow = [&](double t) {
    const double e = std::exp(-t / tau);
    return A * C / 2 * e / tau -
           A * C / 2 / (1 + w * w * tau * tau) * (-w * std::sin(w * t) + w * w * tau * std::cos(w * t) + e / tau);
  };
  const double expected = bisect([&](double t) { return flow(t) - threshold; }, 1e-6, 0.6);
  Assisted a = pressure_mode(AssistMode::pressure_support, 0.0, 8 * kCmH2O, 3.0, 5 * kCmH2O);
  a.cycle = CycleKind::flow;
  a.trigger_threshold = threshold;
  const auto r = simulate(with_effort(single_linear(0.05, 10), a, PatientEffort{rate, 0.5, A}), tight(12.5));
  ASSERT_GE(r.breaths.size(), 2u);
  EXPECT_STREQ(r.breaths[0].mode, "cpap_psv");
  EXPECT_STREQ(r.breaths[0].trigger, "patient_flow");
  EXPECT_NEAR(r.breaths[0].start_s, expected, 1e-9);
  EXPECT_NEAR(r.breaths[0].trigger_delay_s, expected, 1e-9);
  EXPECT_STREQ(r.breaths[0].cycle, "flow");
  // One breath per effort, each triggered by its own effort.
  for (const auto& b : r.breaths) {
    EXPECT_EQ(b.missed_triggers, 0);
    EXPECT_FALSE(b.double_triggered);
    EXPECT_GT(b.trigger_delay_s, 0.0);
    EXPECT_LT(b.trigger_delay_s, ti_effort);
  }
  EXPECT_NEAR(r.breaths[1].start_s - r.breaths[0].start_s, 1 / rate, 0.05);
}

TEST(Ventilator, PressureTriggerOfAKnownEffort) {
  // The circuit closes when the patient pulls: no flow, Paw = PEEP - Pmus, so the breath starts
  // where Pmus reaches the threshold: t = (Ti / pi) acos(1 - 2 threshold / A).
  const double A = 6 * kCmH2O, rate = 0.25, ti_effort = 4.0 / 3.0, threshold = 2 * kCmH2O;
  Assisted a = pressure_mode(AssistMode::pressure_support, 0.0, 8 * kCmH2O, 3.0, 5 * kCmH2O);
  a.cycle = CycleKind::flow;
  a.trigger = TriggerKind::pressure;
  a.trigger_threshold = threshold;
  const auto r = simulate(with_effort(single_linear(0.05, 10), a, PatientEffort{rate, 0.5, A}), tight(12.5));
  ASSERT_GE(r.breaths.size(), 2u);
  EXPECT_STREQ(r.breaths[0].trigger, "patient_pressure");
  const double expected = ti_effort / std::numbers::pi * std::acos(1 - 2 * threshold / A);
  EXPECT_NEAR(r.breaths[0].start_s, expected, 1e-9);
  // Before the trigger the airway is occluded: no flow, the pressure falls below PEEP.
  const auto& s = r.series;
  for (std::size_t k = 1; s.time_s[k] < expected; ++k) {
    EXPECT_NEAR(s.flow_m3_per_s[k], 0.0, 1e-15);
    EXPECT_NEAR(s.airway_pressure_pa[k], 5 * kCmH2O - s.muscle_pressure_pa[k], 1e-9);
  }
}

TEST(Ventilator, WeakEffortsAreMissedStrongOnesTrigger) {
  const Mechanics m = single_linear(0.05, 10);
  Assisted a = vc_ac(12.0 / 60, 0.45e-3, 1.0, 0.0, 5 * kCmH2O);
  a.trigger_threshold = 10 * kLitre / 60;
  // 1 cmH2O cannot draw 10 L/min through 10 cmH2O*s/L: every breath on the backup timer.
  auto r = simulate(with_effort(m, a, PatientEffort{17.0 / 60, 0.5, 1 * kCmH2O}), tight(60.0, 10.0));
  int missed = 0;
  for (const auto& b : r.breaths) {
    EXPECT_STREQ(b.trigger, "time");
    missed += b.missed_triggers;
  }
  // The efforts that started within the reported breaths (one every 60/17 s from t = 0).
  const double last_end = r.breaths.back().start_s + r.breaths.back().duration_s;
  EXPECT_EQ(missed, static_cast<int>(std::ceil(last_end / (60.0 / 17) - 1e-9)));
  // A strong effort at 17 /min over a backup of 12 /min: every breath is the patient's.
  a.trigger_threshold = 2 * kLitre / 60;
  r = simulate(with_effort(m, a, PatientEffort{17.0 / 60, 0.5, 8 * kCmH2O}), tight(60.0, 10.0));
  // The first breath is the machine's (t = 0, during the first effort, which it swallows).
  ASSERT_GE(r.breaths.size(), 16u);
  EXPECT_STREQ(r.breaths[0].trigger, "time");
  EXPECT_EQ(r.breaths[0].missed_triggers, 1);
  for (std::size_t i = 1; i < r.breaths.size(); ++i) {
    EXPECT_STREQ(r.breaths[i].trigger, "patient_flow") << i;
    EXPECT_EQ(r.breaths[i].missed_triggers, 0) << i;
    EXPECT_FALSE(r.breaths[i].double_triggered) << i;
    // Entrained: one breath per effort, at the same delay once the lung is periodic.
    if (i >= 4) {
      EXPECT_NEAR(r.breaths[i].duration_s, 60.0 / 17, 1e-6) << i;
      EXPECT_NEAR(r.breaths[i].trigger_delay_s, r.breaths[i - 1].trigger_delay_s, 1e-6) << i;
    }
  }
}

TEST(Ventilator, ModeSwitchesMidRunLeaveNoGapBetweenBreaths) {
  // PC-AC, then CPAP + PS at 10 s (taking over the expiration in progress), then VC-CMV at 20 s
  // (a mandatory mode ends the assisted breath at once): the breaths tile the time.
  const Mechanics m = single_linear(0.05, 10);
  const PatientEffort effort{18.0 / 60, 0.5, 5 * kCmH2O};
  Assisted pc = pressure_mode(AssistMode::pressure, 12.0 / 60, 12 * kCmH2O, 1.0, 5 * kCmH2O);
  Assisted ps = pressure_mode(AssistMode::pressure_support, 0.0, 8 * kCmH2O, 2.0, 5 * kCmH2O);
  ps.cycle = CycleKind::flow;
  Protocol p{{Setting{0.0, m, pc, effort}, Setting{10.0, m, ps, effort},
              Setting{20.0, m, VolumeControl{0.25, 0.45e-3, 1.0, 0.0, 5 * kCmH2O}, PatientEffort{}}}};
  const auto r = simulate(p, tight(30.0, 10.0));
  ASSERT_GE(r.breaths.size(), 8u);
  for (std::size_t i = 1; i < r.breaths.size(); ++i) {
    EXPECT_NEAR(r.breaths[i].start_s, r.breaths[i - 1].start_s + r.breaths[i - 1].duration_s, 1e-12) << i;
  }
  bool psv = false, cmv = false;
  for (const auto& b : r.breaths) {
    const std::string mode = b.mode;
    if (mode == "cpap_psv") {
      psv = true;
      EXPECT_GE(b.start_s, 10.0);
      EXPECT_STREQ(b.trigger, "patient_flow");
      EXPECT_STREQ(b.cycle, "flow");
    }
    if (mode == "volume_control") {
      cmv = true;
      EXPECT_GE(b.start_s, 20.0);
      EXPECT_STREQ(b.trigger, "time");
    }
  }
  EXPECT_TRUE(psv);
  EXPECT_TRUE(cmv);
  // The first mandatory breath starts at the switch (the assisted breath before it ends there).
  bool at_switch = false;
  for (const auto& b : r.breaths)
    at_switch = at_switch || (std::string(b.mode) == "volume_control" && b.start_s == 20.0);
  EXPECT_TRUE(at_switch);
}

TEST(Ventilator, ALongStrongEffortOutlastingAShortBreathTriggersAgain) {
  // A 3 s effort of 12 cmH2O against a 0.6 s machine breath: the patient still pulls when the
  // machine cycles off, and triggers again (double triggering, a classic asynchrony).
  Assisted a = vc_ac(8.0 / 60, 0.3e-3, 0.6, 0.0, 5 * kCmH2O);
  const auto r =
      simulate(with_effort(single_linear(0.05, 10), a, PatientEffort{10.0 / 60, 1.0, 12 * kCmH2O}), tight(30.0, 10.0));
  int doubles = 0;
  for (std::size_t i = 1; i < r.breaths.size(); ++i) {
    const auto& b = r.breaths[i];
    const auto& before = r.breaths[i - 1];
    const bool patient = std::string(b.trigger) != "time", patient_before = std::string(before.trigger) != "time";
    // The effort's onset is the trigger time minus the delay: the same onset twice is a double trigger.
    const bool same_effort =
        patient && patient_before &&
        std::abs((b.start_s - b.trigger_delay_s) - (before.start_s - before.trigger_delay_s)) < 1e-9;
    EXPECT_EQ(b.double_triggered, same_effort) << i;
    doubles += b.double_triggered ? 1 : 0;
  }
  EXPECT_GE(doubles, 5);
}
