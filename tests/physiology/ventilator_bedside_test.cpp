// The ventilator at the bedside against closed forms of the linear one-compartment (RC) lung: the
// circuit (a leak orifice, tubing compliance), alarms and apnea backup, expiratory flow
// limitation (a Starling resistor), PRVC.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "physiology_fixture.h"

using namespace pneuma::physiology;
using namespace pneuma::test;

namespace {

double relative_error(double actual, double expected) { return std::abs(actual - expected) / std::abs(expected); }

Assisted pc_ac(double rate_hz, double dp_pa, double ti_s, double peep_pa) {
  return pressure_mode(AssistMode::pressure, rate_hz, dp_pa, ti_s, peep_pa);
}

Protocol with_circuit(const Mechanics& m, const Driver& d, const Circuit& c, const Alarms& alarms = {}) {
  Setting s{0.0, m, d};
  s.circuit = c;
  s.alarms = alarms;
  return Protocol{{s}};
}

}  // namespace

TEST(VentilatorCircuit, LeakOrificeLosesKSqrtPTimesTheTimeAtEachPressure) {
  // A square breath (PEEP + dP for Ti, PEEP for Te) on an RC lung through an orifice leak
  // Q = k sqrt(P) at the airway: the patient takes C dP (1 - e^(-Ti/tau)) and gives it back but
  // e^(-Te/tau) of it, the leak takes k sqrt(PEEP + dP) Ti then k sqrt(PEEP) Te. So
  // VTi = C dP (1 - e^(-Ti/tau)) + k sqrt(PEEP + dP) Ti and VTi - VTe = the leak + what stays.
  const double C = 0.05 * kLPerCmH2O, R = 10 * kCmH2OsPerL, tau = R * C;
  const double peep = 5 * kCmH2O, dp = 15 * kCmH2O, ti = 1.0, rate = 0.2, te = 1 / rate - ti;
  Circuit circuit;
  circuit.port.coefficient = leak_coefficient(LeakLaw::orifice, 20 * kLitre / 60, 10 * kCmH2O);  // 20 L/min at 10
  const double k = circuit.port.coefficient;
  // Pressure control on the clock: a leak at PEEP above the flow trigger would start breaths.
  const PressureControl square{rate, dp, ti, peep};
  const auto r = simulate(with_circuit(single_linear(0.05, 10), square, circuit), tight(10.0));
  ASSERT_EQ(r.breaths.size(), 2u);
  const auto& b = r.breaths[0];
  const double into_patient = C * dp * (1 - std::exp(-ti / tau));
  const double vti = into_patient + k * std::sqrt(peep + dp) * ti;
  const double loss = k * (std::sqrt(peep + dp) * ti + std::sqrt(peep) * te) + into_patient * std::exp(-te / tau);
  EXPECT_LT(relative_error(b.vti_m3, vti), 1e-8);
  EXPECT_LT(relative_error(b.vti_m3 - b.vte_m3, loss), 1e-8);
  EXPECT_LT(relative_error(b.inspired_volume_m3, into_patient), 1e-8);
  // A linear leak Q = k P at the same share.
  circuit.port = {LeakLaw::linear, 1e-7};
  const auto l = simulate(with_circuit(single_linear(0.05, 10), square, circuit), tight(10.0));
  const double linear_loss = 1e-7 * ((peep + dp) * ti + peep * te) + into_patient * std::exp(-te / tau);
  EXPECT_LT(relative_error(l.breaths[0].vti_m3 - l.breaths[0].vte_m3, linear_loss), 1e-8);
}

TEST(VentilatorCircuit, ALeakAboveTheFlowTriggerAutoTriggers) {
  // PC-AC, passive patient, orifice leak: during expiration the ventilator's flow is
  // k sqrt(PEEP) - (V / tau) e^(-s / tau), V = C dP (1 - e^(-Ti/tau)); it rises through the
  // trigger threshold at s = tau ln(V / (tau (k sqrt(PEEP) - threshold))): a breath nobody asked for.
  const double C = 0.05 * kLPerCmH2O, tau = 10 * kCmH2OsPerL * C;
  const double peep = 5 * kCmH2O, dp = 15 * kCmH2O, ti = 1.0, threshold = 2 * kLitre / 60;
  Circuit circuit;
  circuit.port.coefficient = leak_coefficient(LeakLaw::orifice, 20 * kLitre / 60, 10 * kCmH2O);
  const auto r = simulate(with_circuit(single_linear(0.05, 10), pc_ac(0.1, dp, ti, peep), circuit), tight(5.0));
  ASSERT_GE(r.breaths.size(), 1u);
  const double v = C * dp * (1 - std::exp(-ti / tau));
  const double s = tau * std::log(v / (tau * (circuit.port.coefficient * std::sqrt(peep) - threshold)));
  EXPECT_NEAR(r.breaths[0].duration_s, ti + s, 1e-9);
  ASSERT_GE(r.breaths.size(), 2u);
  EXPECT_STREQ(r.breaths[1].trigger, "patient_flow");
}

TEST(VentilatorCircuit, TubingComplianceKeepsPTimesCtOfTheSetVolume) {
  // Volume control with a pause: the set volume fills the lung and the tubing to the same
  // pressure, so the patient gets VT C / (C + Ct), the tubing keeps Ct (Pplat - PEEP) and the
  // plateau is PEEP + VT / (C + Ct).
  const double C = 0.05 * kLPerCmH2O, ct = 2e-3 * kLPerCmH2O, peep = 5 * kCmH2O, vt = 0.5 * kLitre;
  Circuit circuit;
  circuit.tubing_compliance_m3_per_pa = ct;
  circuit.tubing_resistance_pa_s_per_m3 = 1 * kCmH2OsPerL;
  const auto r = simulate(with_circuit(single_linear(0.05, 10), vc_ac(0.1, vt, 1.5, 0.7, peep), circuit), tight(20.0));
  ASSERT_EQ(r.breaths.size(), 2u);
  const auto& b = r.breaths[0];
  const double plateau = peep + vt / (C + ct);
  EXPECT_LT(relative_error(b.vti_m3, vt), 1e-9);
  EXPECT_LT(relative_error(b.plateau_pressure_pa, plateau), 1e-8);
  EXPECT_LT(relative_error(vt - b.inspired_volume_m3, ct * (plateau - peep)), 1e-7);
  // Without a leak all of it comes back.
  EXPECT_LT(relative_error(b.vte_m3, vt), 1e-6);
}

TEST(VentilatorCircuit, NoCircuitMeasuresThePatientsVolumes) {
  const auto r = simulate(just(single_linear(0.05, 10), vc_ac(0.2, 0.5e-3, 1.0, 0.0, 0.0)), tight(10.0));
  ASSERT_EQ(r.breaths.size(), 2u);
  EXPECT_DOUBLE_EQ(r.breaths[0].vti_m3, r.breaths[0].inspired_volume_m3);
}

TEST(VentilatorAlarms, LimitsRaiseTheirAlarmOnTheBreathThatCrossesThem) {
  // VC-AC: peak PEEP + R q + VT / C = 5 + 10 * 0.5 + 10 = 20 cmH2O; VTe = VT; MV = VT * 12 /min.
  const double peep = 5 * kCmH2O, vt = 0.5 * kLitre;
  Alarms alarms;
  alarms.high_pressure_pa = 19.9 * kCmH2O;
  alarms.low_tidal_volume_m3 = 0.501 * kLitre;
  alarms.low_minute_volume_m3_per_s = 6.1 * kLitre / 60;  // above 0.5 L * 12 /min
  const auto r =
      simulate(with_circuit(single_linear(0.05, 10), vc_ac(0.2, vt, 1.0, 0.0, peep), {}, alarms), tight(10.0));
  ASSERT_EQ(r.breaths.size(), 2u);
  EXPECT_EQ(r.breaths[0].alarms, "high_pressure;low_tidal_volume;low_minute_volume");
  alarms = {};
  alarms.high_pressure_pa = 20.1 * kCmH2O;
  alarms.low_pressure_pa = 20.05 * kCmH2O;
  alarms.low_minute_volume_m3_per_s = 5.9 * kLitre / 60;
  const auto quiet =
      simulate(with_circuit(single_linear(0.05, 10), vc_ac(0.2, vt, 1.0, 0.0, peep), {}, alarms), tight(10.0));
  EXPECT_EQ(quiet.breaths[0].alarms, "low_pressure");
}

TEST(VentilatorAlarms, ALeakOfAllTheVolumeIsADisconnection) {
  Circuit circuit;
  circuit.port.coefficient = leak_coefficient(LeakLaw::orifice, 200 * kLitre / 60, 10 * kCmH2O);
  Alarms alarms;
  alarms.disconnection_leak_fraction = 0.9;
  const auto r = simulate(
      with_circuit(single_linear(0.05, 10), pc_ac(0.2, 15 * kCmH2O, 1.0, 5 * kCmH2O), circuit, alarms), tight(10.0));
  ASSERT_EQ(r.breaths.size(), 2u);
  EXPECT_GE((r.breaths[0].vti_m3 - r.breaths[0].vte_m3) / r.breaths[0].vti_m3, 0.9);
  EXPECT_EQ(r.breaths[0].alarms, "disconnection");
}

TEST(VentilatorAlarms, ApneaOnCpapStartsBackupBreathsUntilThePatientTriggers) {
  // CPAP with an apnea time of 10 s on a patient who stops breathing: no breath, so the backup
  // (PC-AC at 12 /min) starts at the apnea time, its breaths on the clock every 5 s; when the
  // effort comes back (an action at 40 s) the patient's trigger returns the mode to CPAP/PSV.
  Assisted a;
  a.mode = AssistMode::pressure_support;
  a.rate_hz = 0.0;
  a.peep_pa = 5 * kCmH2O;
  a.inspiratory_pressure_pa = 8 * kCmH2O;
  a.inspiratory_time_s = 3.0;
  a.cycle = CycleKind::flow;
  a.trigger_threshold = 2 * kLitre / 60;
  a.apnea_time_s = 10.0;
  a.backup_rate_hz = 0.2;
  a.backup_pressure_pa = 12 * kCmH2O;
  a.backup_inspiratory_time_s = 1.0;
  const Mechanics m = single_linear(0.05, 10);
  Setting breathing{40.0, m, a, PatientEffort{0.25, 0.5, 8 * kCmH2O}};
  const auto r = simulate(Protocol{{Setting{0.0, m, a}, breathing}}, tight(60.0));
  ASSERT_GE(r.breaths.size(), 8u);
  for (int k = 0; k < 6; ++k) {  // 10, 15, ..., 35 s
    const auto& b = r.breaths[static_cast<std::size_t>(k)];
    EXPECT_STREQ(b.mode, "pc_ac");
    EXPECT_STREQ(b.trigger, "time");
    EXPECT_NEAR(b.start_s, 10.0 + 5.0 * k, 1e-12);
    EXPECT_EQ(b.alarms, k == 0 ? "apnea" : "");
    EXPECT_LT(relative_error(b.inspired_volume_m3, 0.05 * kLitre * 12 * (1 - std::exp(-1.0 / 0.5))), 1e-3);
  }
  // The first patient trigger after 40 s: a backup breath, then CPAP/PSV again.
  std::size_t k = 6;
  while (k < r.breaths.size() && std::string(r.breaths[k].trigger) == "time") ++k;
  ASSERT_LT(k + 1, r.breaths.size());
  EXPECT_STREQ(r.breaths[k + 1].mode, "cpap_psv");
  EXPECT_STREQ(r.breaths[k + 1].trigger, "patient_flow");
}

TEST(VentilatorFlowLimitation, StarlingResistorCapsExpirationWhateverThePeepBelowPcrit) {
  // Passive VC on an RC lung with a choke point at Pcrit > PEEP and Rs = R: the flow out is
  // (Pel - Pcrit) / Rs, so u = V - C Pcrit decays as e^(-t / (Rs C)) during each expiration and
  // the end-expiratory u follows u_n = r^n u_0 + VT r (1 - r^n) / (1 - r), r = e^(-Te / (Rs C)):
  // dynamic hyperinflation to VT r / (1 - r) above C Pcrit, whatever the PEEP below Pcrit.
  const double C = 0.05 * kLPerCmH2O, R = 10 * kCmH2OsPerL, pcrit = 8 * kCmH2O, vt = 0.5 * kLitre;
  const double ti = 1.0, rate = 0.25, te = 1 / rate - ti, r = std::exp(-te / (R * C));
  for (double peep_cmh2o : {0.0, 5.0}) {
    Mechanics m = single_linear(0.05, 10);
    m.critical_pressure_pa = pcrit;
    m.upstream_resistance_pa_s_per_m3 = R;
    const double peep = peep_cmh2o * kCmH2O;
    const auto res = simulate(just(m, VolumeControl{rate, vt, ti, 0.0, peep}), tight(40.0));
    ASSERT_EQ(res.breaths.size(), 10u);
    const double u0 = C * (peep - pcrit);
    for (std::size_t n = 1; n <= res.breaths.size(); ++n) {
      const double rn = std::pow(r, static_cast<double>(n));
      const double u = rn * u0 + vt * r * (1 - rn) / (1 - r);
      EXPECT_NEAR(res.breaths[n - 1].end_expiratory_volume_m3, C * pcrit + u, 1e-9 * vt) << peep_cmh2o << " " << n;
    }
  }
}

TEST(VentilatorFlowLimitation, ExpiratoryResistanceSetsTheExpiratoryTimeConstant) {
  // Inspiration through R, expiration through Re: end-expiratory volume above PEEP's after a full
  // pressure breath is C dP (1 - e^(-Ti/(R C))) e^(-Te/(Re C)).
  const double C = 0.05 * kLPerCmH2O, dp = 10 * kCmH2O, re = 30 * kCmH2OsPerL, ti = 1.0, rate = 0.2;
  Mechanics m = single_linear(0.05, 10);
  m.expiratory_airway_resistance_pa_s_per_m3 = re;
  const auto res = simulate(just(m, PressureControl{rate, dp, ti, 0.0}), tight(5.0));
  ASSERT_EQ(res.breaths.size(), 1u);
  const double expected = C * dp * (1 - std::exp(-ti / (10 * kCmH2OsPerL * C))) * std::exp(-(1 / rate - ti) / (re * C));
  EXPECT_LT(relative_error(res.breaths[0].end_expiratory_volume_m3, expected), 1e-8);
}

TEST(VentilatorPrvc, InspiratoryPressureStepsTowardTheTargetAndConverges) {
  // On an RC lung that empties between breaths, VTi = a dP with a = C (1 - e^(-Ti/tau)): the rule
  // dP += clamp(dP (VT / VTi - 1), +-step) = clamp(VT / a - dP, +-step) climbs by the step until
  // within it of dP* = VT / a, then lands on dP* exactly.
  const double C = 0.02 * kLPerCmH2O, tau = 10 * kCmH2OsPerL * C, ti = 1.0, vt = 0.3 * kLitre;
  const double a = C * (1 - std::exp(-ti / tau)), target = vt / a, step = 3 * kCmH2O;
  Assisted p = pc_ac(0.1, 5 * kCmH2O, ti, 5 * kCmH2O);
  p.mode = AssistMode::prvc;
  p.tidal_volume_m3 = vt;
  p.prvc_step_pa = step;
  const auto r = simulate(just(single_linear(0.02, 10), p), tight(100.0, 10.0));
  ASSERT_EQ(r.breaths.size(), 10u);
  double dp = 5 * kCmH2O;
  for (const auto& b : r.breaths) {
    EXPECT_STREQ(b.mode, "prvc");
    EXPECT_LT(relative_error(b.set_inspiratory_pressure_pa, dp), 1e-9);
    dp += std::clamp(target - dp, -step, step);
  }
  EXPECT_LT(relative_error(r.breaths.back().vti_m3, vt), 1e-9);
  EXPECT_NEAR(target / kCmH2O, 15.0 / (1 - std::exp(-5.0)), 1e-9);  // the oracle itself: 15.10 cmH2O
}
