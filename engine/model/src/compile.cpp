#include "pneuma/model/compile.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <span>

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

// Where a remeshing target came from, for messages: the scenario file and its key ("mesh.edge"),
// or the option ("--edge").
struct EdgeSource {
  std::string file;
  std::string key;
};

// Refuses a remeshing target `edge_m` that would make a surface of `area_m2` larger than
// mesh::kMaxSurfaceVertices, before any of it is made. An area far beyond a lung's (about 0.1 m2)
// is most often a file in millimetres read as metres: the message says so.
void check_surface_size(const EdgeSource& where, double area_m2, double edge_m) {
  if (!(edge_m > 0.0)) return;  // not remeshed
  const double vertices = mesh::vertex_count_at_edge(area_m2, edge_m);
  if (vertices <= mesh::kMaxSurfaceVertices) return;
  const std::string unit_hint =
      area_m2 > 10.0 ? fmt::format("; {:.4g} m2 is not the area of a lung (about 0.1 m2): is mesh.unit right?", area_m2)
                     : std::string();
  throw InputError(
      fmt::format("{}: {}: a surface of {:.4g} m2 at an edge of {:.4g} mm would have about {:.3g} vertices; "
                  "expected at most {:.0f} (a coarser edge){}",
                  where.file, where.key, area_m2, edge_m * 1e3, vertices, mesh::kMaxSurfaceVertices, unit_hint));
}

// Refuses a surface more than a metre across: not a lung (an adult's is about 0.3 m tall), but a
// file in millimetres read as metres or a damaged vertex far away, whose needle triangles
// remeshing would split for hours (a vertex of a damaged STL at z = 11 km; found by scripts/mutate).
void check_lung_extent(const std::filesystem::path& file, const mesh::TriangleMesh& surface) {
  if (surface.vertices.empty()) return;
  const auto [lo, hi] = mesh::bounding_box(surface.vertices);
  const Eigen::Vector3d size = hi - lo;
  Eigen::Index axis = 0;
  const double largest = size.maxCoeff(&axis);
  if (largest <= 1.0) return;
  throw InputError(fmt::format("{}: the surface spans {:.4g} m along {} ({:.4g} x {:.4g} x {:.4g} m); expected a lung, "
                               "at most 1 m across (is mesh.unit right, or a vertex damaged?)",
                               file.string(), largest, "xyz"[axis], size.x(), size.y(), size.z()));
}

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
mesh::TriangleMesh source_surface(const MeshSpec& spec, double edge_m, const EdgeSource& where) {
  if (!spec.labels_file.empty()) {
    mesh::LabelSurfaceOptions extract;
    if (edge_m > 0.0) extract.edge_length_m = std::min(edge_m, extract.edge_length_m);
    mesh::TriangleMesh surface = mesh::surface_from_labels(spec.labels_file, spec.label_values, extract).mesh;
    check_surface_size(where, mesh::surface_area(surface), edge_m);
    return remeshed(std::move(surface), edge_m);
  }
  mesh::TriangleMesh surface = read_file_mesh(spec);
  check_lung_extent(spec.file, surface);
  check_surface_size(where, mesh::surface_area(surface), edge_m);
  if (!spec.repair) return remeshed(std::move(surface), edge_m);
  if (edge_m <= 0.0) return mesh::repair_or_throw(surface, spec.file.string());
  return mesh::repair_and_remesh(surface, spec.file.string(), {}, remesh_options(edge_m)).remesh.mesh;
}

// Two lungs from one label map: where they touch (26-neighbour voxels), both lose those voxels,
// so that their surfaces, each extracted and remeshed alone, keep a gap of about two voxels and
// do not cut into each other at rest (they did on case007 at 4 mm). Only the contact band goes:
// a few mL at most, against litres.
mesh::LabelMap separated_lungs(mesh::LabelMap map, const std::vector<int>& one, const std::vector<int>& other) {
  auto in = [](const std::vector<int>& values, std::int32_t label) {
    return std::find(values.begin(), values.end(), label) != values.end();
  };
  const auto [nx, ny, nz] = map.size;
  std::vector<std::uint8_t> side(map.labels.size(), 0);  // 1: `one`, 2: `other`
  for (std::size_t v = 0; v < side.size(); ++v)
    side[v] = in(one, map.labels[v]) ? 1 : (in(other, map.labels[v]) ? 2 : 0);
  std::vector<std::size_t> contact;
  for (std::size_t k = 0; k < nz; ++k) {
    for (std::size_t j = 0; j < ny; ++j) {
      for (std::size_t i = 0; i < nx; ++i) {
        const std::size_t v = i + nx * (j + ny * k);
        if (side[v] == 0) continue;
        bool touches = false;
        for (int dk = -1; dk <= 1 && !touches; ++dk) {
          for (int dj = -1; dj <= 1 && !touches; ++dj) {
            for (int di = -1; di <= 1 && !touches; ++di) {
              const auto ii = static_cast<std::ptrdiff_t>(i) + di, jj = static_cast<std::ptrdiff_t>(j) + dj,
                         kk = static_cast<std::ptrdiff_t>(k) + dk;
              if (ii < 0 || jj < 0 || kk < 0 || ii >= static_cast<std::ptrdiff_t>(nx) ||
                  jj >= static_cast<std::ptrdiff_t>(ny) || kk >= static_cast<std::ptrdiff_t>(nz))
                continue;
              const std::uint8_t s = side[static_cast<std::size_t>(ii) +
                                          nx * (static_cast<std::size_t>(jj) + ny * static_cast<std::size_t>(kk))];
              touches = s != 0 && s != side[v];
            }
          }
        }
        if (touches) contact.push_back(v);
      }
    }
  }
  for (const std::size_t v : contact) map.labels[v] = 0;
  return map;
}

// One lung's surface source as a one-surface MeshSpec (the functions above read those fields).
MeshSpec lung_mesh_spec(const MeshSpec& mesh, const scenario::LungSpec& lung) {
  if (mesh.lungs.empty()) {
    MeshSpec one = mesh;  // with its segment names resolved (resolve_segment_names)
    one.label_values = lung.label_values;
    one.label_names.clear();
    return one;
  }
  MeshSpec one = mesh;
  one.lungs.clear();
  one.phantom.reset();
  if (lung.phantom) one.phantom = lung.side;
  one.file = lung.file;
  one.label_values = lung.label_values;
  one.label_names.clear();
  one.share = lung.share;
  return one;
}

// The field of one surface (`mesh`: one lung), from the cache file `cache` where it holds one
// for these inputs. A file mesh is looked up by its bytes and the options that shape it before
// it is repaired and remeshed, so a cache hit pays for neither.
CacheLookup surface_field(const Scenario& s, const MeshSpec& mesh, double edge_m, const EdgeSource& where,
                          const std::filesystem::path& cache, const std::filesystem::path& save_to,
                          const std::vector<int>& other_lung_labels) {
  const field::Tissue& tissue = s.field.tissue;
  const field::FieldOptions& given = s.field.options;
  const bool from_source = !mesh.phantom;
  if (!from_source) check_surface_size(where, mesh::surface_area(phantom_surface(mesh, 0.01)), edge_m);
  // A lung of two from one label map is extracted from the map with the contact band removed.
  auto source = [&] {
    if (other_lung_labels.empty()) return source_surface(mesh, edge_m, where);
    mesh::LabelSurfaceOptions extract;
    if (edge_m > 0.0) extract.edge_length_m = std::min(edge_m, extract.edge_length_m);
    const mesh::LabelMap map =
        separated_lungs(mesh::read_label_map(mesh.labels_file), mesh.label_values, other_lung_labels);
    mesh::TriangleMesh surface =
        mesh::surface_from_labels(map, mesh.labels_file.filename().string(), mesh.label_values, extract).mesh;
    check_surface_size(where, mesh::surface_area(surface), edge_m);
    return remeshed(std::move(surface), edge_m);
  };
  if (s.field.cache == scenario::FieldCache::off) {
    const mesh::TriangleMesh surface = from_source ? source() : phantom_surface(mesh, edge_m);
    const field::TissueFieldInputs inputs = field::tissue_field_inputs(surface, tissue, given);
    return {compute_field_record(surface, inputs), false, {}, inputs.options.regions};
  }
  if (!from_source) return load_or_compute(cache, phantom_surface(mesh, edge_m), tissue, given, save_to);
  const bool labels = !mesh.labels_file.empty();
  std::string options_text =
      fmt::format("{} unit {:.17g} m, repair {}, edge {:.17g} m, labels {}", labels ? "labels" : "file",
                  mesh.metres_per_unit, mesh.repair, edge_m, fmt::join(mesh.label_values, ","));
  if (!other_lung_labels.empty()) options_text += fmt::format(", apart from {}", fmt::join(other_lung_labels, ","));
  const std::string key = source_key({labels ? mesh.labels_file : mesh.file, s.field.tissue_file}, options_text);
  std::shared_ptr<const mesh::SurfaceRegions> regions;
  CacheLookup lookup = load_or_compute(
      cache, source_field_key(key, tissue.name, given),
      [&] {
        const mesh::TriangleMesh surface = source();
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
LungModel lung_model(const Scenario& s, const scenario::LungSpec& spec, const std::vector<int>& other_lung_labels,
                     bool two_lungs, const CompileOptions& options, bool& field_reused,
                     std::vector<std::pair<std::string, double>>& timings_s) {
  auto start = Clock::now();
  const MeshSpec mesh = lung_mesh_spec(s.mesh, spec);
  const double edge = options.edge_override_m.value_or(mesh.edge_m);
  // `cache: auto`: looked up in the output folder, written into the stage (a failed run leaves
  // the folder as it was). `cache: <file>`: the user's file, read and written in place.
  const bool automatic = s.field.cache != scenario::FieldCache::file;
  const std::filesystem::path cache =
      lung_cache_path(automatic ? options.output_dir / "field.h5" : s.field.cache_file, spec.side, two_lungs);
  const std::filesystem::path save_to = automatic && !options.stage_dir.empty()
                                            ? lung_cache_path(options.stage_dir / "field.h5", spec.side, two_lungs)
                                            : std::filesystem::path();
  const EdgeSource where{s.file.string(), options.edge_override_m ? "--edge" : "mesh.edge"};
  // The file the surface came from (the scenario's for a phantom), for what the field finds wrong
  // with it (an inward-oriented surface).
  const std::filesystem::path& source =
      !mesh.labels_file.empty() ? mesh.labels_file : (!mesh.file.empty() ? mesh.file : s.file);
  CacheLookup computed = [&] {
    try {
      return surface_field(s, mesh, edge, where, cache, save_to, other_lung_labels);
    } catch (const UnsupportedError& e) {
      const std::string what = e.what();
      if (!what.starts_with("mesh: ")) throw;
      throw UnsupportedError(source.string() + ": " + what.substr(6));
    }
  }();
  field_reused = computed.reused;
  if (!computed.discarded.empty()) {
    // The cache is derived data: a damaged one is replaced, never used, and the user told.
    std::fprintf(stderr, "pneuma: warning: %s; computed the field again and replaced the file\n",
                 computed.discarded.c_str());
  }
  const std::string what = two_lungs ? fmt::format(" ({} lung)", scenario::lung_name(spec.side)) : "";
  timings_s.emplace_back((field_reused ? "mesh and field (cached)" : "mesh and field") + what, seconds_since(start));

  // The inside, where an output needs it: kept in the field's cache file beside the field it
  // extends (on the cached surface, also where the run exports the original mesh).
  std::shared_ptr<const LungInterior> interior;
  if (options.interior) {
    start = Clock::now();
    const std::string key =
        interior_key(computed.record.metadata.key, s.field.interior_edge_m, s.field.interior, s.field.interior_mesher);
    const bool cached = computed.record.interior && computed.record.interior->key == key;
    if (cached) {
      interior = computed.record.interior;
    } else {
      std::shared_ptr<LungInterior> fresh =
          compute_interior(computed.record.rest, computed.record.unit_displacement, s.field.interior_edge_m,
                           s.field.interior, s.field.interior_mesher);
      fresh->key = key;
      interior = fresh;
      computed.record.interior = fresh;
      if (s.field.cache != scenario::FieldCache::off) save_field(save_to.empty() ? cache : save_to, computed.record);
    }
    timings_s.emplace_back((cached ? "interior (cached)" : "interior") + what, seconds_since(start));
  }

  mesh::TriangleMesh rest = std::move(computed.record.rest);
  std::vector<Eigen::Vector3d> u = std::move(computed.record.unit_displacement);
  if (mesh.export_original) {
    // The field lives on the remeshed surface; carry it to the original vertices through their
    // closest points on it (barycentric interpolation).
    start = Clock::now();
    mesh::TriangleMesh original = file_surface(mesh);
    u = mesh::transfer_vertex_field(rest, u, original.vertices);
    rest = std::move(original);
    timings_s.emplace_back("field transfer", seconds_since(start));
  }
  // The field's regions are the rest surface's unless the run exports the original mesh. A lung
  // of two has its side (one surface: the side found from its geometry, as before).
  const mesh::SurfaceRegions* regions = mesh.export_original ? nullptr : computed.regions.get();
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
  lung.reference_volume_m3 = s.mesh.reference_volume_m3;
  lung.compartment = spec.compartment;
  lung.label_values = spec.label_values;
  lung.interior = std::move(interior);
  return lung;
}

// The surface of every lung at scale s_i (one per lung), as one mesh (two lungs: both, the
// left's vertices after the right's).
mesh::TriangleMesh deformed_union(const Model& model, std::span<const double> scales) {
  mesh::TriangleMesh out;
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    const LungModel& lung = model.lungs[i];
    mesh::DeformedSurface kernel(lung.rest.vertices, lung.unit_displacement, lung.rest.triangles);
    std::vector<Eigen::Vector3d> positions(lung.rest.vertex_count());
    kernel.update(scales[i], positions);
    const auto offset = static_cast<std::uint32_t>(out.vertices.size());
    out.vertices.insert(out.vertices.end(), positions.begin(), positions.end());
    for (mesh::Triangle t : lung.rest.triangles) {
      for (auto& v : t) v += offset;
      out.triangles.push_back(t);
    }
  }
  return out;
}

// One CGAL check of the most deformed frames: a self-intersecting surface is refused, and so are
// two lungs that cut into each other (both at their lowest scales, then both at their highest:
// end-expiration and end-inspiration).
void check_no_fold(const Model& model, const Scenario& s, const std::vector<LungScales>& scales) {
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    const LungModel& lung = model.lungs[i];
    mesh::DeformedSurface kernel(lung.rest.vertices, lung.unit_displacement, lung.rest.triangles);
    mesh::TriangleMesh deformed{std::vector<Eigen::Vector3d>(lung.rest.vertex_count()), lung.rest.triangles};
    for (double extreme : {scales[i].min_scale, scales[i].max_scale}) {
      kernel.update(extreme, deformed.vertices);
      if (mesh::self_intersects(deformed)) {
        const std::string which =
            model.two_lungs() ? fmt::format("the {} lung", scenario::lung_name(lung.side)) : std::string("the surface");
        throw UnsupportedError(fmt::format("{}: {} self-intersects at scale {:.4g} (mesh volume {:.4g} L); "
                                           "lower the tidal volume or the mesh share",
                                           s.file.string(), which, extreme, lung.volume_map.volume(extreme) * 1e3));
      }
    }
  }
  if (!model.two_lungs()) return;
  for (const bool highest : {false, true}) {
    const std::array<double, 2> at{highest ? scales[0].max_scale : scales[0].min_scale,
                                   highest ? scales[1].max_scale : scales[1].min_scale};
    // Each lung alone is free of self-intersections (above): an intersection is between them.
    if (mesh::self_intersects(deformed_union(model, at))) {
      throw UnsupportedError(fmt::format("{}: the right and left lungs intersect each other at their {} scales "
                                         "({:.4g}, {:.4g}); lower the tidal volume or the lungs' shares",
                                         s.file.string(), highest ? "highest" : "lowest", at[0], at[1]));
    }
  }
}

}  // namespace

std::filesystem::path lung_cache_path(const std::filesystem::path& path, const std::optional<mesh::Lung>& side,
                                      bool two_lungs) {
  if (!two_lungs) return path;
  std::filesystem::path out = path;
  out.replace_filename(path.stem().string() + "-" + scenario::lung_name(side) + path.extension().string());
  return out;
}

const std::vector<double>& lung_volumes(const LungModel& lung, const physiology::SimulationResult& drive) {
  if (lung.compartment < 0) return drive.series.volume_m3;
  const auto c = static_cast<std::size_t>(lung.compartment);
  if (c >= drive.series.compartment_volume_m3.size())
    throw ValueError(fmt::format("lung_volumes: the drive has no compartment {}", c));
  return drive.series.compartment_volume_m3[c];
}

std::vector<double> frame_scales(const LungModel& lung, const std::vector<double>& time_s,
                                 const std::vector<double>& lung_volume_m3) {
  std::vector<double> scales(time_s.size());
  const double rest_volume = lung.volume_map.volume(0.0);
  double guess = 0.0;
  for (std::size_t k = 0; k < time_s.size(); ++k) {
    const double target = rest_volume + lung.share * (lung_volume_m3[k] - lung.reference_volume_m3);
    try {
      scales[k] = guess = lung.volume_map.scale_for(target, guess);
    } catch (const UnsupportedError& e) {
      throw UnsupportedError(
          fmt::format("frame {} (t = {:.3f} s): {}; lower the tidal volume or the mesh share", k, time_s[k], e.what()));
    }
  }
  return scales;
}

// Segment names given for a lung (`values: [lung_upper_lobe_left, ...]`) become the label map's
// values for them, added to the numbers given; a name the map does not hold, or one lung's
// label reached by name from the other, is an InputError naming the scenario and the key.
void resolve_segment_names(const Scenario& s, std::vector<scenario::LungSpec>& specs) {
  const bool named = std::any_of(specs.begin(), specs.end(), [](const auto& l) { return !l.label_names.empty(); });
  if (!named) return;
  const mesh::LabelMap map = mesh::read_label_map(s.mesh.labels_file);
  for (scenario::LungSpec& lung : specs) {
    if (lung.label_names.empty()) continue;
    const std::string key =
        specs.size() == 2 ? fmt::format("mesh.lungs.{}", scenario::lung_name(*lung.side)) : "mesh.values";
    std::vector<int> values;
    try {
      values = mesh::resolve_labels(map, s.mesh.labels_file.filename().string(), lung.label_names);
    } catch (const ValueError& e) {
      throw InputError(fmt::format("{}: {}: {}", s.file.string(), key, e.what()));
    }
    for (const int value : values) {
      if (std::find(lung.label_values.begin(), lung.label_values.end(), value) == lung.label_values.end())
        lung.label_values.push_back(value);
    }
    lung.label_names.clear();
  }
  if (specs.size() == 2) {
    if (const auto value = scenario::label_in_both_lungs(specs[0], specs[1]))
      throw InputError(fmt::format("{}: mesh.lungs: label {} is in both lungs", s.file.string(), *value));
  }
}

Compiled compile(const Scenario& s, const physiology::SimulationResult& drive, const CompileOptions& options) {
  Compiled compiled;
  compiled.field_reused = true;
  std::vector<scenario::LungSpec> specs = scenario::lung_specs(s.mesh);
  resolve_segment_names(s, specs);
  for (std::size_t i = 0; i < specs.size(); ++i) {
    bool reused = false;
    // Two lungs of one label map: each extracted apart from the other's labels.
    const std::vector<int> other = specs.size() == 2 ? specs[1 - i].label_values : std::vector<int>{};
    compiled.model.lungs.push_back(
        lung_model(s, specs[i], other, specs.size() == 2, options, reused, compiled.timings_s));
    compiled.field_reused = compiled.field_reused && reused;
  }
  for (const LungModel& lung : compiled.model.lungs) {
    LungScales l;
    try {
      l.scales = frame_scales(lung, drive.series.time_s, lung_volumes(lung, drive));
    } catch (const UnsupportedError& e) {
      if (!compiled.model.two_lungs()) throw;
      throw UnsupportedError(fmt::format("the {} lung: {}", scenario::lung_name(lung.side), e.what()));
    }
    if (!l.scales.empty()) {
      const auto [lo, hi] = std::minmax_element(l.scales.begin(), l.scales.end());
      l.min_scale = *lo;
      l.max_scale = *hi;
    }
    compiled.lungs.push_back(std::move(l));
  }
  if (options.interior) {
    compiled.model.body = std::make_shared<const BodyMotion>(compiled.model);
  }
  const auto start = Clock::now();
  check_no_fold(compiled.model, s, compiled.lungs);
  compiled.timings_s.emplace_back("self-intersection check", seconds_since(start));
  return compiled;
}

}  // namespace pneuma::model
