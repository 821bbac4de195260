// APRV and PAV against closed forms of the linear one-compartment (RC) lung, and the breath flags
// of cycling and flow asynchrony on constructed cases where each must and must not fire.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "physiology_fixture.h"

using namespace pneuma::physiology;
using namespace pneuma::test;

namespace {

// APRV: P_high above P_low for T_high, then P_low for T_low.
Assisted aprv(double p_high, double p_low, double t_high, double t_low) {
  Assisted a;
  a.mode = AssistMode::aprv;
  a.rate_hz = 1.0 / (t_high + t_low);
  a.inspiratory_time_s = t_high;
  a.inspiratory_pressure_pa = p_high - p_low;
  a.peep_pa = p_low;
  a.trigger_threshold = 2 * kLitre / 60;
  return a;
}

Assisted pav(double gain, double r_set, double c_set, double peep) {
  Assisted a;
  a.mode = AssistMode::pav;
  a.rate_hz = 0.0;
  a.inspiratory_time_s = 3.0;
  a.peep_pa = peep;
  a.cycle = CycleKind::flow;
  a.trigger_threshold = 2 * kLitre / 60;
  a.pav_gain = gain;
  a.pav_resistance_pa_s_per_m3 = r_set;
  a.pav_elastance_pa_per_m3 = 1.0 / c_set;
  return a;
}

// The response of tau y' + y = cos(w t) that stays bounded: (cos w t + w tau sin w t) / (1 + (w tau)^2).
struct CosineResponse {
  double w, tau;
  double at(double t) const { return (std::cos(w * t) + w * tau * std::sin(w * t)) / (1 + w * w * tau * tau); }
  double rate(double t) const {
    return (-w * std::sin(w * t) + w * w * tau * std::cos(w * t)) / (1 + w * w * tau * tau);
  }
};

}  // namespace

TEST(VentilatorAprv, PassiveLungFollowsTheRcExponentialToEachLevel) {
  // No effort: at each level the volume above the relaxed volume relaxes to C P with the time
  // constant tau: x_high = C Ph + (x - C Ph) e^(-Th/tau), x_low = C Pl + (x_high - C Pl) e^(-Tl/tau),
  // from x = C Pl (the run starts at rest at P_low). Mean airway pressure (Ph Th + Pl Tl) / (Th + Tl).
  const double C = 0.05 * kLPerCmH2O, tau = 10 * kCmH2OsPerL * C;
  const double ph = 25 * kCmH2O, pl = 5 * kCmH2O, th = 2.0, tl = 0.4;
  const auto r = simulate(just(single_linear(0.05, 10), aprv(ph, pl, th, tl)), tight(12.5));
  ASSERT_EQ(r.breaths.size(), 5u);
  double x = C * pl;
  for (std::size_t k = 0; k < r.breaths.size(); ++k) {
    const auto& b = r.breaths[k];
    const double high = C * ph + (x - C * ph) * std::exp(-th / tau);
    const double low = C * pl + (high - C * pl) * std::exp(-tl / tau);
    EXPECT_STREQ(b.mode, "aprv");
    EXPECT_STREQ(b.trigger, "time");
    EXPECT_NEAR(b.start_s, static_cast<double>(k) * (th + tl), 1e-12);
    EXPECT_NEAR(b.inspiratory_time_s, th, 1e-12);
    EXPECT_NEAR(b.inspired_volume_m3, high - x, 1e-9 * C * ph) << k;
    EXPECT_NEAR(b.end_expiratory_volume_m3, low, 1e-9 * C * ph) << k;
    EXPECT_NEAR(b.mean_airway_pressure_pa, (ph * th + pl * tl) / (th + tl), 1e-9 * ph) << k;
    // The release is short against tau: the lung keeps an intrinsic PEEP of (low - C Pl) / C.
    EXPECT_NEAR(b.intrinsic_peep_pa, (low - C * pl) / C, 1e-7 * ph) << k;
    x = low;
  }
}

TEST(VentilatorAprv, SpontaneousBreathsAtEitherLevelAddToThePassiveVolumes) {
  // The levels are held whatever the patient does (the demand valve), so the linear lung's volume
  // is the passive APRV volume plus the effort's own response at a constant airway pressure:
  // V_aprv+effort - V_aprv = V_cpap+effort - V_cpap at every instant; nothing triggers.
  const Mechanics m = single_linear(0.05, 10);
  const double pl = 5 * kCmH2O;
  const PatientEffort effort{0.3, 0.5, 6 * kCmH2O};  // 18 /min, faster than the releases (12.5 /min)
  const Assisted levels = aprv(20 * kCmH2O, pl, 4.0, 0.8);
  const PressureControl cpap{0.2, 0.0, 1.0, pl};  // PEEP only: the effort's reference at one level
  Setting with{0.0, m, levels, effort}, cpap_with{0.0, m, cpap, effort};
  const auto a = simulate(Protocol{{with}}, tight(20.0));
  const auto p = simulate(just(m, levels), tight(20.0));
  const auto c = simulate(Protocol{{cpap_with}}, tight(20.0));
  ASSERT_EQ(a.series.size(), p.series.size());
  ASSERT_EQ(a.series.size(), c.series.size());
  const double rest = 0.05 * kLitre * 5;  // C PEEP
  double largest = 0.0;
  for (std::size_t k = 0; k < a.series.size(); ++k) {
    const double own = c.series.volume_m3[k] - rest;
    largest = std::max(largest, std::abs(own));
    EXPECT_NEAR(a.series.volume_m3[k] - p.series.volume_m3[k], own, 1e-9 * kLitre) << a.series.time_s[k];
    EXPECT_DOUBLE_EQ(a.series.airway_pressure_pa[k], p.series.airway_pressure_pa[k]) << a.series.time_s[k];
  }
  EXPECT_GT(largest, 0.1 * kLitre);  // the effort moved real volume
  for (const auto& b : a.breaths) {
    EXPECT_STREQ(b.trigger, "time");
    EXPECT_EQ(b.missed_triggers, 0);
  }
}

TEST(VentilatorPav, AssistedInspirationIsTheLungWithRAndEScaledByOneMinusGain) {
  // An RC lung at PEEP, a half-cosine effort Pmus = A/2 (1 - cos(w t)), w = pi / Ti. Before the
  // trigger: R Q + E u = Pmus (u above the PEEP volume). From the trigger t0 (u = us), PAV adds
  // Paw - PEEP = g (R Q + E (u - us)), so R Q + E u = (Pmus - g E us) / (1 - g): the same time
  // constant, a forcing 1 / (1 - g) larger. u = K + B y(t) + (us - K - B y(t0)) e^(-(t - t0)/tau),
  // K = (A/2 - g E us) / ((1 - g) E), B = -A / (2 (1 - g) E), y the cosine response.
  const double C = 0.05 * kLPerCmH2O, R = 10 * kCmH2OsPerL, E = 1 / C, tau = R * C;
  const double peep = 5 * kCmH2O, amplitude = 6 * kCmH2O, g = 0.6, threshold = 2 * kLitre / 60;
  const PatientEffort effort{0.2, 0.5, amplitude};  // 12 /min, Ti = 5/3 s
  const double ti = 5.0 / 3.0, w = std::numbers::pi / ti;
  const CosineResponse y{w, tau};
  const double h = amplitude / (2 * E), y0 = 1 / (1 + w * w * tau * tau);
  const auto before = [&](double t) { return h * (1 - std::exp(-t / tau) - (y.at(t) - y0 * std::exp(-t / tau))); };
  const auto flow_before = [&](double t) {
    return h * (std::exp(-t / tau) / tau - (y.rate(t) + y0 * std::exp(-t / tau) / tau));
  };
  double lo = 0.0, hi = ti / 2;  // the flow rises through the threshold once in the first half
  for (int i = 0; i < 200; ++i) (flow_before(0.5 * (lo + hi)) < threshold ? lo : hi) = 0.5 * (lo + hi);
  const double t0 = 0.5 * (lo + hi), us = before(t0);
  const double K = (amplitude / 2 - g * E * us) / ((1 - g) * E), B = -amplitude / (2 * (1 - g) * E);
  const double D = us - K - B * y.at(t0);
  const auto after = [&](double t) { return K + B * y.at(t) + D * std::exp(-(t - t0) / tau); };
  const auto flow_after = [&](double t) { return B * y.rate(t) - D / tau * std::exp(-(t - t0) / tau); };

  Setting s{0.0, single_linear(0.05, 10), pav(g, R, C, peep), effort};
  const auto r = simulate(Protocol{{s}}, tight(6.0, 1000.0));
  ASSERT_GE(r.breaths.size(), 1u);
  EXPECT_NEAR(r.breaths[0].start_s, t0, 1e-9);
  EXPECT_STREQ(r.breaths[0].mode, "pav");
  EXPECT_STREQ(r.breaths[0].breath_type, "spontaneous");
  const double cycle = t0 + r.breaths[0].inspiratory_time_s;
  ASSERT_GT(cycle, ti);  // the flow cycle comes after the neural inspiration: compare up to Ti
  int checked = 0;
  const double rest = C * peep;
  for (std::size_t k = 0; k < r.series.size(); ++k) {
    const double t = r.series.time_s[k];
    if (t <= t0 || t >= ti) continue;
    const double u = after(t), q = flow_after(t);
    EXPECT_NEAR(r.series.volume_m3[k] - rest, u, 1e-9 * kLitre) << t;
    EXPECT_NEAR(r.series.airway_pressure_pa[k], peep + g * (R * q + E * (u - us)), 1e-6 * kCmH2O) << t;
    ++checked;
  }
  EXPECT_GT(checked, 1000);
  // The assisted volume at Ti is larger than the unassisted (g = 0) one: about 1 / (1 - g) of it.
  EXPECT_GT(after(ti), 2.0 * before(ti));
}

TEST(VentilatorFlags, CyclingIsEarlyOrLateAgainstTheNeuralInspirationOnlyBeyondItsBounds) {
  // Volume control on the clock and an effort at the same rate from t = 0: every breath starts at
  // an effort's onset, so the cycle delay is Ti - neural Ti exactly (neural Ti = 5 s / 3 at 1:2).
  // Early: Ti 1.0 s (-0.667 s); neither: 1.8 s (+0.133 s, under 20 % of 1.667 s); late: 2.2 s.
  const Mechanics m = single_linear(0.05, 10);
  const PatientEffort effort{0.2, 0.5, 3 * kCmH2O};
  const double neural = 5.0 / 3.0;
  struct Case {
    double ti;
    bool early, late;
  };
  for (const Case c : {Case{1.0, true, false}, Case{1.8, false, false}, Case{2.2, false, true}}) {
    Setting s{0.0, m, VolumeControl{0.2, 0.5 * kLitre, c.ti, 0.0, 5 * kCmH2O}, effort};
    const auto r = simulate(Protocol{{s}}, tight(15.0, 0.0));
    ASSERT_EQ(r.breaths.size(), 3u);
    for (const auto& b : r.breaths) {
      EXPECT_NEAR(b.cycle_delay_s, c.ti - neural, 1e-12) << c.ti;
      EXPECT_EQ(b.early_cycling, c.early) << c.ti;
      EXPECT_EQ(b.late_cycling, c.late) << c.ti;
    }
  }
  // An effort whose neural inspiration falls in the machine's expiration (onsets at 2.5 s + 5 k,
  // ending 4.17 s + 5 k) overlaps no inspiration: no delay, no flag.
  Setting first{0.0, m, VolumeControl{0.2, 0.5 * kLitre, 1.0, 0.0, 5 * kCmH2O}};
  Setting later = first;
  later.start_time_s = 2.5;
  later.effort = effort;
  const auto r = simulate(Protocol{{first, later}}, tight(15.0, 0.0));
  ASSERT_EQ(r.breaths.size(), 3u);
  for (const auto& b : r.breaths) {
    EXPECT_TRUE(std::isnan(b.cycle_delay_s));
    EXPECT_FALSE(b.early_cycling || b.late_cycling);
  }
}

TEST(VentilatorFlags, FlowStarvationIsTheEffortsPullAgainstTheSetFlow) {
  // Volume control sets the flow, so the passive lung's airway pressure at the same state is
  // Paw + Pmus: the dip is the muscle pressure, largest at the end of the flow (the effort still
  // rising): A/2 (1 - cos(pi Ti / neural Ti)). A = 6 cmH2O: 3.93 cmH2O, above 2: starved;
  // A = 1.5 cmH2O: 0.98, not; a passive patient: nothing to measure. Pressure control: the
  // flow follows the patient, never starved.
  const Mechanics m = single_linear(0.05, 10);
  const double neural = 5.0 / 3.0, ti = 1.0;
  for (double a_cmh2o : {6.0, 1.5}) {
    const double a = a_cmh2o * kCmH2O;
    Setting s{0.0, m, VolumeControl{0.2, 0.5 * kLitre, ti, 0.0, 5 * kCmH2O}, PatientEffort{0.2, 0.5, a}};
    const auto r = simulate(Protocol{{s}}, tight(15.0, 0.0));
    ASSERT_EQ(r.breaths.size(), 3u);
    const double dip = a / 2 * (1 - std::cos(std::numbers::pi * ti / neural));
    for (const auto& b : r.breaths) {
      EXPECT_NEAR(b.flow_starvation_pa, dip, 1e-9 * kCmH2O) << a_cmh2o;
      EXPECT_EQ(b.flow_starvation, dip > 2 * kCmH2O) << a_cmh2o;
    }
  }
  // The same through VC-AC (patient triggered): the dip is the largest Pmus over the flow phase.
  Setting assisted{0.0, m, vc_ac(0.1, 0.5 * kLitre, ti, 0.0, 5 * kCmH2O), PatientEffort{0.2, 0.5, 6 * kCmH2O}};
  const auto v = simulate(Protocol{{assisted}}, tight(15.0, 0.0));
  ASSERT_GE(v.breaths.size(), 2u);
  const auto& b = v.breaths[1];  // the first patient-triggered one
  ASSERT_STREQ(b.trigger, "patient_flow");
  const double end_of_flow = b.trigger_delay_s + ti;  // since the effort's onset
  EXPECT_NEAR(b.flow_starvation_pa, 3 * kCmH2O * (1 - std::cos(std::numbers::pi * end_of_flow / neural)),
              1e-9 * kCmH2O);
  EXPECT_TRUE(b.flow_starvation);
  const auto passive = simulate(just(m, VolumeControl{0.2, 0.5 * kLitre, ti, 0.0, 5 * kCmH2O}), tight(10.0, 0.0));
  EXPECT_TRUE(std::isnan(passive.breaths[0].flow_starvation_pa));
  EXPECT_FALSE(passive.breaths[0].flow_starvation);
  Setting pc{0.0, m, PressureControl{0.2, 10 * kCmH2O, ti, 5 * kCmH2O}, PatientEffort{0.2, 0.5, 6 * kCmH2O}};
  const auto p = simulate(Protocol{{pc}}, tight(10.0, 0.0));
  EXPECT_TRUE(std::isnan(p.breaths[0].flow_starvation_pa));
}

TEST(VentilatorFlowCycle, AnAbsoluteCycleFlowEndsAStepBreathWhereTheFlowFallsToIt) {
  // A pressure step dP on a passive RC lung: Q = (dP / R) e^(-t/tau), so a cycle at the flow F
  // (cycle: {flow: 5 L/min}, as Pulse's emulation of the bench) comes at tau ln(dP / (R F)).
  const double R = 10 * kCmH2OsPerL, tau = R * 0.05 * kLPerCmH2O, dp = 10 * kCmH2O, flow = 5 * kLitre / 60;
  Assisted a = pav(0.5, R, 1.0, 0.0);  // any assisted pressure breath; made a PC-AC one below
  a.mode = AssistMode::pressure;
  a.rate_hz = 0.2;
  a.inspiratory_pressure_pa = dp;
  a.inspiratory_time_s = 3.0;
  a.cycle_fraction = 0.0;
  a.cycle_flow_m3_per_s = flow;
  const auto r = simulate(just(single_linear(0.05, 10), a), tight(6.0, 0.0));
  ASSERT_GE(r.breaths.size(), 1u);
  EXPECT_STREQ(r.breaths[0].cycle, "flow");
  EXPECT_NEAR(r.breaths[0].inspiratory_time_s, tau * std::log(dp / (R * flow)), 1e-9);
}

TEST(VentilatorAprv, BiLevelSupportsTheTriggersAtPLowAndKeepsTheClock) {
  // BiLevel (APRV with pressure support): 20/5 cmH2O, 2 s / 8 s, support 8 cmH2O, on an RC lung
  // (tau 0.5 s). An effort from 7 s (every 10 s, Ti 2 s) starts in the low phase: the flow is the
  // release's decay, -(dV / tau) e^(-(t - 2)/tau) with dV = C (Ph - Pl)(1 - e^(-2/tau)), plus the
  // effort's own response from its onset; the trigger is where their sum reaches 2 L/min. That
  // breath is supported (8 cmH2O above P_low); the next high phase still comes at 10 s.
  const double C = 0.05 * kLPerCmH2O, E = 1 / C, tau = 10 * kCmH2OsPerL * C, threshold = 2 * kLitre / 60;
  const double ph = 20 * kCmH2O, pl = 5 * kCmH2O, amplitude = 5 * kCmH2O, ti = 2.0;
  Assisted bilevel = aprv(ph, pl, 2.0, 8.0);
  bilevel.support_pa = 8 * kCmH2O;
  bilevel.cycle = CycleKind::flow;
  const Mechanics m = single_linear(0.05, 10);
  Setting breathing{7.0, m, bilevel, PatientEffort{0.1, 0.25, amplitude}};
  const auto r = simulate(Protocol{{Setting{0.0, m, bilevel}, breathing}}, tight(12.0, 0.0));
  ASSERT_GE(r.breaths.size(), 2u);

  const CosineResponse y{std::numbers::pi / ti, tau};
  const double h = amplitude / (2 * E), y0 = 1 / (1 + y.w * y.w * tau * tau);
  const double dv = C * (ph - pl) * (1 - std::exp(-2.0 / tau));
  const auto flow = [&](double t) {
    const double s = t - 7.0;
    return h * (std::exp(-s / tau) / tau - (y.rate(s) + y0 * std::exp(-s / tau) / tau)) -
           dv / tau * std::exp(-(t - 2.0) / tau);
  };
  double lo = 7.0, hi = 7.0 + ti / 2;
  for (int i = 0; i < 200; ++i) (flow(0.5 * (lo + hi)) < threshold ? lo : hi) = 0.5 * (lo + hi);
  const auto& high = r.breaths[0];
  const auto& supported = r.breaths[1];
  EXPECT_STREQ(high.breath_type, "mandatory");
  EXPECT_NEAR(high.inspiratory_time_s, 2.0, 1e-12);
  EXPECT_STREQ(supported.mode, "aprv");
  EXPECT_STREQ(supported.breath_type, "spontaneous");
  EXPECT_STREQ(supported.trigger, "patient_flow");
  EXPECT_NEAR(supported.start_s, 0.5 * (lo + hi), 1e-9);
  EXPECT_NEAR(supported.set_inspiratory_pressure_pa, 8 * kCmH2O, 1e-9);
  EXPECT_NEAR(supported.start_s + supported.duration_s, 10.0, 1e-12);  // the clock's next high phase
  EXPECT_FALSE(std::isnan(supported.cycle_delay_s));                   // a supported breath is judged
}
