#include "pneuma/runner/runner.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cstdio>
#include <memory>
#include <optional>
#include <span>

#include "pneuma/core/interrupt.h"
#include "pneuma/core/staged_output.h"
#include "pneuma/core/stopwatch.h"
#include "pneuma/model/compile.h"
#include "pneuma/model/frame.h"
#include "pneuma/outputs/manifest.h"
#include "pneuma/runner/output_registry.h"
#include "pneuma/runner/progress.h"

namespace pneuma::runner {
namespace {

// The fold check's pass, kept in the output folder beside the field cache (model::NoFoldRecord).
constexpr const char* kNoFoldFile = "self-intersection.check";

// One output of the run with the seconds it took, over begin, every frame and finish.
struct RunningOutput {
  std::unique_ptr<outputs::Output> output;
  double seconds = 0.0;
};

// Writes manifest.json into the stage (where a failure, such as text JSON cannot hold, still
// leaves the folder as it was), then moves the staged outputs into the folder, the manifest
// last, in one step that Ctrl-C cannot cut: the folder holds the previous output or this one,
// never half of each.
void commit_run(StagedOutput& staged, const std::filesystem::path& folder, RunResult& result,
                const outputs::ManifestInput& manifest) {
  const std::filesystem::path written = outputs::write_manifest(staged.stage(), manifest);
  const DeferInterruptions defer;
  std::vector<std::string> obsolete;  // what the previous run wrote and this one did not
  for (auto& name : outputs::manifest_entries(folder)) {
    const bool ours = std::any_of(result.files.begin(), result.files.end(),
                                  [&](const std::filesystem::path& file) { return file.begin()->string() == name; });
    if (!ours) obsolete.push_back(std::move(name));
  }
  std::error_code ec;
  std::filesystem::remove(folder / "manifest.json", ec);  // no manifest: not complete (yet)
  staged.commit(obsolete, written.filename().string());
  result.files.push_back(written.filename());
}

// The manifest's facts of the model. One lung: as they always were. Two: the totals, then each
// lung's under "lungs.<side>." (vertices, triangles, rest volume and area, scale range, share).
std::vector<std::pair<std::string, std::string>> run_facts(const scenario::Scenario& s, const model::Model& model,
                                                           std::span<const model::LungScales> lung_scales,
                                                           const RunResult& result) {
  std::vector<std::pair<std::string, std::string>> facts{
      {"frames", std::to_string(result.frame_count)},
      {"frame_rate_hz", fmt::format("{}", s.frame_rate_hz)},
      {"vertices", std::to_string(model.vertex_count())},
      {"triangles", std::to_string(model.triangle_count())},
  };
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    const model::LungModel& lung = model.lungs[i];
    const model::LungScales& scales = lung_scales[i];
    const std::string prefix =
        model.two_lungs() ? fmt::format("lungs.{}.", scenario::lung_name(lung.side)) : std::string();
    if (model.two_lungs()) {
      facts.emplace_back(prefix + "vertices", std::to_string(lung.rest.vertex_count()));
      facts.emplace_back(prefix + "triangles", std::to_string(lung.rest.triangle_count()));
    }
    facts.emplace_back(prefix + "rest_volume_m3", fmt::format("{:.9g}", lung.volume_map.volume(0.0)));
    facts.emplace_back(prefix + "rest_area_m2", fmt::format("{:.9g}", lung.rest_area_m2));
    facts.emplace_back(prefix + "scale_range", fmt::format("{:.9g} .. {:.9g}", scales.min_scale, scales.max_scale));
    facts.emplace_back(prefix + "reference_volume_m3", fmt::format("{:.9g}", lung.reference_volume_m3));
    if (lung.deflation_sigma_m > 0.0)
      facts.emplace_back(prefix + "deflation_smoothing_m", fmt::format("{:.9g}", lung.deflation_sigma_m));
    if (!lung.label_values.empty()) {
      facts.emplace_back(
          prefix + "touches_label_map_edge",
          lung.label_map_edges.empty() ? "no" : fmt::format("{}", fmt::join(lung.label_map_edges, ", ")));
    }
    if (model.two_lungs()) {
      facts.emplace_back(prefix + "share", fmt::format("{:.9g}", lung.share));
      if (lung.compartment >= 0) facts.emplace_back(prefix + "compartment", s.mesh.lungs[i].compartment_name);
    }
  }
  if (model.body && model.body->steepest() > 0.0) {
    // The body's narrowest blur, as its ladder chose it for this breath (model/body_motion.h).
    facts.emplace_back("body_smoothing_m", fmt::format("{:.9g}", model.body->options().smallest_sigma_m));
    facts.emplace_back("body_steepest_gradient", fmt::format("{:.3g}", model.body->steepest()));
  }
  facts.emplace_back("field", result.field_reused ? "reused from cache" : "computed");
  return facts;
}

// For a run driven by a trace that the lungs cannot follow (V -> s or the fold check failed): the
// sample to blame, named by its line (a damaged value, 4e-320 in an RPM trace, #49). Of the samples
// the run's window interpolates, the lowest and then the highest volume are each tried alone as a
// whole run: the interpolated frames never go beyond them, so one of them fails as the run did.
std::optional<std::string> unfollowable_trace_sample(const model::Model& model, const physiology::Trace& trace,
                                                     double duration_s) {
  const std::vector<double>& t = trace.time_s;
  const std::vector<double>& v = trace.volume_m3;
  if (t.empty()) return std::nullopt;
  // The window's samples with the one before its start and the one after its end.
  auto first = static_cast<std::size_t>(std::upper_bound(t.begin(), t.end(), trace.start_s) - t.begin());
  auto last = static_cast<std::size_t>(std::lower_bound(t.begin(), t.end(), trace.start_s + duration_s) - t.begin());
  first = first > 0 ? first - 1 : 0;
  last = std::min(last, t.size() - 1);
  const auto [lowest, highest] = std::minmax_element(v.begin() + static_cast<std::ptrdiff_t>(first),
                                                     v.begin() + static_cast<std::ptrdiff_t>(last) + 1);
  for (const auto sample : {lowest, highest}) {
    const auto k = static_cast<std::size_t>(sample - v.begin());
    try {
      std::vector<model::LungScales> scales;
      for (const model::LungModel& lung : model.lungs) {
        model::LungScales one;
        one.scales = lung.scales({t[k]}, {v[k]});
        one.min_scale = one.max_scale = one.scales.front();
        scales.push_back(std::move(one));
      }
      model::check_no_fold(model, scales);
    } catch (const UnsupportedError& e) {
      return fmt::format("{}:{}: the lungs cannot follow this sample ({:.4g} mL from FRC, the run's {}): {}",
                         trace.file.string(), trace.line[k], v[k] * 1e6, sample == lowest ? "lowest" : "highest",
                         e.what());
    }
  }
  return std::nullopt;
}

}  // namespace

Prepared prepare(const scenario::Scenario& s, const physiology::SimulationResult& drive,
                 const model::CompileOptions& options, const model::NoFoldRecord& no_fold) {
  model::CompileOptions with_drive = options;
  with_drive.drive = &drive;  // places the scan on the breath (mesh.breath)
  Prepared prepared{model::compile(s, with_drive), {}, {}};
  prepared.timings_s = prepared.model.report.timings_s;
  try {
    prepared.scales = prepared.model.scales(drive);
    const auto start = Clock::now();
    const bool passed_before = model::check_no_fold(prepared.model, prepared.scales, no_fold);
    prepared.timings_s.emplace_back(passed_before ? "self-intersection check (cached)" : "self-intersection check",
                                    seconds_since(start));
  } catch (const UnsupportedError&) {
    if (s.physiology.trace) {
      if (auto sample = unfollowable_trace_sample(prepared.model, *s.physiology.trace, s.duration_s))
        throw InputError(*sample);
    }
    throw;
  }
  return prepared;
}

RunResult run_scenario(const scenario::Scenario& s, const RunOptions& options) {
  RunResult result;
  // Every output, the field cache (`cache: auto`) and the manifest included, is written into a
  // stage and moved into the folder at the end (staged_output.h): a failed or interrupted run
  // leaves the previous complete output as it was. The cache is looked up in the folder.
  const std::filesystem::path& folder = options.output_dir;
  StagedOutput staged(folder);
  const std::filesystem::path& out = staged.stage();
  const std::vector<const outputs::OutputPlugin*> plugins = requested_outputs(s);
  const outputs::OutputNeeds needs = requested_needs(s);

  // Drive: the physiology at the frame rate, and at its own output rate for the outputs that
  // show it (two cheap runs, no resampling).
  auto start = Clock::now();
  const physiology::SimulationResult drive = scenario::simulate_physiology(s, s.frame_rate_hz);
  physiology::SimulationResult physiology;
  if (needs.physiology) physiology = scenario::simulate_physiology(s, s.physiology.options.output_rate_hz);
  result.timings_s.emplace_back("physiology", seconds_since(start));

  // Compile: the model and the scale of every frame, checked. `cache: auto` looks in the folder
  // and writes into the stage.
  // With the field cache in the folder, the fold check's pass is kept there too (the same surfaces
  // and scales are not checked again).
  const bool keep = s.field.cache == scenario::FieldCache::automatic;
  const Prepared prepared =
      prepare(s, drive,
              {.auto_cache_file = folder / "field.h5",
               .auto_cache_write_file = out / "field.h5",
               .edge_override_m = options.edge_override_m,
               .interior = needs.interior},
              keep ? model::NoFoldRecord{folder / kNoFoldFile, out / kNoFoldFile} : model::NoFoldRecord{});
  const model::Model& model = prepared.model;
  for (const std::string& warning : model.report.warnings)
    std::fprintf(stderr, "pneuma: warning: %s\n", warning.c_str());
  result.timings_s.insert(result.timings_s.end(), prepared.timings_s.begin(), prepared.timings_s.end());
  result.field_reused = model.report.field_reused;
  result.vertex_count = model.vertex_count();
  result.frame_count = drive.series.time_s.size();
  outputs::RunInfo info{result.frame_count, s.frame_rate_hz, {}, {}, out};
  std::vector<std::span<const double>> scales;
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    const model::LungScales& lung = prepared.scales[i];
    info.min_scale.push_back(lung.min_scale);
    info.max_scale.push_back(lung.max_scale);
    scales.emplace_back(lung.scales);
    result.lungs.push_back(
        {scenario::lung_name(model.lungs[i].side), model.lungs[i].rest.vertex_count(), lung.min_scale, lung.max_scale});
  }
  result.min_scale = prepared.scales.front().min_scale;
  result.max_scale = prepared.scales.front().max_scale;
  if (keep) {
    for (const model::LungModel& lung : model.lungs)  // lives with the outputs
      result.files.push_back(model::lung_cache_path("field.h5", lung.side, model.two_lungs()));
    result.files.emplace_back(kNoFoldFile);
    if (needs.interior) result.files.emplace_back(model::kBodyFieldCacheFile);
  }

  // The loop: every frame advanced once and handed to every output.
  std::vector<RunningOutput> running;
  running.reserve(plugins.size());
  for (const outputs::OutputPlugin* plugin : plugins) {
    running.push_back({plugin->make(s.output(plugin->key.key)->settings, out), 0.0});
  }
  for (RunningOutput& o : running) {
    const auto begin = Clock::now();
    o.output->begin(model, info);
    o.seconds += seconds_since(begin);
  }
  const auto& t = drive.series.time_s;
  const auto tables = Clock::now();
  // A table costs 33 to 257 exact area sums (about one frame's work each): worth it from a few
  // hundred frames on; a short run sums every frame.
  constexpr std::size_t kFramesForAreaTables = 256;
  std::vector<model::ScaleRange> ranges;
  if (result.frame_count >= kFramesForAreaTables) {
    for (const model::LungScales& lung : prepared.scales) ranges.push_back({lung.min_scale, lung.max_scale});
  }
  model::Frame frame(model, ranges);
  Progress progress("frames", result.frame_count, options.quiet);
  double update_seconds = seconds_since(tables);  // the area tables are part of the frames' work
  for (std::size_t k = 0; k < result.frame_count; ++k) {
    const auto update = Clock::now();
    model::FrameInput input{k, t[k], drive.series.volume_m3[k], {}};
    for (std::size_t i = 0; i < model.lungs.size(); ++i) input.scale[i] = prepared.scales[i].scales[k];
    model::advance(model, input, frame);
    update_seconds += seconds_since(update);
    for (RunningOutput& o : running) {
      const auto begin = Clock::now();
      o.output->frame(model, frame);
      o.seconds += seconds_since(begin);
    }
    progress.update(k + 1);
  }
  progress.finish();
  result.timings_s.emplace_back("frame updates", update_seconds);

  // The end of the run: what needs all of it, then the manifest.
  std::vector<outputs::BreathMotion> motion;
  if (needs.breath_motion) motion = outputs::breath_motion(model, drive, scales);
  // The rest lungs' mask of the voxel outputs is kept beside the field cache, and as it is.
  const std::filesystem::path cache_dir = keep ? folder : std::filesystem::path();
  const outputs::RunRecord record{&s,        info, &drive, &physiology, scales, &motion, model.report.field_reused,
                                  cache_dir, {}};
  outputs::ManifestInput manifest{s.file, s.name, {}, {}, run_facts(s, model, prepared.scales, result)};
  for (RunningOutput& o : running) {
    const auto begin = Clock::now();
    for (auto& file : o.output->finish(model, record)) result.files.push_back(std::filesystem::relative(file, out));
    o.seconds += seconds_since(begin);
    result.timings_s.emplace_back("output " + o.output->name(), o.seconds);
    for (auto& fact : o.output->facts()) manifest.facts.push_back(std::move(fact));
  }
  manifest.files = result.files;
  manifest.timings_s = result.timings_s;
  commit_run(staged, folder, result, manifest);
  return result;
}

}  // namespace pneuma::runner
