// `pneuma simulate` end to end: shipped scenarios run; every bad input is one line + exit code.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "test_support.h"

using pneuma::test::count_lines;
using pneuma::test::run_pneuma;
using pneuma::test::TempDir;

TEST(SimulateCli, ShippedScenariosRunAndWriteCsv) {
  for (const char* name : {"quiet-breathing", "ventilated-patient"}) {
    TempDir dir;
    const auto scenario = pneuma::test::source_dir() / "scenarios" / (std::string(name) + ".yaml");
    const auto r = run_pneuma({"simulate", scenario.string(), "-o", (dir / "phys.csv").string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(r.err.empty()) << r.err;
    EXPECT_GT(count_lines(dir / "phys.csv"), 6000);  // 100 Hz over 60-90 s, plus the header
    EXPECT_GT(count_lines(dir / "phys-breaths.csv"), 10);
  }
}

TEST(SimulateCli, ShippedVentilatorScenariosArePatientTriggered) {
  for (const char* name :
       {"ventilator-vc-ac", "ventilator-pc-ac", "ventilator-cpap-psv", "ventilator-simv", "ventilator-pav"}) {
    TempDir dir;
    const auto scenario = pneuma::test::source_dir() / "scenarios" / (std::string(name) + ".yaml");
    const auto r = run_pneuma({"simulate", scenario.string(), "-o", (dir / "phys.csv").string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(r.err.empty()) << r.err;
    EXPECT_GT(count_lines(dir / "phys.csv"), 6000);
    const std::string breaths = pneuma::test::read_text(dir / "phys-breaths.csv");
    EXPECT_NE(
        breaths.find(",trigger,trigger_delay_s,cycle,inspiratory_time_s,ie_ratio,mean_airway_pressure_cmH2O,"
                     "intrinsic_peep_cmH2O,missed_triggers,double_trigger,breath_type,expiratory_hold_s,"
                     "total_peep_cmH2O,vti_mL,vte_mL,leak_percent,inspiratory_pressure_cmH2O,alarms,cycle_delay_s,"
                     "early_cycling,late_cycling,flow_starvation_cmH2O,flow_starvation\n"),
        std::string::npos)
        << name;
    EXPECT_NE(breaths.find(",patient_flow,"), std::string::npos) << name;
  }
}

TEST(SimulateCli, ShippedSimvScenarioMixesMandatoryAndSupportedBreathsAndHoldsOnce) {
  TempDir dir;
  const auto scenario = pneuma::test::source_dir() / "scenarios" / "ventilator-simv.yaml";
  const auto r = run_pneuma({"simulate", scenario.string(), "-o", (dir / "phys.csv").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::istringstream rows(pneuma::test::read_text(dir / "phys-breaths.csv"));
  std::string row;
  std::getline(rows, row);
  int mandatory = 0, spontaneous = 0, synchronised = 0, holds = 0, pc_simv = 0;
  while (std::getline(rows, row)) {
    mandatory += row.find(",mandatory,") != std::string::npos;
    spontaneous += row.find(",spontaneous,") != std::string::npos;
    synchronised += row.find(",patient_flow,") != std::string::npos && row.find(",mandatory,") != std::string::npos;
    holds += row.find(",mandatory,2,") != std::string::npos || row.find(",spontaneous,2,") != std::string::npos;
    pc_simv += row.find(",pc_simv,") != std::string::npos;
  }
  // 60 s at 10 /min then 6 /min: about 8 mandatory breaths, the patient's 16 /min fill the rest.
  EXPECT_GE(mandatory, 6);
  EXPECT_LE(mandatory, 10);
  EXPECT_GE(spontaneous, 5);
  EXPECT_GE(synchronised, 1);
  EXPECT_EQ(holds, 1);
  EXPECT_GE(pc_simv, 3);
}

TEST(SimulateCli, VersionAndHelp) {
  auto r = run_pneuma({"--version"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_EQ(r.out, "pneuma " PNEUMA_VERSION "\n");
  r = run_pneuma({"--help"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("simulate"), std::string::npos);
  // Usage names the program, not the path it was started from; examples in the footer.
  EXPECT_NE(r.out.find("Usage: pneuma "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("Examples:\n  pneuma run scenarios/quiet-breathing.yaml -o out/demo\n"), std::string::npos);
  r = run_pneuma({"run", "--help"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("Usage: pneuma run "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("--edge <length, e.g. 3mm>"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("Examples:"), std::string::npos) << r.out;
}

// Every command's --help ends with examples of that very command (not the top-level ones).
TEST(SimulateCli, EveryCommandsHelpShowsItsOwnExamples) {
  const std::vector<std::vector<std::string>> commands = {{"run"},
                                                          {"simulate"},
                                                          {"field"},
                                                          {"phantom"},
                                                          {"render"},
                                                          {"compare"},
                                                          {"mesh"},
                                                          {"mesh", "info"},
                                                          {"mesh", "repair"},
                                                          {"mesh", "remesh"},
                                                          {"mesh", "from-labels"}};
  for (const auto& command : commands) {
    std::vector<std::string> args = command;
    args.emplace_back("--help");
    const auto r = run_pneuma(args);
    std::string name = "pneuma";
    for (const auto& word : command) name += " " + word;
    ASSERT_EQ(r.exit_code, 0) << name;
    const auto examples = r.out.find("\nExamples:\n");
    ASSERT_NE(examples, std::string::npos) << name << ":\n" << r.out;
    std::istringstream lines(r.out.substr(examples + 11));
    int count = 0;
    for (std::string line; std::getline(lines, line) && !line.empty(); ++count) {
      EXPECT_EQ(line.rfind("  " + name + " ", 0), 0u) << name << ": '" << line << "'";
    }
    EXPECT_GE(count, command == std::vector<std::string>{"mesh"} ? 4 : 2) << name;
  }
}

struct BadScenario {
  const char* name;
  const char* yaml;
  const char* message;  // after "<file>:"
};

class SimulateBadInput : public ::testing::TestWithParam<BadScenario> {};

TEST_P(SimulateBadInput, OneLineNamingFilePlaceAndExpectation) {
  TempDir dir;
  const auto file = dir.write("s.yaml", GetParam().yaml);
  const auto out = dir / "out.csv";
  const auto r = run_pneuma({"simulate", file.string(), "-o", out.string()});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, file.string() + ":" + GetParam().message + "\n");
  EXPECT_TRUE(r.out.empty());
  EXPECT_EQ(dir.files(), std::vector<std::string>{"s.yaml"}) << "no partial output";
}

// A name longer than the file system takes (found by fuzz_scenario: std::filesystem::exists threw
// ENAMETOOLONG past the loader, which aborted): the same one line as any unknown name.
TEST(SimulateCli, ANameTooLongForTheFileSystemIsTheUsualOneLine) {
  TempDir dir;
  const std::string name(300, 'x');
  const auto file = dir.write("s.yaml", "duration: 20 s\nphysiology:\n  preset: " + name + "\n");
  auto r = run_pneuma({"simulate", file.string(), "-o", (dir / "out.csv").string()});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, file.string() + ":3:11: physiology.preset: no preset '" + name +
                       "' (looked for " PNEUMA_SOURCE_DIR "/configs/physiology/" + name +
                       ".yaml; shipped presets: healthy-adult, obstructive, stiff-lung)\n");
  const auto run =
      dir.write("r.yaml", "duration: 20 s\nphysiology:\n  preset: healthy-adult\nfield:\n  tissue: " + name + "\n");
  r = run_pneuma({"run", run.string(), "-o", (dir / "out").string()});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(
      r.err,
      run.string() + ":5:11: field.tissue: no tissue '" + name + "' (looked for " PNEUMA_SOURCE_DIR "/configs/tissue/" +
          name +
          ".yaml; shipped presets: fibrotic-lower-lobe, healthy-supine, healthy-supine-slide, healthy-upright, healthy-upright-ct)\n");
  EXPECT_FALSE(std::filesystem::exists(dir / "out"));
}

INSTANTIATE_TEST_SUITE_P(
    Cases, SimulateBadInput,
    ::testing::Values(
        BadScenario{"missing_unit", "duration: 20\nphysiology:\n  preset: healthy-adult\n",
                    "1:11: duration: expected a duration such as '2 s', got '20'"},
        BadScenario{"wrong_unit", "duration: 20 s\nphysiology:\n  preset: healthy-adult\n  compliance: 0.1 L\n",
                    "4:15: physiology.compliance: expected a compliance such as '0.1 L/cmH2O', got '0.1 L'"},
        BadScenario{"negative_duration", "duration: -5 s\nphysiology:\n  preset: healthy-adult\n",
                    "1:11: duration: expected a positive duration, got '-5 s'"},
        // The ventilator at the bedside (#47): circuit, PRVC, apnea backup, alarms, flow limitation.
        // APRV and PAV (#47).
        BadScenario{"aprv_high_below_low",
                    "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n"
                    "  driver: {mode: aprv, high_pressure: 5 cmH2O, low_pressure: 8 cmH2O, high_time: 4 s, low_time: "
                    "0.5 s}\n",
                    "5:39: physiology.driver.high_pressure: expected high_pressure above low_pressure (8 cmH2O), got 5 "
                    "cmH2O"},
        BadScenario{"aprv_trigger_without_support",
                    "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n"
                    "  driver: {mode: aprv, high_pressure: 25 cmH2O, low_pressure: 8 cmH2O, high_time: 4 s, low_time: "
                    "0.5 s, trigger: {flow: 2 L/min}}\n",
                    "5:114: physiology.driver.trigger: APRV triggers and cycles nothing; set pressure_support for "
                    "BiLevel's supported breaths"},
        BadScenario{"pav_full_gain",
                    "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n"
                    "  driver: {mode: pav, gain: 100 %, assisted_resistance: 10 cmH2O*s/L, assisted_compliance: 50 "
                    "mL/cmH2O}\n",
                    "5:29: physiology.driver.gain: expected a share of the patient's pressure above 0 and below 100 %, "
                    "got '100 %'"},
        BadScenario{"pav_runaway",
                    "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n"
                    "  driver: {mode: pav, gain: 50 %, assisted_resistance: 10 cmH2O*s/L, assisted_compliance: 50 "
                    "mL/cmH2O}\n  actions:\n    - {at: 5 s, resistance: 4 cmH2O*s/L}\n",
                    "7:29: physiology.actions[0].resistance: the assist gain times the assisted resistance must stay "
                    "below the patient's resistance (4 cmH2O*s/L): the assist would run away"},
        BadScenario{"pav_with_circuit",
                    "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n"
                    "  driver: {mode: pav, gain: 80 %, assisted_resistance: 10 cmH2O*s/L, assisted_compliance: 50 "
                    "mL/cmH2O, circuit: {leak: {flow: 5 L/min, at: 10 cmH2O}}}\n",
                    "5:113: physiology.driver.circuit: PAV assists the patient's own flow: it takes no circuit"},
        BadScenario{
            "tubing_without_resistance",
            "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n  driver:\n"
            "    mode: pc_ac\n    rate: 12 /min\n    inspiratory_time: 1 s\n    inspiratory_pressure: 10 cmH2O\n"
            "    circuit: {compliance: 2 mL/cmH2O}\n",
            "10:27: physiology.driver.circuit.compliance: a tubing compliance fills through the tubing: give "
            "the tubing resistance too (such as '1 cmH2O*s/L')"},
        BadScenario{"prvc_limit_below_first_breath",
                    "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n  driver:\n"
                    "    mode: prvc\n    rate: 12 /min\n    inspiratory_time: 1 s\n    peep: 5 cmH2O\n"
                    "    tidal_volume: 450 mL\n    inspiratory_pressure: 10 cmH2O\n    pressure_limit: 12 cmH2O\n",
                    "12:21: physiology.driver.pressure_limit: expected a pressure limit above PEEP + "
                    "inspiratory_pressure (15 cmH2O), got 12 cmH2O"},
        BadScenario{"apnea_backup_too_long",
                    "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n  driver:\n"
                    "    mode: cpap_psv\n    pressure_support: 8 cmH2O\n    apnea: {time: 20 s, rate: 12 /min, "
                    "inspiratory_pressure: 10 cmH2O, inspiratory_time: 6 s}\n",
                    "8:90: physiology.driver.apnea.inspiratory_time: expected less than one backup breath (60 / rate "
                    "= 5 s), got '6 s'"},
        BadScenario{
            "apnea_outside_cpap",
            "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n  driver:\n"
            "    mode: pc_ac\n    rate: 12 /min\n    inspiratory_time: 1 s\n    inspiratory_pressure: 10 cmH2O\n"
            "    apnea: {time: 20 s, rate: 12 /min, inspiratory_pressure: 10 cmH2O, inspiratory_time: 1 s}\n",
            "10:12: physiology.driver.apnea: not a setting of pc_ac mode"},
        BadScenario{
            "disconnection_share",
            "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n  driver:\n"
            "    mode: pc_ac\n    rate: 12 /min\n    inspiratory_time: 1 s\n    inspiratory_pressure: 10 cmH2O\n"
            "    alarms: {disconnection: 120 %}\n",
            "10:29: physiology.driver.alarms.disconnection: expected a leak share above 0 and at most 100 %, "
            "got '120 %'"},
        BadScenario{
            "leak_law",
            "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n  driver:\n"
            "    mode: pc_ac\n    rate: 12 /min\n    inspiratory_time: 1 s\n    inspiratory_pressure: 10 cmH2O\n"
            "    circuit: {leak: {flow: 10 L/min, at: 10 cmH2O, law: turbulent}}\n",
            "10:57: physiology.driver.circuit.leak.law: expected one of: orifice, linear; got 'turbulent'"},
        BadScenario{"flow_limitation_two_compartments",
                    "duration: 20 s\nphysiology:\n  model: two_compartment\n  resistance: 1 cmH2O*s/L\n"
                    "  compartments:\n    upper: {compliance: 0.02 L/cmH2O, resistance: 5 cmH2O*s/L}\n"
                    "    lower: {compliance: 0.03 L/cmH2O, resistance: 5 cmH2O*s/L}\n"
                    "  flow_limitation: {critical_pressure: 8 cmH2O}\n  driver: {mode: pc_ac, rate: 12 /min, "
                    "inspiratory_time: 1 s, inspiratory_pressure: 10 cmH2O}\n",
                    "8:20: physiology.flow_limitation: only the single model takes this"},
        BadScenario{"unknown_key", "duration: 20 s\nphysiology:\n  preset: healthy-adult\n  complience: 0.1 L/cmH2O\n",
                    "4:3: physiology.complience: unknown key; expected one of: actions, chest_wall_fraction, "
                    "compartments, compliance, driver, effort, expiratory_resistance, flow_limitation, model, "
                    "output_rate, preset, pressure_volume_curve, resistance, solver, transpulmonary_pressure_at_rest"},
        BadScenario{
            "unknown_preset", "duration: 20 s\nphysiology:\n  preset: healthy-martian\n",
            "3:11: physiology.preset: no preset 'healthy-martian' (looked for " PNEUMA_SOURCE_DIR
            "/configs/physiology/healthy-martian.yaml; shipped presets: healthy-adult, obstructive, stiff-lung)"},
        BadScenario{"bad_ratio", "duration: 20 s\nphysiology:\n  preset: healthy-adult\n  driver: {ie_ratio: 2}\n",
                    "4:22: physiology.driver.ie_ratio: expected a ratio such as '1:2', got '2'"},
        BadScenario{"wrong_mode_key",
                    "duration: 20 s\nphysiology:\n  preset: healthy-adult\n  driver: {peep: 5 cmH2O}\n",
                    "4:18: physiology.driver.peep: not a setting of spontaneous mode"},
        BadScenario{
            "action_after_end",
            "duration: 20 s\nphysiology:\n  preset: healthy-adult\n  actions:\n    - {at: 30 s, rate: 10 /min}\n",
            "5:12: physiology.actions[0].at: expected a time within the scenario's duration"},
        BadScenario{"retired_hdf5_positions",
                    "duration: 20 s\nphysiology:\n  preset: healthy-adult\noutputs:\n  hdf5: {positions: true}\n",
                    "5:21: outputs.hdf5.positions: expected float32 or float64 (the stored type; series.h5 now "
                    "always stores every frame's positions, the plain geometry ParaView and meshio read), got 'true'"},
        BadScenario{"hdf5_compression_unknown",
                    "duration: 20 s\nphysiology:\n  preset: healthy-adult\noutputs:\n  hdf5: {compression: lzf}\n",
                    "5:23: outputs.hdf5.compression: expected one of: none, gzip; got 'lzf'"},
        BadScenario{"report_not_a_switch",
                    "duration: 20 s\nphysiology:\n  preset: healthy-adult\noutputs:\n  report: maybe\n",
                    "5:11: outputs.report: expected true or false, got 'maybe'"},
        BadScenario{"report_unknown_option",
                    "duration: 20 s\nphysiology:\n  preset: healthy-adult\noutputs:\n  report: {open: true}\n",
                    "5:12: outputs.report.open: unknown key; expected one of: enabled"},
        BadScenario{
            "trigger_threshold_zero",
            "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n"
            "  driver: {mode: vc_ac, rate: 12 /min, tidal_volume: 450 mL, inspiratory_time: 1 s, trigger: {flow: 0 L/min}}\n",
            "5:101: physiology.driver.trigger.flow: expected a positive flow, got '0 L/min'"},
        BadScenario{
            "trigger_wrong_unit",
            "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n"
            "  driver: {mode: vc_ac, rate: 12 /min, tidal_volume: 450 mL, inspiratory_time: 1 s, trigger: {pressure: 2 L/min}}\n",
            "5:105: physiology.driver.trigger.pressure: expected a pressure such as '5 cmH2O', got '2 L/min'"},
        BadScenario{
            "cycle_fraction_above_one",
            "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n"
            "  driver: {mode: cpap_psv, pressure_support: 8 cmH2O, cycle: {flow: 120 %}}\n",
            "5:69: physiology.driver.cycle.flow: expected a share of the peak flow above 0 and below 100 %, got '120 %'"},
        BadScenario{
            "pressure_limit_below_peep",
            "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n"
            "  driver: {mode: vc_ac, rate: 12 /min, tidal_volume: 450 mL, inspiratory_time: 1 s, peep: 8 cmH2O, pressure_limit: 6 cmH2O}\n",
            "5:116: physiology.driver.pressure_limit: expected a pressure limit above PEEP (8 cmH2O), got 6 cmH2O"},
        BadScenario{
            "pressure_limit_below_new_peep",
            "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n"
            "  driver: {mode: vc_ac, rate: 12 /min, tidal_volume: 450 mL, inspiratory_time: 1 s}\n  actions:\n    - {at: 10 s, peep: 12 cmH2O, pressure_limit: 10 cmH2O}\n",
            "7:50: physiology.actions[0].pressure_limit: expected a pressure limit above PEEP (12 cmH2O), got 10 cmH2O"},
        BadScenario{"psv_has_no_backup_rate",
                    "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n"
                    "  driver: {mode: cpap_psv, pressure_support: 8 cmH2O, rate: 10 /min}\n",
                    "5:61: physiology.driver.rate: not a setting of cpap_psv mode"},
        BadScenario{
            "effort_on_spontaneous",
            "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n"
            "  driver: {mode: spontaneous, rate: 12 /min, ie_ratio: 1:2, muscle_pressure: 5 cmH2O}\n  effort: {rate: 15 /min, muscle_pressure: 4 cmH2O}\n",
            "6:11: physiology.effort: a patient effort acts on a ventilated patient; spontaneous mode is the patient's own breathing"},
        BadScenario{"simv_rate_missing",
                    "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n"
                    "  driver: {mode: vc_simv, tidal_volume: 450 mL, inspiratory_time: 1 s}\n",
                    "5:11: physiology.driver: missing key 'rate' (expected rate such as '12 /min')"},
        BadScenario{
            "simv_window_longer_than_a_cycle",
            "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n"
            "  driver: {mode: pc_simv, rate: 12 /min, inspiratory_pressure: 15 cmH2O, inspiratory_time: 1 s, trigger_window: 6 s}\n",
            "5:113: physiology.driver.trigger_window: expected a trigger window of at most one cycle (60 / rate = 5 s), got 6 s"},
        BadScenario{"simv_negative_support",
                    "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n"
                    "  driver: {mode: pc_simv, rate: 12 /min, inspiratory_pressure: 15 cmH2O, inspiratory_time: 1 s, "
                    "pressure_support: -2 cmH2O}\n",
                    "5:115: physiology.driver.pressure_support: expected a pressure >= 0, got '-2 cmH2O'"},
        BadScenario{
            "trigger_window_outside_simv",
            "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n"
            "  driver: {mode: vc_ac, rate: 12 /min, tidal_volume: 450 mL, inspiratory_time: 1 s, trigger_window: 2 s}\n",
            "5:101: physiology.driver.trigger_window: not a setting of vc_ac mode"},
        BadScenario{
            "hold_without_ventilator",
            "duration: 20 s\nphysiology:\n  preset: healthy-adult\n  actions:\n    - {at: 10 s, expiratory_hold: 2 s}\n",
            "5:35: physiology.actions[0].expiratory_hold: an expiratory hold needs a ventilator; the patient "
            "breathes spontaneously"},
        BadScenario{"hold_of_zero_seconds",
                    "duration: 20 s\nphysiology:\n  compliance: 0.05 L/cmH2O\n  resistance: 10 cmH2O*s/L\n"
                    "  driver: {mode: vc_ac, rate: 12 /min, tidal_volume: 450 mL, inspiratory_time: 1 s}\n"
                    "  actions:\n    - {at: 10 s, expiratory_hold: 0 s}\n",
                    "7:35: physiology.actions[0].expiratory_hold: expected a positive duration, got '0 s'"},
        BadScenario{"not_yaml", "duration: [20 s\n", "2:1: not valid YAML: end of sequence flow not found"}),
    [](const auto& test_case) { return std::string(test_case.param.name); });

TEST(SimulateCli, MissingScenarioFileIsAUsageError) {
  const auto r = run_pneuma({"simulate", "/nonexistent/scenario.yaml"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "pneuma: scenario: File does not exist: /nonexistent/scenario.yaml (see 'pneuma --help')\n");
}
