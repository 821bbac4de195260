#include "pneuma/outputs/ventilator_facts.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <string>
#include <string_view>
#include <variant>

#include "pneuma/core/units.h"

namespace pneuma::outputs {
namespace {

using Facts = std::vector<std::pair<std::string, std::string>>;
using physiology::Assisted;
using physiology::AssistMode;

constexpr double kMl = units::ml_per_m3;
constexpr double kLitre = units::litres_per_m3;
constexpr double kCmH2O = units::cmh2o_per_pa;

std::string number(double v) { return fmt::format("{:.6g}", v); }

// The settings of one driver, as "ventilator.settings[i].<key>" facts.
void driver_facts(const std::string& prefix, const physiology::Driver& driver, Facts& out) {
  const auto add = [&](const char* key, const std::string& value) { out.emplace_back(prefix + key, value); };
  add("mode", physiology::mode_name(driver));
  if (const auto* v = std::get_if<physiology::VolumeControl>(&driver)) {
    add("rate_per_min", number(v->rate_hz * 60.0));
    add("tidal_volume_mL", number(v->tidal_volume_m3 * kMl));
    add("inspiratory_time_s", number(v->inspiratory_time_s));
    add("pause_s", number(v->pause_time_s));
    add("peep_cmH2O", number(v->peep_pa * kCmH2O));
    return;
  }
  if (const auto* p = std::get_if<physiology::PressureControl>(&driver)) {
    add("rate_per_min", number(p->rate_hz * 60.0));
    add("inspiratory_pressure_cmH2O", number(p->inspiratory_pressure_pa * kCmH2O));
    add("inspiratory_time_s", number(p->inspiratory_time_s));
    add("peep_cmH2O", number(p->peep_pa * kCmH2O));
    return;
  }
  const auto* a = std::get_if<Assisted>(&driver);
  if (!a) return;
  const bool support = a->mode == AssistMode::pressure_support, simv = physiology::is_simv(*a);
  const bool volume = a->mode == AssistMode::volume || a->mode == AssistMode::simv_volume;
  const bool no_backup = support || a->mode == AssistMode::pav;  // every breath is the patient's
  if (!no_backup) add("rate_per_min", number(a->rate_hz * 60.0));
  add(no_backup ? "longest_inspiratory_time_s" : "inspiratory_time_s", number(a->inspiratory_time_s));
  add("peep_cmH2O", number(a->peep_pa * kCmH2O));
  add("trigger", a->trigger == physiology::TriggerKind::flow
                     ? fmt::format("flow {:.6g} L/min", a->trigger_threshold * kLitre * 60.0)
                     : fmt::format("pressure {:.6g} cmH2O", a->trigger_threshold * kCmH2O));
  if (volume) {
    add("tidal_volume_mL", number(a->tidal_volume_m3 * kMl));
    add("pause_s", number(a->pause_time_s));
    add("waveform", a->waveform == physiology::FlowWaveform::square ? "square" : "decelerating");
    if (a->pressure_limit_pa > 0.0) add("pressure_limit_cmH2O", number(a->pressure_limit_pa * kCmH2O));
  }
  if (a->mode == AssistMode::aprv) {
    add("high_pressure_cmH2O", number((a->peep_pa + a->inspiratory_pressure_pa) * kCmH2O));
    add("low_pressure_cmH2O", number(a->peep_pa * kCmH2O));
    add("high_time_s", number(a->inspiratory_time_s));
    add("low_time_s", number(1.0 / a->rate_hz - a->inspiratory_time_s));
    if (a->support_pa > 0.0) add("pressure_support_cmH2O", number(a->support_pa * kCmH2O));  // BiLevel
  }
  if (a->mode == AssistMode::pav) {
    add("gain_percent", number(a->pav_gain * 100.0));
    add("assisted_resistance_cmH2O_s_per_L", number(a->pav_resistance_pa_s_per_m3 * kCmH2O / kLitre));
    add("assisted_compliance_mL_per_cmH2O", number(kMl / (a->pav_elastance_pa_per_m3 * kCmH2O)));
  }
  if (a->mode == AssistMode::pressure || a->mode == AssistMode::simv_pressure)
    add("inspiratory_pressure_cmH2O", number(a->inspiratory_pressure_pa * kCmH2O));
  if (support) add("pressure_support_cmH2O", number(a->inspiratory_pressure_pa * kCmH2O));
  if (simv) {
    add("pressure_support_cmH2O", number(a->support_pa * kCmH2O));
    add("trigger_window_s", number(a->trigger_window_s));
  }
  if (a->mode != AssistMode::volume) {
    add("rise_time_s", number(a->rise_time_s));
    switch (a->cycle) {
      case physiology::CycleKind::time: add("cycle", "time"); break;
      case physiology::CycleKind::flow:
        add("cycle", a->cycle_flow_m3_per_s > 0.0
                         ? fmt::format("flow {:.6g} L/min", a->cycle_flow_m3_per_s * kLitre * 60.0)
                         : fmt::format("flow {:.6g} %", a->cycle_fraction * 100.0));
        break;
      case physiology::CycleKind::volume:
        add("cycle", fmt::format("volume {:.6g} mL", a->cycle_volume_m3 * kMl));
        break;
    }
    if (a->volume_limit_m3 > 0.0) add("volume_limit_mL", number(a->volume_limit_m3 * kMl));
  }
}

// Mean, min and max of `value` over the breaths it is defined for (finite), as three facts.
void summary(const std::string& name, const std::vector<const physiology::BreathMetrics*>& breaths,
             const std::function<double(const physiology::BreathMetrics&)>& value, Facts& out) {
  double sum = 0.0, low = std::numeric_limits<double>::infinity(), high = -std::numeric_limits<double>::infinity();
  std::size_t n = 0;
  for (const auto* b : breaths) {  // in breath order: the same sum, bit for bit, at any thread count
    const double v = value(*b);
    if (!std::isfinite(v)) continue;
    sum += v;
    low = std::min(low, v);
    high = std::max(high, v);
    ++n;
  }
  if (n == 0) return;
  out.emplace_back("ventilator." + name + ".mean", number(sum / static_cast<double>(n)));
  out.emplace_back("ventilator." + name + ".min", number(low));
  out.emplace_back("ventilator." + name + ".max", number(high));
}

// Whether a breath's ';'-separated alarms name `alarm`.
bool raises(const std::string& alarms, std::string_view alarm) {
  for (std::size_t from = 0; from <= alarms.size();) {
    const std::size_t end = std::min(alarms.find(';', from), alarms.size());
    if (std::string_view(alarms).substr(from, end - from) == alarm) return true;
    from = end + 1;
  }
  return false;
}

}  // namespace

Facts ventilator_facts(const physiology::Protocol& protocol, const physiology::SimulationResult& result) {
  Facts out;
  const auto& settings = protocol.settings;
  if (std::none_of(settings.begin(), settings.end(), [](const auto& s) { return physiology::is_ventilator(s.driver); }))
    return out;
  std::size_t index = 0;
  for (std::size_t i = 0; i < settings.size(); ++i) {
    const auto& s = settings[i];
    if (i > 0 && s.driver == settings[i - 1].driver && s.effort == settings[i - 1].effort) continue;
    const std::string prefix = fmt::format("ventilator.settings[{}].", index++);
    out.emplace_back(prefix + "at_s", number(s.start_time_s));
    driver_facts(prefix, s.driver, out);
    if (s.effort.active()) {
      std::string effort = fmt::format("{:.6g} /min, I:E {:.6g}, {:.6g} cmH2O", s.effort.rate_hz * 60.0,
                                       s.effort.ie_ratio, s.effort.amplitude_pa * kCmH2O);
      // The release only where set, so the manifests of the default effort read as before.
      if (s.effort.release_share != physiology::PatientEffort{}.release_share)
        effort += fmt::format(", release {:.6g} %", 100.0 * s.effort.release_share);
      out.emplace_back(prefix + "effort", effort);
    }
  }
  if (!protocol.holds.empty()) {
    std::string holds;
    for (const auto& h : protocol.holds)
      holds += fmt::format("{}at {:.6g} s for {:.6g} s", holds.empty() ? "" : "; ", h.at_s, h.duration_s);
    out.emplace_back("ventilator.expiratory_holds", holds);
  }

  std::vector<const physiology::BreathMetrics*> ventilated;
  for (const auto& b : result.breaths)
    if (*b.trigger != '\0') ventilated.push_back(&b);
  const auto count = [&](const std::function<bool(const physiology::BreathMetrics&)>& which) {
    return std::to_string(std::count_if(ventilated.begin(), ventilated.end(), [&](auto* b) { return which(*b); }));
  };
  const auto is = [](const char* a, const char* b) { return std::strcmp(a, b) == 0; };
  out.emplace_back("ventilator.breaths", std::to_string(ventilated.size()));
  out.emplace_back("ventilator.breaths.mandatory",
                   count([&](const auto& b) { return is(b.breath_type, "mandatory"); }));
  out.emplace_back("ventilator.breaths.spontaneous",
                   count([&](const auto& b) { return is(b.breath_type, "spontaneous"); }));
  for (const char* trigger : {"time", "patient_flow", "patient_pressure"})
    out.emplace_back(std::string("ventilator.triggers.") + trigger,
                     count([&](const auto& b) { return is(b.trigger, trigger); }));
  int missed = 0;
  for (const auto* b : ventilated) missed += b->missed_triggers;
  out.emplace_back("ventilator.missed_triggers", std::to_string(missed));
  out.emplace_back("ventilator.double_triggers", count([](const auto& b) { return b.double_triggered; }));
  out.emplace_back("ventilator.early_cycling", count([](const auto& b) { return b.early_cycling; }));
  out.emplace_back("ventilator.late_cycling", count([](const auto& b) { return b.late_cycling; }));
  out.emplace_back("ventilator.flow_starvation", count([](const auto& b) { return b.flow_starvation; }));
  summary(
      "peak_pressure_cmH2O", ventilated, [](const auto& b) { return b.peak_pressure_pa * kCmH2O; }, out);
  summary(
      "plateau_pressure_cmH2O", ventilated, [](const auto& b) { return b.plateau_pressure_pa * kCmH2O; }, out);
  summary(
      "mean_airway_pressure_cmH2O", ventilated, [](const auto& b) { return b.mean_airway_pressure_pa * kCmH2O; }, out);
  summary(
      "intrinsic_peep_cmH2O", ventilated, [](const auto& b) { return b.intrinsic_peep_pa * kCmH2O; }, out);
  summary(
      "delivered_tidal_volume_mL", ventilated, [](const auto& b) { return b.inspired_volume_m3 * kMl; }, out);
  summary(
      "inspiratory_time_s", ventilated, [](const auto& b) { return b.inspiratory_time_s; }, out);
  summary(
      "trigger_delay_s", ventilated, [](const auto& b) { return b.trigger_delay_s; }, out);
  summary(
      "total_peep_cmH2O", ventilated,
      [](const auto& b) { return b.expiratory_hold_s > 0.0 ? b.total_peep_pa * kCmH2O : NAN; }, out);
  // Each alarm raised: how many breaths raised it and when first (breath start), absent when none.
  for (const char* alarm :
       {"high_pressure", "low_pressure", "low_tidal_volume", "low_minute_volume", "apnea", "disconnection"}) {
    std::size_t raised = 0;
    double first = 0.0;
    for (const auto* b : ventilated) {
      if (!raises(b->alarms, alarm)) continue;
      if (raised++ == 0) first = b->start_s;
    }
    if (raised > 0)
      out.emplace_back(std::string("ventilator.alarms.") + alarm,
                       fmt::format("{} breaths, the first at {:.6g} s", raised, first));
  }
  return out;
}

}  // namespace pneuma::outputs
