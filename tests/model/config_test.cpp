// The YAML layer: units, locations, key paths, unknown keys, presets.
#include "pneuma/scenario/config.h"

#include <gtest/gtest.h>

#include "pneuma/core/error.h"
#include "pneuma/outputs/ventilator_facts.h"
#include "pneuma/scenario/physiology_config.h"
#include "test_support.h"

using pneuma::scenario::Node;
namespace kind = pneuma::units::kind;

namespace {

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const pneuma::InputError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(Config, QuantityWithoutUnitNamesFileLineColumnAndKeyPath) {
  const Node root = Node::load_string("physiology:\n  model: single\n  compliance: 0.1\n", "scenarios/x.yaml");
  EXPECT_EQ(error_of([&] { root.map("physiology").quantity("compliance", kind::compliance); }),
            "scenarios/x.yaml:3:15: physiology.compliance: expected a compliance such as '0.1 L/cmH2O', got '0.1'");
}

TEST(Config, UnknownKeyIsRefusedWithTheKeysThatExist) {
  const Node root = Node::load_string("duration: 10 s\nduraton: 5 s\n", "s.yaml");
  EXPECT_DOUBLE_EQ(root.quantity("duration", kind::duration), 10.0);
  EXPECT_EQ(error_of([&] { root.finish(); }), "s.yaml:2:1: duraton: unknown key; expected one of: duration");
}

TEST(Config, NotYamlAndNotAMappingAreOneLineErrors) {
  EXPECT_EQ(error_of([] { Node::load_string("a: [1, 2\n", "bad.yaml"); }),
            "bad.yaml:2:1: not valid YAML: end of sequence flow not found");
  EXPECT_EQ(error_of([] { Node::load_string("- 1\n- 2\n", "list.yaml"); }),
            "list.yaml:1:1: expected a YAML mapping of keys at the top level");
}

TEST(Config, MissingKeyAndWrongChoice) {
  const Node root = Node::load_string("driver:\n  mode: jogging\n", "d.yaml");
  EXPECT_EQ(error_of([&] { root.map("driver").quantity("rate", kind::rate); }),
            "d.yaml:2:3: driver: missing key 'rate' (expected rate such as '12 /min')");
  EXPECT_EQ(error_of([&] {
              root.map("driver").choice("mode", {"spontaneous", "volume_control"});
            }),
            "d.yaml:2:9: driver.mode: expected one of: spontaneous, volume_control; got 'jogging'");
}

TEST(Config, FallbackLayersResolveAndReportTheFileOfEachValue) {
  const Node preset = Node::load_string("compliance: 0.1 L/cmH2O\nresistance: 2\n", "preset.yaml");
  const Node scenario = Node::load_string("compliance: 0.05 L/cmH2O\n", "scenario.yaml");
  const Node merged = scenario.with_fallback(preset);
  EXPECT_DOUBLE_EQ(merged.quantity("compliance", kind::compliance), 0.05e-3 / 98.0665);
  EXPECT_EQ(error_of([&] { merged.quantity("resistance", kind::resistance); }),
            "preset.yaml:2:13: resistance: expected a resistance such as '2 cmH2O*s/L', got '2'");
}

TEST(PhysiologyConfig, ActionsPatchTheDriverAndRefuseKeysOfAnotherMode) {
  const std::string base =
      "model: single\ncompliance: 0.05 L/cmH2O\nresistance: 10 cmH2O*s/L\n"
      "driver: {mode: volume_control, rate: 15 /min, tidal_volume: 500 mL, ie_ratio: 1:2, peep: 5 cmH2O}\n";
  const Node good = Node::load_string(base + "actions:\n  - {at: 10 s, rate: 20 /min}\n"
                                             "  - {at: 20 s, mode: pressure_control, inspiratory_pressure: 15 cmH2O}\n",
                                      "p.yaml");
  const auto cfg = pneuma::scenario::read_physiology(good, 60.0, "/nonexistent");
  ASSERT_EQ(cfg.protocol.settings.size(), 3u);
  const auto& vc = std::get<pneuma::physiology::VolumeControl>(cfg.protocol.settings[1].driver);
  EXPECT_DOUBLE_EQ(vc.rate_hz, 20.0 / 60.0);
  EXPECT_DOUBLE_EQ(vc.inspiratory_time_s, 4.0 / 3.0);  // Ti kept from 15 /min at 1:2
  const auto& pc = std::get<pneuma::physiology::PressureControl>(cfg.protocol.settings[2].driver);
  EXPECT_DOUBLE_EQ(pc.peep_pa, 5 * 98.0665);  // carried over across the mode switch
  EXPECT_DOUBLE_EQ(pc.inspiratory_pressure_pa, 15 * 98.0665);

  const Node bad = Node::load_string(base + "actions:\n  - {at: 10 s, inspiratory_pressure: 15 cmH2O}\n", "p.yaml");
  EXPECT_EQ(error_of([&] { pneuma::scenario::read_physiology(bad, 60.0, "/nonexistent"); }),
            "p.yaml:6:38: actions[0].inspiratory_pressure: not a setting of volume_control mode");
}

TEST(PhysiologyConfig, AssistModesTheirDefaultsAndAModeSwitchMidRun) {
  using namespace pneuma::physiology;
  const Node n = Node::load_string(
      "model: single\ncompliance: 0.05 L/cmH2O\nresistance: 10 cmH2O*s/L\n"
      "driver: {mode: vc_ac, rate: 12 /min, tidal_volume: 450 mL, inspiratory_time: 1 s, peep: 5 cmH2O,\n"
      "         trigger: {pressure: 1.5 cmH2O}, waveform: decelerating, pressure_limit: 35 cmH2O}\n"
      "effort: {rate: 16 /min, muscle_pressure: 4 cmH2O}\n"
      "actions:\n"
      "  - {at: 10 s, effort: {muscle_pressure: 2 cmH2O}}\n"
      "  - {at: 20 s, mode: cpap_psv, pressure_support: 8 cmH2O, cycle: {flow: 30 %}, rise_time: 0.1 s}\n",
      "p.yaml");
  const auto cfg = pneuma::scenario::read_physiology(n, 60.0, "/nonexistent");
  ASSERT_EQ(cfg.protocol.settings.size(), 3u);
  const auto& vc = std::get<Assisted>(cfg.protocol.settings[0].driver);
  EXPECT_EQ(vc.mode, AssistMode::volume);
  EXPECT_EQ(vc.trigger, TriggerKind::pressure);
  EXPECT_DOUBLE_EQ(vc.trigger_threshold, 1.5 * 98.0665);
  EXPECT_EQ(vc.waveform, FlowWaveform::decelerating);
  EXPECT_DOUBLE_EQ(vc.pressure_limit_pa, 35 * 98.0665);
  EXPECT_DOUBLE_EQ(cfg.protocol.settings[0].effort.rate_hz, 16.0 / 60);
  EXPECT_DOUBLE_EQ(cfg.protocol.settings[0].effort.ie_ratio, 0.5);  // default 1:2
  // The effort patched key by key; the driver unchanged.
  EXPECT_DOUBLE_EQ(cfg.protocol.settings[1].effort.amplitude_pa, 2 * 98.0665);
  EXPECT_DOUBLE_EQ(cfg.protocol.settings[1].effort.rate_hz, 16.0 / 60);
  EXPECT_TRUE(cfg.protocol.settings[1].driver == cfg.protocol.settings[0].driver);
  // The switch keeps PEEP, the trigger and the (longest) inspiratory time; no backup rate.
  const auto& ps = std::get<Assisted>(cfg.protocol.settings[2].driver);
  EXPECT_EQ(ps.mode, AssistMode::pressure_support);
  EXPECT_EQ(ps.rate_hz, 0.0);
  EXPECT_DOUBLE_EQ(ps.peep_pa, 5 * 98.0665);
  EXPECT_EQ(ps.trigger, TriggerKind::pressure);
  EXPECT_DOUBLE_EQ(ps.inspiratory_pressure_pa, 8 * 98.0665);
  EXPECT_EQ(ps.cycle, CycleKind::flow);
  EXPECT_DOUBLE_EQ(ps.cycle_fraction, 0.3);
  EXPECT_DOUBLE_EQ(ps.rise_time_s, 0.1);
  EXPECT_DOUBLE_EQ(ps.inspiratory_time_s, 1.0);
  // Defaults: a flow trigger at 2 L/min; pressure support cycles at 25 % within 3 s.
  const Node d = Node::load_string("model: single\ncompliance: 0.05 L/cmH2O\nresistance: 10 cmH2O*s/L\n"
                                   "driver: {mode: cpap_psv, pressure_support: 8 cmH2O}\n",
                                   "d.yaml");
  const auto& dp =
      std::get<Assisted>(pneuma::scenario::read_physiology(d, 60.0, "/nonexistent").protocol.settings[0].driver);
  EXPECT_EQ(dp.trigger, TriggerKind::flow);
  EXPECT_DOUBLE_EQ(dp.trigger_threshold, 2e-3 / 60);
  EXPECT_EQ(dp.cycle, CycleKind::flow);
  EXPECT_DOUBLE_EQ(dp.cycle_fraction, 0.25);
  EXPECT_DOUBLE_EQ(dp.inspiratory_time_s, 3.0);
}

TEST(PhysiologyConfig, EffortReleaseIsAShareOfTheExpiration) {
  const std::string head = "model: single\ncompliance: 0.05 L/cmH2O\nresistance: 10 cmH2O*s/L\n"
                           "driver: {mode: cpap_psv, pressure_support: 8 cmH2O}\n";
  const auto effort_of = [&](const std::string& effort) {
    return pneuma::scenario::read_physiology(Node::load_string(head + effort, "r.yaml"), 60.0, "/nonexistent")
        .protocol.settings[0]
        .effort;
  };
  EXPECT_DOUBLE_EQ(effort_of("effort: {rate: 16 /min, muscle_pressure: 4 cmH2O, release: 20 %}\n").release_share, 0.2);
  EXPECT_DOUBLE_EQ(effort_of("effort: {rate: 16 /min, muscle_pressure: 4 cmH2O, release: 1}\n").release_share, 1.0);
  // Default: the spontaneous driver's relaxation over half of the expiration.
  EXPECT_DOUBLE_EQ(effort_of("effort: {rate: 16 /min, muscle_pressure: 4 cmH2O}\n").release_share, 0.5);
  EXPECT_EQ(error_of([&] { effort_of("effort: {rate: 16 /min, muscle_pressure: 4 cmH2O, release: 0 %}\n"); }),
            "r.yaml:5:60: effort.release: expected a share of the expiration above 0 and at most 100 %, got '0 %'");
  EXPECT_EQ(error_of([&] { effort_of("effort: {rate: 16 /min, muscle_pressure: 4 cmH2O, release: 120 %}\n"); }),
            "r.yaml:5:60: effort.release: expected a share of the expiration above 0 and at most 100 %, got '120 %'");
}

TEST(PhysiologyConfig, TheManifestNamesAnEffortsReleaseOnlyWhereSet) {
  const auto effort_fact = [](const std::string& effort) {
    const Node n = Node::load_string("model: single\ncompliance: 0.05 L/cmH2O\nresistance: 10 cmH2O*s/L\n"
                                     "driver: {mode: cpap_psv, pressure_support: 8 cmH2O}\n" +
                                         effort,
                                     "m.yaml");
    const auto cfg = pneuma::scenario::read_physiology(n, 60.0, "/nonexistent");
    for (const auto& [key, value] : pneuma::outputs::ventilator_facts(cfg.protocol, {}))
      if (key == "ventilator.settings[0].effort") return value;
    return std::string("(none)");
  };
  EXPECT_EQ(effort_fact("effort: {rate: 16 /min, muscle_pressure: 4 cmH2O, release: 20 %}\n"),
            "16 /min, I:E 0.5, 4 cmH2O, release 20 %");
  // The default effort reads as before the release could be set.
  EXPECT_EQ(effort_fact("effort: {rate: 16 /min, muscle_pressure: 4 cmH2O}\n"), "16 /min, I:E 0.5, 4 cmH2O");
}
