#pragma once
// The scenario runner: physiology -> V(t); mesh -> field (cached); V(t) -> s(t) -> frames ->
// sinks (sink_registry.h); then manifest.json. `pneuma run` is a thin wrapper around run_scenario().
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "pneuma/engine/frame.h"
#include "pneuma/engine/scenario.h"

namespace pneuma::engine {

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
  double min_scale = 0.0, max_scale = 0.0;
};

// The immutable model of a scenario: its mesh, field and volume map (no frames). Records the
// time of each step in `timings_s` and whether the field came from the cache.
BreathingModel prepare_model(const Scenario& scenario, const RunOptions& options,
                             std::vector<std::pair<std::string, double>>& timings_s, bool& field_reused);

// Runs the whole scenario. Throws pneuma::Error (one line) on any failure; files are written
// atomically, so a failed or interrupted run leaves no partial file.
// The sinks are the registry's (sink_registry.h) that the scenario asks for.
RunResult run_scenario(const Scenario& scenario, const RunOptions& options);

// The scale of every frame for the lung volumes `lung_volume_m3` (physiology, above FRC):
// mesh volume = rest volume + share * (V - reference). Throws UnsupportedError naming the
// first frame whose volume the field cannot reach.
std::vector<double> frame_scales(const BreathingModel& model, const MeshSpec& mesh,
                                 const std::vector<double>& time_s, const std::vector<double>& lung_volume_m3);

}  // namespace pneuma::engine
