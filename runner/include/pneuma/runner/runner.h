#pragma once
// The scenario runner: drive (physiology -> V(t)), prepare (model::compile: surface, field; then
// V -> s and the fold check), then the loop: advance every frame and hand it to every output the scenario
// asks for (output_registry.h); then each output's end-of-run step and manifest.json.
// `pneuma run` is a thin wrapper around run_scenario().
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "pneuma/model/compile.h"
#include "pneuma/model/model.h"
#include "pneuma/model/no_fold_record.h"
#include "pneuma/physiology/simulate.h"
#include "pneuma/scenario/scenario.h"

namespace pneuma::runner {

// The stages before the loop, as every caller runs them (run_scenario, the Python module):
// compile, the scale of every sample of the drive (V -> s), and the fold check of the most
// deformed frames.
struct Prepared {
  model::Model model;
  std::vector<model::LungScales> scales;                  // per model lung
  std::vector<std::pair<std::string, double>> timings_s;  // compile's steps and the fold check
};

// Throws pneuma::Error (one line) as model::compile, Model::scales and model::check_no_fold; for a
// trace-driven run the lungs cannot follow, InputError "<trace>:<line>: ..." naming the sample.
// With `no_fold`, the fold check is skipped where an earlier run passed it for the same surfaces
// and scales, and its pass kept (model::check_no_fold's record).
Prepared prepare(const scenario::Scenario& scenario, const physiology::SimulationResult& drive,
                 const model::CompileOptions& options, const model::NoFoldRecord& no_fold = {});

struct RunOptions {
  std::filesystem::path output_dir;
  bool quiet = false;
  std::optional<double> edge_override_m;  // a coarser or finer mesh than the scenario's
};

struct RunResult {
  std::vector<std::filesystem::path> files;  // relative to the output folder, manifest last
  std::vector<std::pair<std::string, double>> timings_s;
  std::size_t frame_count = 0;
  std::size_t vertex_count = 0;
  bool field_reused = false;
  double min_scale = 0.0, max_scale = 0.0;  // of the first lung (the only one of a one-lung run)
  struct Lung {
    std::string name;  // "right", "left", or "lung" for one surface of no known side
    std::size_t vertex_count = 0;
    double min_scale = 0.0, max_scale = 0.0;
  };
  std::vector<Lung> lungs;  // one or two, in the model's order
};

// Runs the whole scenario (loaded with output_keys(): see output_registry.h). Throws
// pneuma::Error (one line) on any failure; outputs are staged and appear together, so a failed
// or interrupted run leaves the previous complete output as it was.
RunResult run_scenario(const scenario::Scenario& scenario, const RunOptions& options);

}  // namespace pneuma::runner
