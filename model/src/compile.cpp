#include "pneuma/model/compile.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <cstddef>
#include <exception>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/core/stopwatch.h"
#include "pneuma/core/tsan.h"
#include "pneuma/field/tissue.h"
#include "pneuma/image/label_map.h"
#include "pneuma/mesh/geometry/surface_queries.h"
#include "pneuma/mesh/source/surface_source.h"
#include "pneuma/model/field_cache.h"

namespace pneuma::model {
namespace {

using scenario::Scenario;

// The scenario's mesh section in mesh terms: each lung's source, the shared label map, unit,
// repair and edge.
mesh::SurfaceSourceSpec source_spec(const Scenario& s, const CompileOptions& options) {
  mesh::SurfaceSourceSpec spec;
  const std::vector<scenario::LungSpec> lungs = scenario::lung_specs(s.mesh);
  for (const scenario::LungSpec& lung : lungs) {
    mesh::LungSource source;
    if (lung.phantom) source.phantom = lung.side;
    source.file = lung.file;
    source.label_values = lung.label_values;
    source.label_names = lung.label_names;
    source.label_key = lungs.size() == 2 ? fmt::format("mesh.lungs.{}", scenario::lung_name(lung.side)) : "mesh.values";
    spec.lungs.push_back(std::move(source));
  }
  spec.labels_file = s.mesh.labels_file;
  spec.metres_per_unit = s.mesh.metres_per_unit;
  spec.unit_from_file = !s.mesh.unit_given;
  spec.repair = s.mesh.repair;
  spec.edge_m = options.edge_override_m.value_or(s.mesh.edge_m);
  spec.origin = s.file.string();
  spec.edge_key = options.edge_override_m ? "--edge" : "mesh.edge";
  return spec;
}

// The field of lung i's surface, from the cache file `cache` where it holds one for these inputs.
// A file or label map is looked up by its bytes and the options that shape its surface before the
// surface is made, so a cache hit pays for neither the extraction, the repair nor the remeshing.
CacheLookup surface_field(const Scenario& s, const mesh::SurfaceSource& source, std::size_t i,
                          const std::filesystem::path& cache, const std::filesystem::path& save_to) {
  const field::Tissue& tissue = s.field.tissue;
  const field::FieldOptions& given = s.field.options;
  if (s.field.cache == scenario::FieldCache::off) {
    const mesh::TriangleMesh surface = source.surface(i);
    const field::TissueFieldInputs inputs = field::tissue_field_inputs(surface, tissue, given);
    return {compute_field_record(surface, inputs), false, {}, inputs.options.regions};
  }
  if (source.is_phantom(i)) return load_or_compute(cache, source.surface(i), tissue, given, save_to);
  // A label map's every file (a mask folder's masks, a detached header's data), else the file.
  std::vector<std::filesystem::path> input_files =
      source.from_labels() ? image::label_map_files(source.input_file(i)) : std::vector{source.input_file(i)};
  input_files.push_back(s.field.tissue_file);
  const std::string key = source_key(input_files, source.key_text(i));
  std::shared_ptr<const mesh::SurfaceRegions> regions;
  CacheLookup lookup = load_or_compute(
      cache, source_field_key(key, tissue.name, given),
      [&] {
        const mesh::TriangleMesh surface = source.surface(i);
        const field::TissueFieldInputs inputs = field::tissue_field_inputs(surface, tissue, given);
        regions = inputs.options.regions;
        return compute_field_record(surface, inputs);
      },
      save_to);
  lookup.regions = std::move(regions);
  return lookup;
}

// One lung of the scenario: its surface and field (cached), moved onto the original file's
// vertices where the scenario exports those.
LungModel lung_model(const Scenario& s, const mesh::SurfaceSource& surfaces, std::size_t index,
                     const CompileOptions& options, CompileReport& report) {
  auto start = Clock::now();
  const scenario::LungSpec spec = scenario::lung_specs(s.mesh)[index];
  const bool two_lungs = surfaces.two_lungs();
  // `cache: auto`: looked up in the output folder, written into the stage (a failed run leaves
  // the folder as it was). `cache: <file>`: the user's file, read and written in place.
  const bool automatic = s.field.cache != scenario::FieldCache::file;
  const std::filesystem::path cache =
      lung_cache_path(automatic ? options.auto_cache_file : s.field.cache_file, spec.side, two_lungs);
  const std::filesystem::path save_to = automatic && !options.auto_cache_write_file.empty()
                                            ? lung_cache_path(options.auto_cache_write_file, spec.side, two_lungs)
                                            : std::filesystem::path();
  // The file the surface came from (the scenario's for a phantom), for what the field finds wrong
  // with it (an inward-oriented surface).
  const std::filesystem::path& source = surfaces.is_phantom(index) ? s.file : surfaces.input_file(index);
  CacheLookup computed = [&] {
    try {
      return surface_field(s, surfaces, index, cache, save_to);
    } catch (const UnsupportedError& e) {
      const std::string what = e.what();
      if (!what.starts_with("mesh: ")) throw;
      throw UnsupportedError(source.string() + ": " + what.substr(6));
    }
  }();
  report.field_reused = report.field_reused && computed.reused;
  if (!computed.discarded.empty()) {
    // The cache is derived data: a damaged one is replaced, never used, and the user told.
    report.warnings.push_back(computed.discarded + "; computed the field again and replaced the file");
  }
  const std::string what = two_lungs ? fmt::format(" ({} lung)", scenario::lung_name(spec.side)) : "";
  report.timings_s.emplace_back((computed.reused ? "mesh and field (cached)" : "mesh and field") + what,
                                seconds_since(start));

  // Where the scan lies on this lung's breath, and how far below it the lung deflates: the field
  // that deflation needs (the cached field stays the inflation's; docs/voxels.md).
  start = Clock::now();
  const std::vector<double>* volumes = options.drive ? &lung_volumes(*options.drive, spec.compartment) : nullptr;
  double reference_m3 = s.mesh.reference_volume_m3;
  if (s.mesh.breath_at_end_inspiration)
    reference_m3 = volumes && !volumes->empty() ? *std::max_element(volumes->begin(), volumes->end()) : 0.0;
  const double lowest_m3 = volumes && !volumes->empty() ? *std::min_element(volumes->begin(), volumes->end()) : 0.0;
  const double deflation_m3 = spec.share * std::max(0.0, reference_m3 - lowest_m3);
  DeflationField deflation = field_for_deflation(computed.record.rest, computed.record.unit_displacement, deflation_m3);
  if (deflation_m3 > 0.0) report.timings_s.emplace_back("deflation field" + what, seconds_since(start));
  if (!deflation.passes) {
    report.warnings.push_back(fmt::format(
        "the deflation field{} smoothed at {:.0f} mm still crosses itself or moves two surface points "
        "relative to each other by more than their distance at 1.5 times the {:.0f} mL it deflates, or by "
        "more than half their distance at the depth: the lung's inside may tear below the scan (docs/voxels.md, \"The "
        "scan's place on the breath\")",
        what, deflation.sigma_m * 1e3, deflation_m3 * 1e6));
  }

  // The inside, where an output needs it: kept in the field's cache file beside the field it
  // extends (on the cached surface, also where the run exports the original mesh).
  std::shared_ptr<const LungInterior> interior;
  if (options.interior) {
    start = Clock::now();
    field::InteriorOptions interior_options = s.field.interior;
    interior_options.unfold_deflation_m3 = deflation_m3;
    // The inside extends the field it is given: the deflation's, where it is smoothed.
    const std::string field_key = deflation.sigma_m > 0.0 ? fmt::format("{} deflation-sigma {:.17g}",
                                                                        computed.record.metadata.key, deflation.sigma_m)
                                                          : computed.record.metadata.key;
    const std::string key = interior_key(field_key, s.field.interior_edge_m, interior_options, s.field.interior_mesher);
    const bool cached = computed.record.interior && computed.record.interior->key == key;
    if (cached) {
      interior = computed.record.interior;
    } else {
      std::shared_ptr<LungInterior> fresh =
          compute_interior(computed.record.rest, deflation.unit_displacement, s.field.interior_edge_m, interior_options,
                           s.field.interior_mesher);
      fresh->key = key;
      interior = fresh;
      computed.record.interior = fresh;
      if (s.field.cache != scenario::FieldCache::off) save_field(save_to.empty() ? cache : save_to, computed.record);
    }
    report.timings_s.emplace_back((cached ? "interior (cached)" : "interior") + what, seconds_since(start));
  }

  mesh::TriangleMesh rest = std::move(computed.record.rest);
  std::vector<Eigen::Vector3d> u = std::move(deflation.unit_displacement);
  if (s.mesh.export_original) {
    // The field lives on the remeshed surface; carry it to the original vertices through their
    // closest points on it (barycentric interpolation).
    start = Clock::now();
    mesh::TriangleMesh original = surfaces.original_surface(index);
    u = mesh::transfer_vertex_field(rest, u, original.vertices);
    rest = std::move(original);
    report.timings_s.emplace_back("field transfer", seconds_since(start));
  }
  // The field's regions are the rest surface's unless the run exports the original mesh. A lung
  // of two has its side (one surface: the side found from its geometry, as before).
  const mesh::SurfaceRegions* regions = s.mesh.export_original ? nullptr : computed.regions.get();
  LungModel lung = [&] {
    try {
      return make_model(std::move(rest), std::move(u), s.field.options.area_unit, field::body_axes(s.field.tissue),
                        regions, two_lungs ? spec.side : std::optional<mesh::Lung>{});
    } catch (const UnsupportedError& e) {  // a field that does not enlarge the surface: name what it came from
      throw UnsupportedError(source.string() + ": " + e.what());
    }
  }();
  lung.side = spec.side;
  lung.share = spec.share;
  lung.reference_volume_m3 = reference_m3;
  lung.deflation_sigma_m = deflation.sigma_m;
  lung.compartment = spec.compartment;
  lung.label_values = surfaces.lung(index).label_values;
  lung.interior = std::move(interior);
  return lung;
}

}  // namespace

std::filesystem::path lung_cache_path(const std::filesystem::path& path, const std::optional<mesh::Lung>& side,
                                      bool two_lungs) {
  if (!two_lungs) return path;
  std::filesystem::path out = path;
  out.replace_filename(path.stem().string() + "-" + scenario::lung_name(side) + path.extension().string());
  return out;
}

Model compile(const Scenario& s, const CompileOptions& options) {
  Model model;
  model.scenario_file = s.file;
  model.report.field_reused = true;
  const mesh::SurfaceSource surfaces(source_spec(s, options));
  // Two lungs are made side by side: each one's surface, field and inside depend on nothing of
  // the other's, and their largest steps (CGAL Mesh_3 on a label map, the tetrahedra) run on one
  // thread each. Each lung reports into its own CompileReport, merged in lung order, and the
  // first lung's error wins as it did when they were made one after the other, so the model,
  // its messages and its files are the same at any thread count; only the stage times overlap.
  const std::size_t count = surfaces.lung_count();
  std::vector<std::optional<LungModel>> made(count);
  std::vector<CompileReport> reports(count, CompileReport{.field_reused = true, .timings_s = {}, .warnings = {}});
  std::vector<std::exception_ptr> errors(count);
  // Isolated: a thread waiting inside one lung's parallel loops takes no work of the other lung's,
  // which could otherwise start on top of it while it holds a lock (HDF5's, ITK's reader's). The
  // label map itself is made once collaboratively (SurfaceSource::label_map): no lock there.
  auto make = [&](std::size_t i) {
    tbb::this_task_arena::isolate([&] {
      try {
        made[i] = lung_model(s, surfaces, i, options, reports[i]);
      } catch (...) {
        errors[i] = std::current_exception();
      }
    });
  };
  {
    const tsan::Region region;
    tbb::task_group others;
    for (std::size_t i = 1; i < count; ++i) others.run(region.wrap([&make, i] { make(i); }));
    make(0);
    others.wait();
    region.join();
  }
  for (std::size_t i = 0; i < count; ++i) {
    if (errors[i]) std::rethrow_exception(errors[i]);
  }
  for (std::size_t i = 0; i < count; ++i) {
    model.report.field_reused = model.report.field_reused && reports[i].field_reused;
    for (auto& t : reports[i].timings_s) model.report.timings_s.push_back(std::move(t));
    for (auto& w : reports[i].warnings) model.report.warnings.push_back(std::move(w));
    model.lungs.push_back(std::move(*made[i]));
    // Where the scan cut a lung flat, its surface is not the pleura: said also on a cached field
    // (the label map is read for it then).
    LungModel& lung = model.lungs.back();
    lung.label_map_edges = surfaces.edges_touched(i);
    if (!lung.label_map_edges.empty()) {
      model.report.warnings.push_back(fmt::format(
          "{}: the {}lung touches the label map's edge at its {} (the scan cuts it flat there, not anatomy)",
          surfaces.input_file(i).string(), lung.side ? scenario::lung_name(lung.side) + std::string(" ") : "",
          fmt::join(lung.label_map_edges, ", ")));
    }
  }
  if (options.interior) {
    model.label_map = surfaces.label_map();  // the rest label map, for the voxel outputs (read once)
    // The body's narrowest blur is chosen for the breath the lungs follow (body_motion.h): its
    // ends are each lung's lowest and highest scales. A drive the lungs cannot follow gives none
    // (the run then stops naming the frame, Model::scales, before any output asks the body).
    const auto start = Clock::now();
    BodyMotionOptions body_options;
    if (options.drive) {
      try {
        for (const LungScales& lung : model.scales(*options.drive))
          body_options.scale_range.push_back({lung.min_scale, lung.max_scale});
      } catch (const UnsupportedError&) {
        body_options.scale_range.clear();
      }
    }
    // Kept beside the field cache (`cache: auto`) for a run into the same folder.
    std::filesystem::path lookup, save_to;
    if (s.field.cache == scenario::FieldCache::automatic && !options.auto_cache_file.empty()) {
      lookup = options.auto_cache_file.parent_path() / kBodyFieldCacheFile;
      save_to = options.auto_cache_write_file.empty()
                    ? lookup
                    : options.auto_cache_write_file.parent_path() / kBodyFieldCacheFile;
    }
    model.body = body_motion_cached(model, body_options, lookup, save_to);
    model.report.timings_s.emplace_back("body field", seconds_since(start));
  }
  return model;
}

}  // namespace pneuma::model
