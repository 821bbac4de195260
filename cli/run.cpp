// pneuma run SCENARIO.yaml -o OUTDIR: the whole pipeline, physiology to frames and files.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <utility>
#include <vector>

#include "commands.h"
#include "pneuma/core/parameters.h"
#include "pneuma/runner/output_registry.h"
#include "pneuma/runner/runner.h"

namespace pneuma::cli {
namespace {

struct RunCommandOptions {
  std::string scenario;
  std::string output = "out";
  double edge_m = std::numeric_limits<double>::quiet_NaN();  // NaN: not given
  bool quiet = false;
};

void run_command(const RunCommandOptions& o) {
  if (!std::isnan(o.edge_m)) check_option("--edge", parameters::kEdge, o.edge_m);
  const scenario::Scenario scenario = runner::load_scenario(o.scenario);
  runner::RunOptions options;
  options.output_dir = o.output;
  options.quiet = o.quiet;
  if (!std::isnan(o.edge_m)) options.edge_override_m = o.edge_m;
  const runner::RunResult r = runner::run_scenario(scenario, options);
  if (o.quiet) return;
  fmt::print("{}: {} frames at {} Hz over {} s, mesh of {} vertices, field {}\n", scenario.name, r.frame_count,
             scenario.frame_rate_hz, scenario.duration_s, r.vertex_count,
             r.field_reused ? "reused from cache" : "computed");
  if (r.lungs.size() == 2) {
    for (const auto& lung : r.lungs)
      fmt::print("{} lung: {} vertices, scale s from {:.4g} to {:.4g} area units\n", lung.name, lung.vertex_count,
                 lung.min_scale, lung.max_scale);
  } else {
    fmt::print("scale s from {:.4g} to {:.4g} area units\n", r.min_scale, r.max_scale);
  }
  for (const auto& [stage, seconds] : r.timings_s) fmt::print("  {:<26} {:8.3f} s\n", stage, seconds);
  // Files at the top level one by one; a folder (png/, frames/) as one line with its count.
  std::vector<std::pair<std::string, std::size_t>> folders;  // in the order they first appear
  for (const auto& file : r.files) {
    if (file.parent_path().empty()) {
      fmt::print("  {}\n", (std::filesystem::path(o.output) / file).string());
      continue;
    }
    const std::string folder = file.parent_path().generic_string();
    auto it = std::find_if(folders.begin(), folders.end(), [&](const auto& f) { return f.first == folder; });
    if (it == folders.end()) folders.emplace_back(folder, 1);
    else ++it->second;
  }
  for (const auto& [folder, count] : folders)
    fmt::print("  {}/ {} file{}\n", (std::filesystem::path(o.output) / folder).string(), count, count == 1 ? "" : "s");
  fmt::print("outputs are in {}/ (manifest.json lists every file)\n", o.output);
  if (std::find(r.files.begin(), r.files.end(), std::filesystem::path("report.html")) != r.files.end()) {
    fmt::print("open {} in a browser: the lung, the plots and the motion table (no server needed)\n",
               (std::filesystem::path(o.output) / "report.html").string());
  }
}

}  // namespace

void register_run(CLI::App& app) {
  auto options = std::make_shared<RunCommandOptions>();
  CLI::App* cmd = app.add_subcommand("run", "Run a breathing scenario: physiology, field, frames and every output");
  cmd->add_option("scenario", options->scenario, "Scenario YAML file")->required()->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", options->output, "Output folder")->capture_default_str();
  add_quantity_option(*cmd, "--edge", options->edge_m,
                      "Override the mesh edge length, " + parameters::kEdge.range() + " (e.g. 8mm for a quick run)",
                      "length");
  cmd->add_flag("-q,--quiet", options->quiet, "No progress and no summary");
  add_examples(*cmd, {"pneuma run scenarios/quiet-breathing.yaml -o out/demo",
                      "pneuma run scenarios/ventilated-patient.yaml -o out/vent --edge 8mm --quiet"});
  cmd->callback([options] { run_command(*options); });
}

}  // namespace pneuma::cli
