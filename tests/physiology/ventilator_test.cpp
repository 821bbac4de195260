// Assisted ventilation against closed-form oracles of the linear one-compartment (RC) lung:
// plateau, cycle instants (flow, volume, pressure limit), trigger instants of a known effort.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <string>

#include "physiology_fixture.h"
#include "pneuma/core/error.h"

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

namespace {

Assisted simv(AssistMode mode, double rate_hz, double window_s, double peep_pa) {
  Assisted a;
  a.mode = mode;
  a.rate_hz = rate_hz;
  a.trigger_window_s = window_s;
  a.peep_pa = peep_pa;
  a.inspiratory_time_s = 1.0;
  a.cycle = CycleKind::flow;
  a.trigger_threshold = 2 * kLitre / 60;
  return a;
}

}  // namespace

TEST(Ventilator, PassiveSimvGivesMandatoryBreathsAtTheSetRate) {
  // No effort: SIMV is VC-CMV, every breath the machine's at k * 60 / rate. Each expiration
  // (4 s, tau = 0.5 s) keeps k = e^(-8) of the volume: breath i starts x_i = VT k (1 - k^i) / (1 - k)
  // above the PEEP volume and its plateau is PEEP + (x_i + VT) / C.
  const double C = 0.05 * kLPerCmH2O, peep = 5 * kCmH2O, vt = 0.5 * kLitre, keep = std::exp(-8.0);
  Assisted a = simv(AssistMode::simv_volume, 0.2, 2.0, peep);
  a.tidal_volume_m3 = vt;
  a.pause_time_s = 0.2;
  a.support_pa = 8 * kCmH2O;
  const auto r = simulate(just(single_linear(0.05, 10), a), tight(30.0));
  ASSERT_EQ(r.breaths.size(), 6u);
  for (std::size_t i = 0; i < r.breaths.size(); ++i) {
    const auto& b = r.breaths[i];
    EXPECT_STREQ(b.mode, "vc_simv");
    EXPECT_STREQ(b.breath_type, "mandatory");
    EXPECT_STREQ(b.trigger, "time");
    EXPECT_DOUBLE_EQ(b.start_s, 5.0 * static_cast<double>(i));
    const double x = vt * keep * (1 - std::pow(keep, static_cast<double>(i))) / (1 - keep);
    EXPECT_LT(relative_error(b.plateau_pressure_pa, peep + (x + vt) / C), 1e-9) << i;
  }
}

TEST(Ventilator, SimvSynchronisesTheMandatoryBreathWithinItsWindowAndSupportsTheRest) {
  // SIMV-VC at 10 /min (a mandatory breath due every 6 s from t = 0), trigger window 2 s before
  // each due time; the patient's effort (15 /min) starts at 2.5 s. From the rule:
  // - 0 s: the mode's first breath, the machine's;
  // - 2.5 s + delay: the first effort triggers outside the window [4, 6): a supported breath, at
  //   the instant the flow reaches 2 L/min; in closed form, the expiration of the first breath
  //   (VT e^(-(t - 1)/tau), from x = VT at the end of its 1 s square flow) plus the effort's
  //   response from rest;
  // - 6 s: no trigger in [4, 6) (the next effort starts at 6.5 s): the machine's;
  // - 10.5 s + delay, in [10, 12): the mandatory breath, synchronised;
  // - 14.5 s + delay, before [16, 18): supported; 18 s: the machine's; and so on every 12 s.
  const double C = 0.05 * kLPerCmH2O, R = 10 * kCmH2OsPerL, tau = R * C, peep = 5 * kCmH2O, vt = 0.5 * kLitre;
  const double A = 6 * kCmH2O, ti_effort = 4.0 / 3.0, w = std::numbers::pi / ti_effort, onset = 2.5;
  const double threshold = 2 * kLitre / 60;
  Assisted a = simv(AssistMode::simv_volume, 10.0 / 60, 2.0, peep);
  a.tidal_volume_m3 = vt;
  a.support_pa = 5 * kCmH2O;
  const Mechanics m = single_linear(0.05, 10);
  const Protocol p{{Setting{0.0, m, a}, Setting{onset, m, a, PatientEffort{0.25, 0.5, A}}}};
  const auto r = simulate(p, tight(36.0, 10.0));
  const auto effort_flow = [&](double t) {
    const double e = std::exp(-t / tau);
    return A * C / 2 * e / tau -
           A * C / 2 / (1 + w * w * tau * tau) * (-w * std::sin(w * t) + w * w * tau * std::cos(w * t) + e / tau);
  };
  const auto flow = [&](double t) { return -vt / tau * std::exp(-(t - 1.0) / tau) + effort_flow(t - onset); };
  const double first_trigger = bisect([&](double t) { return flow(t) - threshold; }, onset + 1e-6, onset + 1.0);
  struct Expected {
    const char* type;
    const char* trigger;
  };
  const Expected pattern[] = {{"spontaneous", "patient_flow"}, {"mandatory", "time"}, {"mandatory", "patient_flow"}};
  ASSERT_EQ(r.breaths.size(), 9u);  // the last, at 34.5 s + delay, ends after 36 s
  EXPECT_STREQ(r.breaths[0].breath_type, "mandatory");
  EXPECT_EQ(r.breaths[0].start_s, 0.0);
  EXPECT_NEAR(r.breaths[1].start_s, first_trigger, 1e-9);
  int mandatory = 0;
  for (std::size_t i = 1; i < r.breaths.size(); ++i) {
    const auto& b = r.breaths[i];
    const Expected& e = pattern[(i - 1) % 3];
    const std::size_t cycle = (i - 1) / 3;  // the pattern repeats every 12 s
    const double cycle_start = 12.0 * static_cast<double>(cycle);
    EXPECT_STREQ(b.breath_type, e.type) << i;
    EXPECT_STREQ(b.trigger, e.trigger) << i;
    if ((i - 1) % 3 == 0) {  // supported, flow cycled at 25 % of its peak flow
      EXPECT_NEAR(b.start_s - b.trigger_delay_s, cycle_start + onset, 1e-9) << i;
      EXPECT_STREQ(b.cycle, "flow") << i;
      EXPECT_EQ(b.set_tidal_volume_m3, 0.0) << i;
    } else if ((i - 1) % 3 == 1) {  // the machine's, on the clock
      EXPECT_DOUBLE_EQ(b.start_s, cycle_start + 6.0) << i;
      EXPECT_EQ(b.set_tidal_volume_m3, vt) << i;
    } else {  // synchronised within [10, 12) + 12 k
      EXPECT_NEAR(b.start_s - b.trigger_delay_s, cycle_start + 10.5, 1e-9) << i;
      EXPECT_GE(b.start_s, cycle_start + 10.0) << i;
      EXPECT_LT(b.start_s, cycle_start + 12.0) << i;
      EXPECT_LT(relative_error(b.inspired_volume_m3, vt), 1e-9) << i;
    }
    mandatory += std::string(b.breath_type) == "mandatory" ? 1 : 0;
  }
  // Exactly one mandatory breath per cycle: in the window [6 k - 2, 6 k] of each due time 6 k.
  for (int k = 1; 6.0 * k <= r.breaths.back().start_s; ++k) {
    int in_window = 0;
    for (const auto& b : r.breaths)
      in_window += std::string(b.breath_type) == "mandatory" && b.start_s >= 6.0 * k - 2.0 && b.start_s <= 6.0 * k;
    EXPECT_EQ(in_window, 1) << k;
  }
  // ... and none outside the windows.
  for (const auto& b : r.breaths) {
    if (std::string(b.breath_type) != "mandatory") continue;
    const double k = std::ceil(b.start_s / 6.0);
    EXPECT_GE(b.start_s, 6.0 * k - 2.0) << b.start_s;
  }
  EXPECT_EQ(mandatory, 5);  // 6, 10.5 + d, 18, 22.5 + d, 30 s
}

TEST(Ventilator, ExpiratoryHoldReadsTheClosedFormTotalPeepOfAShortExpiration) {
  // VC-CMV on an RC lung (tau = 1 s) with only 2 s to expire: from rest, each breath adds VT and
  // each expiration keeps r = e^(-Te/tau) of the volume, so after n breaths the lung holds
  // x_n = VT r (1 - r^n) / (1 - r) above the PEEP volume. An occluded single compartment holds
  // its alveolar pressure: the hold reads PEEP + x_n / C, and intrinsic PEEP x_n / C.
  const double C = 0.05 * kLPerCmH2O, tau = 1.0, peep = 5 * kCmH2O, vt = 0.5 * kLitre, te = 2.0, hold = 1.5;
  const double r = std::exp(-te / tau);
  const auto x = [&](int n) { return vt * r * (1 - std::pow(r, n)) / (1 - r); };
  for (bool assisted : {false, true}) {
    Driver d = VolumeControl{1.0 / 3, vt, 1.0, 0.0, peep};
    if (assisted) d = vc_ac(1.0 / 3, vt, 1.0, 0.0, peep);
    Protocol p = just(single_linear(0.05, 20), d);
    p.holds = {{8.2, hold}};  // during the third breath: held at its end, t = 9 s
    const auto res = simulate(p, tight(18.0));
    ASSERT_GE(res.breaths.size(), 5u) << assisted;
    const auto& b = res.breaths[2];
    EXPECT_DOUBLE_EQ(b.expiratory_hold_s, hold) << assisted;
    EXPECT_NEAR(b.duration_s, 3.0 + hold, 1e-12) << assisted;
    EXPECT_LT(relative_error(b.total_peep_pa, peep + x(3) / C), 1e-9) << assisted;
    EXPECT_LT(relative_error(b.intrinsic_peep_pa, x(3) / C), 1e-8) << assisted;
    // The breaths without a hold keep the instantaneous reading, the same closed form.
    EXPECT_TRUE(std::isnan(res.breaths[1].total_peep_pa));
    EXPECT_LT(relative_error(res.breaths[1].intrinsic_peep_pa, x(2) / C), 1e-8) << assisted;
    // No flow during the hold; the next breath is the machine's, right after it.
    for (std::size_t k = 0; k < res.series.size(); ++k) {
      if (res.series.time_s[k] > 9.0 && res.series.time_s[k] < 9.0 + hold) {
        EXPECT_EQ(res.series.flow_m3_per_s[k], 0.0) << res.series.time_s[k];
      }
    }
    EXPECT_NEAR(res.breaths[3].start_s, 9.0 + hold, 1e-12) << assisted;
    EXPECT_STREQ(res.breaths[3].trigger, "time");
    EXPECT_EQ(res.breaths[3].expiratory_hold_s, 0.0);
  }
}

TEST(Ventilator, ExpiratoryHoldLetsTwoCompartmentsShareTheirPressure) {
  // Two compartments behind a shared airway, occluded at end expiration: the total volume stays,
  // the pressures equalise through the branches (pendelluft). With Pi = Vi / Ci and
  // D = P1 - P2, D' = -D / tau_p, tau_p = (R1 + R2) C1 C2 / (C1 + C2), and the airway (branch
  // point) pressure is Peq + D (C2 R2 - C1 R1) / ((C1 + C2)(R1 + R2)), Peq = (V1 + V2) / (C1 + C2).
  const double C1 = 0.02 * kLPerCmH2O, C2 = 0.04 * kLPerCmH2O, R1 = 2 * kCmH2OsPerL, R2 = 30 * kCmH2OsPerL;
  Mechanics m;
  m.airway_resistance_pa_s_per_m3 = 5 * kCmH2OsPerL;
  m.compartments = {{"upper", LinearCompliance{C1}, R1}, {"lower", LinearCompliance{C2}, R2}};
  const double peep = 5 * kCmH2O, hold = 1.0;
  Protocol p = just(m, VolumeControl{0.4, 0.5 * kLitre, 0.8, 0.0, peep});
  p.holds = {{4.0, hold}};  // the end of the second breath, t = 5 s: an output sample
  const auto res = simulate(p, tight(10.0));
  ASSERT_GE(res.breaths.size(), 2u);
  const auto& s = res.series;
  std::size_t k0 = 0;
  while (s.time_s[k0] < 5.0 - 1e-9) ++k0;
  ASSERT_NEAR(s.time_s[k0], 5.0, 1e-12);
  const double v1 = s.compartment_volume_m3[0][k0], v2 = s.compartment_volume_m3[1][k0];
  const double peq = (v1 + v2) / (C1 + C2), d0 = v1 / C1 - v2 / C2;
  const double tau_p = (R1 + R2) * C1 * C2 / (C1 + C2);
  const double expected = peq + d0 * std::exp(-hold / tau_p) * (C2 * R2 - C1 * R1) / ((C1 + C2) * (R1 + R2));
  const auto& b = res.breaths[1];
  EXPECT_LT(relative_error(b.total_peep_pa, expected), 1e-8);
  EXPECT_GT(std::abs(d0), 0.1 * kCmH2O);  // the compartments did differ at the occlusion
  // The total volume does not change during the hold.
  for (std::size_t k = k0; s.time_s[k] <= 5.0 + hold; ++k) EXPECT_NEAR(s.volume_m3[k], v1 + v2, 1e-15);
}

TEST(Ventilator, SwitchingToSimvMidRunTakesOverTheExpiration) {
  // VC-AC at 12 /min, then at 7 s SIMV-VC at 10 /min: the breath in progress (started at 5 s)
  // counts as the first mandatory one, the next is due at 11 s; no effort, so it comes then.
  const Mechanics m = single_linear(0.05, 10);
  Assisted ac = vc_ac(0.2, 0.45e-3, 1.0, 0.0, 5 * kCmH2O);
  Assisted s = simv(AssistMode::simv_volume, 10.0 / 60, 2.0, 5 * kCmH2O);
  s.tidal_volume_m3 = 0.45e-3;
  const auto r = simulate(Protocol{{Setting{0.0, m, ac}, Setting{7.0, m, s}}}, tight(24.0, 10.0));
  ASSERT_EQ(r.breaths.size(), 4u);
  EXPECT_STREQ(r.breaths[1].mode, "vc_ac");
  EXPECT_DOUBLE_EQ(r.breaths[1].duration_s, 6.0);
  EXPECT_STREQ(r.breaths[2].mode, "vc_simv");
  EXPECT_DOUBLE_EQ(r.breaths[2].start_s, 11.0);
  EXPECT_DOUBLE_EQ(r.breaths[3].start_s, 17.0);
}

TEST(Ventilator, EffortReleasesOverItsShareOfTheExpiration) {
  // 15 /min, I:E 1:3 (Ti 1 s, Te 3 s), released over 20 % of Te: Pmus = A/2 (1 + cos(pi (t - Ti) /
  // 0.6 s)) from 1 s to 1.6 s, then 0 until the next onset at 4 s. The default (half of Te) relaxes
  // over 1.5 s.
  const double A = 10 * kCmH2O, ti = 1.0, release = 0.2 * 3.0;
  PatientEffort effort{15.0 / 60, 1.0 / 3, A};
  effort.release_share = 0.2;
  for (double t : {1.1, 1.3, 1.45, 1.59}) {
    const double expected = A / 2 * (1 + std::cos(std::numbers::pi * (t - ti) / release));
    EXPECT_NEAR(effort_pressure(effort, t), expected, 1e-9 * A) << t;
    EXPECT_NEAR(effort_pressure(effort, t + 4.0), expected, 1e-9 * A) << t;  // the next period
    EXPECT_NEAR(effort_pressure_rate(effort, t),
                -A / 2 * std::numbers::pi / release * std::sin(std::numbers::pi * (t - ti) / release), 1e-9 * A)
        << t;
  }
  EXPECT_EQ(effort_pressure(effort, 1.61), 0.0);
  EXPECT_EQ(effort_pressure(effort, 3.9), 0.0);
  EXPECT_NEAR(next_effort_boundary(effort, 1.2), ti + release, 1e-12);
  EXPECT_NEAR(next_effort_boundary(effort, 1.7), 4.0, 1e-12);
  const PatientEffort by_default{15.0 / 60, 1.0 / 3, A};
  EXPECT_NEAR(next_effort_boundary(by_default, 1.2), ti + 1.5, 1e-12);
  EXPECT_GT(effort_pressure(by_default, 1.61), 0.0);
  // A whole expiration is a release; none or more than that is refused.
  effort.release_share = 1.0;
  EXPECT_NO_THROW(validate(effort));
  EXPECT_NEAR(next_effort_boundary(effort, 1.2), 4.0, 1e-12);
  for (double bad : {0.0, -0.1, 1.01}) {
    effort.release_share = bad;
    EXPECT_THROW(validate(effort), pneuma::ValueError) << bad;
  }
}
