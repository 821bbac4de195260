#include "pneuma/model/compile.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cstdio>

#include "pneuma/core/error.h"
#include "pneuma/core/stopwatch.h"
#include "pneuma/field/tissue.h"
#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/mesh/geometry/deformed_surface.h"
#include "pneuma/mesh/geometry/surface_queries.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "pneuma/mesh/labels/labels.h"
#include "pneuma/mesh/repair/remesh.h"
#include "pneuma/mesh/repair/repair.h"
#include "pneuma/model/field_cache.h"

namespace pneuma::model {
namespace {

using scenario::MeshSpec;
using scenario::Scenario;

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

// The field of the scenario's surface, from the cache where it holds one for these inputs.
// A file mesh is looked up by its bytes and the options that shape it before it is repaired and
// remeshed, so a cache hit pays for neither.
CacheLookup scenario_field(const Scenario& s, double edge_m, const std::filesystem::path& output_dir) {
  const field::Tissue& tissue = s.field.tissue;
  const field::FieldOptions& given = s.field.options;
  const bool from_source = !s.mesh.phantom;
  if (s.field.cache == scenario::FieldCache::off) {
    const mesh::TriangleMesh surface = from_source ? source_surface(s.mesh, edge_m) : phantom_surface(s.mesh, edge_m);
    const field::TissueFieldInputs inputs = field::tissue_field_inputs(surface, tissue, given);
    return {compute_field_record(surface, inputs), false, {}, inputs.options.regions};
  }
  const std::filesystem::path cache =
      s.field.cache == scenario::FieldCache::file ? s.field.cache_file : output_dir / "field.h5";
  if (!from_source) return load_or_compute(cache, phantom_surface(s.mesh, edge_m), tissue, given);
  const bool labels = !s.mesh.labels_file.empty();
  const std::string source =
      source_key({labels ? s.mesh.labels_file : s.mesh.file, s.field.tissue_file},
                 fmt::format("{} unit {:.17g} m, repair {}, edge {:.17g} m, labels {}", labels ? "labels" : "file",
                             s.mesh.metres_per_unit, s.mesh.repair, edge_m, fmt::join(s.mesh.label_values, ",")));
  std::shared_ptr<const mesh::SurfaceRegions> regions;
  CacheLookup lookup = load_or_compute(cache, source_field_key(source, tissue.name, given), [&] {
    const mesh::TriangleMesh surface = source_surface(s.mesh, edge_m);
    const field::TissueFieldInputs inputs = field::tissue_field_inputs(surface, tissue, given);
    regions = inputs.options.regions;
    return compute_field_record(surface, inputs);
  });
  lookup.regions = std::move(regions);
  return lookup;
}

// The model of the scenario: its surface and field (cached), moved onto the original file's
// vertices where the scenario exports those.
Model scenario_model(const Scenario& s, const CompileOptions& options, bool& field_reused,
                     std::vector<std::pair<std::string, double>>& timings_s) {
  auto start = Clock::now();
  const double edge = options.edge_override_m.value_or(s.mesh.edge_m);
  CacheLookup computed = scenario_field(s, edge, options.output_dir);
  field_reused = computed.reused;
  if (!computed.discarded.empty()) {
    // The cache is derived data: a damaged one is replaced, never used, and the user told.
    std::fprintf(stderr, "pneuma: warning: %s; computed the field again and replaced the file\n",
                 computed.discarded.c_str());
  }
  timings_s.emplace_back(field_reused ? "mesh and field (cached)" : "mesh and field", seconds_since(start));

  mesh::TriangleMesh rest = std::move(computed.record.rest);
  std::vector<Eigen::Vector3d> u = std::move(computed.record.unit_displacement);
  if (s.mesh.export_original) {
    // The field lives on the remeshed surface; carry it to the original vertices through their
    // closest points on it (barycentric interpolation).
    start = Clock::now();
    mesh::TriangleMesh original = file_surface(s.mesh);
    u = mesh::transfer_vertex_field(rest, u, original.vertices);
    rest = std::move(original);
    timings_s.emplace_back("field transfer", seconds_since(start));
  }
  // The field's regions are the rest surface's unless the run exports the original mesh.
  const mesh::SurfaceRegions* regions = s.mesh.export_original ? nullptr : computed.regions.get();
  return make_model(std::move(rest), std::move(u), s.field.options.area_unit, field::body_axes(s.field.tissue),
                    regions);
}

// One CGAL check of the most deformed frames: a self-intersecting surface is refused.
void check_no_fold(const Model& model, const Scenario& s, double min_scale, double max_scale) {
  mesh::DeformedSurface kernel(model.rest.vertices, model.unit_displacement, model.rest.triangles);
  mesh::TriangleMesh deformed{std::vector<Eigen::Vector3d>(model.rest.vertex_count()), model.rest.triangles};
  for (double extreme : {min_scale, max_scale}) {
    kernel.update(extreme, deformed.vertices);
    if (mesh::self_intersects(deformed)) {
      throw UnsupportedError(fmt::format("{}: the surface self-intersects at scale {:.4g} (mesh volume {:.4g} L); "
                                         "lower the tidal volume or the mesh share",
                                         s.file.string(), extreme, model.volume_map.volume(extreme) * 1e3));
    }
  }
}

}  // namespace

std::vector<double> frame_scales(const Model& model, const MeshSpec& mesh, const std::vector<double>& time_s,
                                 const std::vector<double>& lung_volume_m3) {
  std::vector<double> scales(time_s.size());
  const double rest_volume = model.volume_map.volume(0.0);
  double guess = 0.0;
  for (std::size_t k = 0; k < time_s.size(); ++k) {
    const double target = rest_volume + mesh.share * (lung_volume_m3[k] - mesh.reference_volume_m3);
    try {
      scales[k] = guess = model.volume_map.scale_for(target, guess);
    } catch (const UnsupportedError& e) {
      throw UnsupportedError(
          fmt::format("frame {} (t = {:.3f} s): {}; lower the tidal volume or the mesh share", k, time_s[k], e.what()));
    }
  }
  return scales;
}

Compiled compile(const Scenario& s, const physiology::SimulationResult& drive, const CompileOptions& options) {
  bool field_reused = false;
  std::vector<std::pair<std::string, double>> timings_s;
  Model model = scenario_model(s, options, field_reused, timings_s);
  std::vector<double> scales = frame_scales(model, s.mesh, drive.series.time_s, drive.series.volume_m3);
  double min_scale = 0.0, max_scale = 0.0;
  if (!scales.empty()) {
    const auto [lo, hi] = std::minmax_element(scales.begin(), scales.end());
    min_scale = *lo;
    max_scale = *hi;
  }
  const auto start = Clock::now();
  check_no_fold(model, s, min_scale, max_scale);
  timings_s.emplace_back("self-intersection check", seconds_since(start));
  return Compiled{std::move(model), std::move(scales), min_scale, max_scale, field_reused, std::move(timings_s)};
}

}  // namespace pneuma::model
