// pneuma simulate SCENARIO.yaml -o physiology.csv: the physiology part of a scenario alone.
#include <fmt/format.h>

#include <filesystem>

#include "commands.h"
#include "pneuma/core/error.h"
#include "pneuma/outputs/physiology_csv.h"
#include "pneuma/runner/output_registry.h"
#include "pneuma/scenario/scenario.h"

namespace pneuma::cli {
namespace {

struct SimulateOptions {
  std::string scenario;
  std::string output = "physiology.csv";
  std::string breaths;
  bool quiet = false;
};

void run_simulate(const SimulateOptions& o) {
  const scenario::Scenario scenario = runner::load_scenario(o.scenario);
  const physiology::SimulationResult result = scenario::simulate_physiology(scenario);
  const std::filesystem::path csv = o.output;
  std::filesystem::path breaths = o.breaths;
  if (breaths.empty()) breaths = csv.parent_path() / (csv.stem().string() + "-breaths.csv");
  outputs::write_time_series_csv(csv, result);
  outputs::write_breaths_csv(breaths, result);
  if (o.quiet) return;
  double vt = 0.0, ve = 0.0;
  for (const auto& b : result.breaths) {
    vt += b.tidal_volume_m3;
    ve += b.minute_ventilation_m3_per_s;
  }
  const double n = static_cast<double>(std::max<std::size_t>(1, result.breaths.size()));
  fmt::print("{}: {:.1f} s simulated, {} breaths, mean tidal volume {:.0f} mL, mean minute ventilation {:.2f} L/min\n",
             scenario.name, scenario.duration_s, result.breaths.size(), vt / n * 1e6, ve / n * 60e3);
  fmt::print("CVODE: {} steps, {} right-hand-side evaluations, {} restarts at phase switches\n", result.stats.steps,
             result.stats.rhs_evaluations, result.stats.restarts);
  fmt::print("wrote {} ({} samples) and {}\n", csv.string(), result.series.size(), breaths.string());
}

}  // namespace

void register_simulate(CLI::App& app) {
  auto options = std::make_shared<SimulateOptions>();
  CLI::App* cmd = app.add_subcommand("simulate", "Run only the physiology of a scenario and write CSV time series");
  cmd->add_option("scenario", options->scenario, "Scenario YAML file")->required()->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", options->output, "Time-series CSV to write")->capture_default_str();
  cmd->add_option("--breaths", options->breaths, "Per-breath metrics CSV (default: <output stem>-breaths.csv)");
  cmd->add_flag("-q,--quiet", options->quiet, "Print nothing on success");
  add_examples(*cmd, {"pneuma simulate scenarios/quiet-breathing.yaml -o quiet.csv",
                      "pneuma simulate scenarios/ventilated-patient.yaml -o vent.csv --breaths vent-breaths.csv"});
  cmd->callback([options] { run_simulate(*options); });
}

}  // namespace pneuma::cli
