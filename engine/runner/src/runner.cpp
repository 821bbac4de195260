#include "pneuma/engine/runner.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "pneuma/core/error.h"
#include "pneuma/core/interrupt.h"
#include "pneuma/core/staged_output.h"
#include "pneuma/core/stopwatch.h"
#include "pneuma/engine/field_cache.h"
#include "pneuma/engine/manifest.h"
#include "pneuma/engine/physiology_csv.h"
#include "pneuma/engine/progress.h"
#include "pneuma/engine/report.h"
#include "pneuma/engine/sinks.h"
#include "pneuma/engine/sink_registry.h"
#include "pneuma/engine/tissue.h"
#include "pneuma/engine/motion_csv.h"
#include "pneuma/mesh/io.h"
#include "pneuma/mesh/labels.h"
#include "pneuma/mesh/phantom.h"
#include "pneuma/mesh/remesh.h"
#include "pneuma/mesh/repair.h"
#include "pneuma/mesh/surface_queries.h"

namespace pneuma::engine {
namespace {

mesh::TriangleMesh phantom_surface(const MeshSpec& spec, double edge_m) {
  mesh::PhantomOptions phantom;
  phantom.lung = *spec.phantom;
  phantom.edge_length_m = edge_m;
  return mesh::make_lung_phantom(phantom);
}

mesh::TriangleMesh read_file_mesh(const MeshSpec& spec) {
  mesh::ReadOptions read;
  read.metres_per_unit = spec.metres_per_unit;
  read.unit_from_file = !spec.unit_given;
  return mesh::read_mesh(spec.file, read);
}

// The file's own surface: read and, where asked, repaired (what `export: original` exports).
mesh::TriangleMesh file_surface(const MeshSpec& spec) {
  mesh::TriangleMesh surface = read_file_mesh(spec);
  if (spec.repair) surface = mesh::repair_or_throw(surface, spec.file.string());
  return surface;
}

mesh::RemeshOptions remesh_options(double edge_m) {
  mesh::RemeshOptions remesh;
  remesh.target_edge_length_m = edge_m;
  return remesh;
}

mesh::TriangleMesh remeshed(mesh::TriangleMesh surface, double edge_m) {
  if (edge_m <= 0.0) return surface;
  return mesh::remesh_isotropic(surface, remesh_options(edge_m)).mesh;
}

// The surface the field is computed on, for a file or a label map. A file with a remeshing
// target is repaired, remeshed, and only then judged: remeshing removes slivers repair left.
// A label map is extracted at its own resolution (at most 2 mm, finer for a finer target) and
// remeshed to the target.
mesh::TriangleMesh source_surface(const MeshSpec& spec, double edge_m) {
  if (!spec.labels_file.empty()) {
    mesh::LabelSurfaceOptions extract;
    if (edge_m > 0.0) extract.edge_length_m = std::min(edge_m, extract.edge_length_m);
    return remeshed(mesh::surface_from_labels(spec.labels_file, spec.label_values, extract).mesh, edge_m);
  }
  if (!spec.repair) return remeshed(read_file_mesh(spec), edge_m);
  if (edge_m <= 0.0) return file_surface(spec);
  return mesh::repair_and_remesh(read_file_mesh(spec), spec.file.string(), {}, remesh_options(edge_m)).remesh.mesh;
}

// The field model of the scenario's surface, from the cache where it holds one for these inputs.
// A file mesh is looked up by its bytes and the options that shape it before it is repaired and
// remeshed, so a cache hit pays for neither.
CachedField field_model(const Scenario& s, const Tissue& tissue, double edge_m, const std::filesystem::path& output_dir) {
  const FieldOptions& field = s.field.options;
  const bool from_source = !s.mesh.phantom;
  if (s.field.cache == FieldCache::off) {
    const mesh::TriangleMesh surface = from_source ? source_surface(s.mesh, edge_m) : phantom_surface(s.mesh, edge_m);
    return compute_uncached(surface, tissue, field);
  }
  const std::filesystem::path cache = s.field.cache == FieldCache::file ? s.field.cache_file : output_dir / "field.h5";
  if (!from_source) return load_or_compute(cache, phantom_surface(s.mesh, edge_m), tissue, field);
  const bool labels = !s.mesh.labels_file.empty();
  const std::string source =
      source_key({labels ? s.mesh.labels_file : s.mesh.file, s.field.tissue_file},
                 fmt::format("{} unit {:.17g} m, repair {}, edge {:.17g} m, labels {}", labels ? "labels" : "file",
                             s.mesh.metres_per_unit, s.mesh.repair, edge_m, fmt::join(s.mesh.label_values, ",")));
  return load_or_compute(cache, source, [&] { return source_surface(s.mesh, edge_m); }, tissue, field);
}

// How each anatomical region moved in each completed breath: from the breath's lowest to its
// highest scale (the frames inside it), measured on the surface at the lowest.
std::vector<BreathMotion> breath_motion(const BreathingModel& model, const physiology::SimulationResult& physiology,
                                        const std::vector<double>& scales) {
  std::vector<BreathMotion> out;
  const auto& t = physiology.series.time_s;
  mesh::TriangleMesh from = model.rest;
  for (std::size_t b = 0; b < physiology.breaths.size(); ++b) {
    const auto& breath = physiology.breaths[b];
    std::size_t lo = scales.size(), hi = scales.size();
    for (std::size_t k = 0; k < scales.size(); ++k) {
      if (t[k] < breath.start_s || t[k] > breath.start_s + breath.duration_s) continue;
      if (lo == scales.size() || scales[k] < scales[lo]) lo = k;
      if (hi == scales.size() || scales[k] > scales[hi]) hi = k;
    }
    if (lo == scales.size()) continue;
    for (std::size_t i = 0; i < from.vertices.size(); ++i) {
      from.vertices[i] = model.rest.vertices[i] + scales[lo] * model.unit_displacement[i];
    }
    out.push_back({b, breath.start_s, scales[lo], scales[hi],
                   mesh::summarize_motion(from, model.unit_displacement, scales[hi] - scales[lo], model.regions)});
  }
  return out;
}

// What report.html shows: the physiology.csv series, the motion table, the run's key facts and
// the glb (the bytes breathing.glb has, made here too when the glTF output is off).
ReportInput report_input(const Scenario& s, const BreathingModel& model, const RunInfo& run, const RunResult& result,
                         const physiology::SimulationResult& physiology, const std::vector<BreathMotion>& motion,
                         const std::vector<double>& time_s, const std::vector<double>& scales) {
  ReportInput r;
  r.scenario_name = s.name;
  r.description = s.description;
  r.duration_s = time_s.empty() ? 0.0 : time_s.back();
  r.frame_rate_hz = s.frame_rate_hz;
  r.frame_count = scales.size();
  r.physiology = &physiology;
  const double rest_volume = model.volume_map.volume(0.0);
  std::string mesh = s.mesh.file.filename().string();
  if (!s.mesh.labels_file.empty()) mesh = s.mesh.labels_file.filename().string();
  if (s.mesh.phantom) mesh = *s.mesh.phantom == mesh::Lung::left ? "left lung phantom" : "right lung phantom";
  r.facts = {
      {"scenario", s.file.filename().string()},
      {"mesh",
       fmt::format("{}, {} vertices, {} triangles", mesh, model.rest.vertex_count(), model.rest.triangle_count())},
      {"rest volume, area", fmt::format("{:.1f} mL, {:.1f} cm\u00b2", rest_volume * 1e6, model.rest_area_m2 * 1e4)},
      {"tissue", s.field.tissue},
      {"frames", fmt::format("{} at {:g} Hz, 0 to {:g} s", scales.size(), s.frame_rate_hz, r.duration_s)},
      {"mesh share of each breath", fmt::format("{:g} %", s.mesh.share * 100.0)},
      {"mesh volume change",
       fmt::format("{:.1f} to {:.1f} mL", (model.volume_map.volume(run.min_scale) - rest_volume) * 1e6,
                   (model.volume_map.volume(run.max_scale) - rest_volume) * 1e6)},
      {"field", result.field_reused ? "reused from cache" : "computed"},
  };
  if (!physiology.breaths.empty()) {
    double tidal = 0.0, minute = 0.0;
    for (const auto& b : physiology.breaths) {
      tidal += b.tidal_volume_m3;
      minute += b.minute_ventilation_m3_per_s;
    }
    const double n = static_cast<double>(physiology.breaths.size());
    r.facts.emplace_back("breaths", std::to_string(physiology.breaths.size()));
    r.facts.emplace_back("tidal volume (mean)", fmt::format("{:.0f} mL", tidal / n * 1e6));
    r.facts.emplace_back("minute ventilation (mean)", fmt::format("{:.2f} L/min", minute / n * 1e3 * 60.0));
  }
  r.motion = motion;  // a copy: the manifest's facts come from it too
  r.glb = make_glb(model, run, time_s, scales);
  return r;
}

}  // namespace

BreathingModel prepare_model(const Scenario& s, const RunOptions& options,
                             std::vector<std::pair<std::string, double>>& timings, bool& field_reused) {
  auto start = Clock::now();
  const double edge = options.edge_override_m.value_or(s.mesh.edge_m);
  const Tissue tissue = load_tissue(s.field.tissue_file);
  CachedField computed = field_model(s, tissue, edge, options.output_dir);
  field_reused = computed.reused;
  if (!computed.discarded.empty()) {
    // The cache is derived data: a damaged one is replaced, never used, and the user told.
    std::fprintf(stderr, "pneuma: warning: %s; computed the field again and replaced the file\n",
                 computed.discarded.c_str());
  }
  timings.emplace_back(field_reused ? "mesh and field (cached)" : "mesh and field", seconds_since(start));

  mesh::TriangleMesh rest = std::move(computed.model.rest);
  std::vector<Eigen::Vector3d> u = std::move(computed.model.unit_displacement);
  if (s.mesh.export_original) {
    // The field lives on the remeshed surface; carry it to the original vertices through their
    // closest points on it (barycentric interpolation).
    start = Clock::now();
    mesh::TriangleMesh original = file_surface(s.mesh);
    u = mesh::transfer_vertex_field(rest, u, original.vertices);
    rest = std::move(original);
    timings.emplace_back("field transfer", seconds_since(start));
  }
  // The field's regions are the rest surface's unless the run exports the original mesh.
  const mesh::SurfaceRegions* regions = s.mesh.export_original ? nullptr : computed.regions.get();
  return make_breathing_model(std::move(rest), std::move(u), s.field.options.area_unit, body_frame(tissue), regions);
}

std::vector<double> frame_scales(const BreathingModel& model, const MeshSpec& mesh, const std::vector<double>& time_s,
                                 const std::vector<double>& lung_volume_m3) {
  std::vector<double> scales(time_s.size());
  const double rest_volume = model.volume_map.volume(0.0);
  double guess = 0.0;
  for (std::size_t k = 0; k < time_s.size(); ++k) {
    const double target = rest_volume + mesh.share * (lung_volume_m3[k] - mesh.reference_volume_m3);
    try {
      scales[k] = guess = model.volume_map.scale_for(target, guess);
    } catch (const UnsupportedError& e) {
      throw UnsupportedError(fmt::format("frame {} (t = {:.3f} s): {}; lower the tidal volume or the mesh share", k,
                                         time_s[k], e.what()));
    }
  }
  return scales;
}

RunResult run_scenario(const Scenario& s, const RunOptions& options) {
  RunResult result;
  // Every output but the field cache is written into a stage and moved into the folder at the
  // end (staged_output.h): a failed or interrupted run leaves the previous complete output as
  // it was. The cache stays in the folder itself: it is complete on its own (written
  // atomically) and worth keeping after an interruption.
  const std::filesystem::path& folder = options.output_dir;
  StagedOutput staged(folder);
  const std::filesystem::path& out = staged.stage();

  // Physiology: the CSV at its own rate, the frames at theirs (two cheap runs, no resampling).
  auto start = Clock::now();
  const physiology::SimulationResult frames_physiology = simulate_physiology(s, s.frame_rate_hz);
  physiology::SimulationResult csv_physiology;
  if (s.outputs.physiology_csv || s.outputs.report) {
    csv_physiology = simulate_physiology(s, s.physiology.options.output_rate_hz);
  }
  result.timings_s.emplace_back("physiology", seconds_since(start));

  const BreathingModel model = prepare_model(s, options, result.timings_s, result.field_reused);
  result.vertex_count = model.rest.vertex_count();
  if (s.field.cache == FieldCache::automatic) result.files.emplace_back("field.h5");  // the cache lives with the outputs

  const auto& t = frames_physiology.series.time_s;
  const std::vector<double> scales = frame_scales(model, s.mesh, t, frames_physiology.series.volume_m3);
  const auto [lo, hi] = std::minmax_element(scales.begin(), scales.end());
  result.min_scale = *lo;
  result.max_scale = *hi;
  result.frame_count = scales.size();

  // One CGAL check of the most deformed frame: a self-intersecting surface is refused.
  start = Clock::now();
  for (double extreme : {result.min_scale, result.max_scale}) {
    mesh::TriangleMesh deformed = model.rest;
    for (std::size_t i = 0; i < deformed.vertices.size(); ++i) deformed.vertices[i] += extreme * model.unit_displacement[i];
    if (mesh::self_intersects(deformed)) {
      throw UnsupportedError(fmt::format("{}: the surface self-intersects at scale {:.4g} (mesh volume {:.4g} L); "
                                         "lower the tidal volume or the mesh share",
                                         s.file.string(), extreme, model.volume_map.volume(extreme) * 1e3));
    }
  }
  result.timings_s.emplace_back("self-intersection check", seconds_since(start));

  std::vector<std::unique_ptr<FrameSink>> sinks = make_sinks(s, out);

  const RunInfo run{scales.size(), s.frame_rate_hz, result.min_scale, result.max_scale, out};
  std::vector<double> sink_seconds(sinks.size(), 0.0);
  for (std::size_t i = 0; i < sinks.size(); ++i) {
    const auto begin = Clock::now();
    sinks[i]->begin(model, run);
    sink_seconds[i] += seconds_since(begin);
  }
  Frame frame(model);
  Progress progress("frames", scales.size(), options.quiet);
  double update_seconds = 0.0;
  for (std::size_t k = 0; k < scales.size(); ++k) {
    const auto update = Clock::now();
    advance(model, {k, t[k], frames_physiology.series.volume_m3[k], scales[k]}, frame);
    update_seconds += seconds_since(update);
    for (std::size_t i = 0; i < sinks.size(); ++i) {
      const auto begin = Clock::now();
      sinks[i]->frame(model, frame);
      sink_seconds[i] += seconds_since(begin);
    }
    progress.update(k + 1);
  }
  progress.finish();
  result.timings_s.emplace_back("frame updates", update_seconds);
  for (std::size_t i = 0; i < sinks.size(); ++i) {
    const auto begin = Clock::now();
    for (auto& file : sinks[i]->end()) result.files.push_back(std::filesystem::relative(file, out));
    sink_seconds[i] += seconds_since(begin);
    result.timings_s.emplace_back("sink " + sinks[i]->name(), sink_seconds[i]);
  }
  if (s.outputs.physiology_csv) {
    write_time_series_csv(out / "physiology.csv", csv_physiology);
    write_breaths_csv(out / "physiology-breaths.csv", csv_physiology);
    result.files.emplace_back("physiology.csv");
    result.files.emplace_back("physiology-breaths.csv");
  }
  std::vector<BreathMotion> motion;
  if (s.outputs.motion_csv || s.outputs.report) motion = breath_motion(model, frames_physiology, scales);
  if (s.outputs.motion_csv) {
    write_motion_csv(out / "motion.csv", motion);
    result.files.emplace_back("motion.csv");
  }
  if (s.outputs.report) {
    start = Clock::now();
    write_report(out / "report.html", report_input(s, model, run, result, csv_physiology, motion, t, scales));
    result.files.emplace_back("report.html");
    result.timings_s.emplace_back("report", seconds_since(start));
  }

  ManifestInput manifest{s.file, s.name, result.files, result.timings_s,
                         {{"frames", std::to_string(result.frame_count)},
                          {"frame_rate_hz", fmt::format("{}", s.frame_rate_hz)},
                          {"vertices", std::to_string(model.rest.vertex_count())},
                          {"triangles", std::to_string(model.rest.triangle_count())},
                          {"rest_volume_m3", fmt::format("{:.9g}", model.volume_map.volume(0.0))},
                          {"rest_area_m2", fmt::format("{:.9g}", model.rest_area_m2)},
                          {"scale_range", fmt::format("{:.9g} .. {:.9g}", result.min_scale, result.max_scale)},
                          {"field", result.field_reused ? "reused from cache" : "computed"}}};
  if (s.outputs.motion_csv) {
    for (auto& fact : motion_facts(motion)) manifest.facts.push_back(std::move(fact));
  }
  {
    // The folder holds the previous output or this one, never half of each: Ctrl-C waits.
    const DeferInterruptions defer;
    std::vector<std::string> obsolete;  // what the previous run wrote and this one did not
    for (auto& name : manifest_entries(folder)) {
      const bool ours = std::any_of(result.files.begin(), result.files.end(),
                                    [&](const std::filesystem::path& file) { return file.begin()->string() == name; });
      if (!ours) obsolete.push_back(std::move(name));
    }
    std::error_code ec;
    std::filesystem::remove(folder / "manifest.json", ec);  // no manifest: not complete (yet)
    staged.commit(obsolete);
    result.files.push_back(std::filesystem::relative(write_manifest(folder, manifest), folder));
  }
  return result;
}

}  // namespace pneuma::engine
