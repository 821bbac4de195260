#include "pneuma/mesh/source/surface_source.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>

#include "pneuma/core/error.h"
#include "pneuma/core/fresh_pages.h"
#include "pneuma/core/parallel.h"
#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/mesh/geometry/validate.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "pneuma/mesh/labels/labels.h"
#include "pneuma/mesh/repair/remesh.h"
#include "pneuma/mesh/repair/repair.h"

namespace pneuma::mesh {
namespace {

// Refuses a remeshing target `edge_m` that would make a surface of `area_m2` larger than
// kMaxSurfaceVertices, before any of it is made. An area far beyond a lung's (about 0.1 m2)
// is most often a file in millimetres read as metres: the message says so.
void check_surface_size(const SurfaceSourceSpec& where, double area_m2, double edge_m) {
  if (!(edge_m > 0.0)) return;  // not remeshed
  const double vertices = vertex_count_at_edge(area_m2, edge_m);
  if (vertices <= kMaxSurfaceVertices) return;
  const std::string unit_hint =
      area_m2 > 10.0 ? fmt::format("; {:.4g} m2 is not the area of a lung (about 0.1 m2): is mesh.unit right?", area_m2)
                     : std::string();
  throw InputError(
      fmt::format("{}: {}: a surface of {:.4g} m2 at an edge of {:.4g} mm would have about {:.3g} vertices; "
                  "expected at most {:.0f} (a coarser edge){}",
                  where.origin, where.edge_key, area_m2, edge_m * 1e3, vertices, kMaxSurfaceVertices, unit_hint));
}

TriangleMesh phantom_surface(Lung side, double edge_m) {
  PhantomOptions phantom;
  phantom.lung = side;
  phantom.edge_length_m = edge_m;
  return make_lung_phantom(phantom);
}

RemeshOptions remesh_options(double edge_m) {
  RemeshOptions remesh;
  remesh.target_edge_length_m = edge_m;
  return remesh;
}

TriangleMesh remeshed(TriangleMesh surface, double edge_m) {
  if (edge_m <= 0.0) return surface;
  return remesh_isotropic(surface, remesh_options(edge_m)).mesh;
}

// Two lungs from one label map: where they touch (26-neighbour voxels), both lose those voxels,
// so that their surfaces, each extracted and remeshed alone, keep a gap of about two voxels and
// do not cut into each other at rest (they did on case007 at 4 mm). Only the contact band goes:
// a few mL at most, against litres. The band is symmetric (a voxel of either lung with a neighbour
// of the other), so the map is the same whichever lung is `one`.
image::LabelMap separated_lungs(const image::LabelMap& map, const std::vector<int>& one,
                                const std::vector<int>& other) {
  auto in = [](const std::vector<int>& values, std::int32_t label) {
    return std::find(values.begin(), values.end(), label) != values.end();
  };
  // Plain names, not a structured binding: the lambdas below capture them.
  const std::size_t nx = map.size[0], ny = map.size[1], nz = map.size[2];
  const std::size_t slice = nx * ny;
  // Each voxel's side as a bit (1: `one`, 2: `other`), and `near`, the bits of its 3 x 3
  // neighbours in its slice (ORed along x, then along y); a voxel of one side touches the other
  // where the bits of `near` in its own slice and the two beside it hold the other's. Slice by
  // slice on every core (#50), each slice writing its own: the same map at any thread count.
  // Fresh buffers mapped on every core first (core/fresh_pages.h): at the label map's own grid
  // they are 70-280 MB each.
  std::vector<std::uint8_t> side, near;
  core::resize_mapped(side, map.labels.size());
  core::resize_mapped(near, map.labels.size());
  core::for_each_index(
      nz,
      [&](std::size_t k) {
        const std::size_t start = k * slice;
        std::int32_t last = map.labels[start];
        std::uint8_t last_side = in(one, last) ? 1 : (in(other, last) ? 2 : 0);
        for (std::size_t v = start; v < start + slice; ++v) {
          if (map.labels[v] != last) last = map.labels[v], last_side = in(one, last) ? 1 : (in(other, last) ? 2 : 0);
          side[v] = last_side;
        }
        std::vector<std::uint8_t> along_x(slice);
        for (std::size_t j = 0; j < ny; ++j) {
          const std::uint8_t* row = side.data() + start + j * nx;
          std::uint8_t* out = along_x.data() + j * nx;
          for (std::size_t i = 0; i < nx; ++i)
            out[i] = row[i] | (i > 0 ? row[i - 1] : 0) | (i + 1 < nx ? row[i + 1] : 0);
        }
        for (std::size_t j = 0; j < ny; ++j) {
          const std::uint8_t* row = along_x.data() + j * nx;
          const std::uint8_t* below = j > 0 ? row - nx : nullptr;
          const std::uint8_t* above = j + 1 < ny ? row + nx : nullptr;
          std::uint8_t* out = near.data() + start + j * nx;
          for (std::size_t i = 0; i < nx; ++i) out[i] = row[i] | (below ? below[i] : 0) | (above ? above[i] : 0);
        }
      },
      1);
  // The separated map written in one pass from the read one (not a copy of it edited after: the
  // copy was a serial 283 MB memmove at case004's own grid).
  image::LabelMap out;
  out.size = map.size;
  out.ijk_to_lps = map.ijk_to_lps;
  out.transform_source = map.transform_source;
  out.segments = map.segments;
  core::resize_mapped(out.labels, map.labels.size());
  core::for_each_index(
      nz,
      [&](std::size_t k) {
        const std::size_t start = k * slice;
        for (std::size_t v = start; v < start + slice; ++v) {
          const std::uint8_t around =
              side[v] == 0 ? 0 : near[v] | (k > 0 ? near[v - slice] : 0) | (k + 1 < nz ? near[v + slice] : 0);
          out.labels[v] = (around & ~side[v]) != 0 ? 0 : map.labels[v];
        }
      },
      1);
  return out;
}

bool contains(const std::vector<int>& values, int value) {
  return std::find(values.begin(), values.end(), value) != values.end();
}

}  // namespace

SurfaceSource::SurfaceSource(SurfaceSourceSpec spec) : spec_(std::move(spec)) {
  const bool named =
      std::any_of(spec_.lungs.begin(), spec_.lungs.end(), [](const auto& l) { return !l.label_names.empty(); });
  if (!named) return;
  // Segment names given for a lung (`values: [lung_upper_lobe_left, ...]`) become the label map's
  // values for them, added to the numbers given.
  const std::shared_ptr<const image::LabelMap> map = label_map();
  for (LungSource& lung : spec_.lungs) {
    if (lung.label_names.empty()) continue;
    std::vector<int> values;
    try {
      values = image::resolve_labels(*map, spec_.labels_file.filename().string(), lung.label_names);
    } catch (const ValueError& e) {
      throw InputError(fmt::format("{}: {}: {}", spec_.origin, lung.label_key, e.what()));
    }
    for (const int value : values) {
      if (!contains(lung.label_values, value)) lung.label_values.push_back(value);
    }
    lung.label_names.clear();
  }
  if (two_lungs()) {
    for (const int value : spec_.lungs[0].label_values) {
      if (contains(spec_.lungs[1].label_values, value))
        throw InputError(fmt::format("{}: {}: label {} is in both lungs", spec_.origin, spec_.lungs_key, value));
    }
  }
}

const std::filesystem::path& SurfaceSource::input_file(std::size_t i) const {
  static const std::filesystem::path none;
  if (is_phantom(i)) return none;
  return from_labels() ? spec_.labels_file : spec_.lungs[i].file;
}

std::string SurfaceSource::key_text(std::size_t i) const {
  const std::vector<int>& values = spec_.lungs[i].label_values;
  std::string text =
      fmt::format("{} unit {:.17g} m, repair {}, edge {:.17g} m, labels {}", from_labels() ? "labels" : "file",
                  spec_.metres_per_unit, spec_.repair, spec_.edge_m, fmt::join(values, ","));
  if (two_lungs() && !spec_.lungs[1 - i].label_values.empty())
    text += fmt::format(", apart from {}", fmt::join(spec_.lungs[1 - i].label_values, ","));
  // The facet size it is meshed at (a field cached before that size followed the edge is not
  // taken for one made now).
  if (from_labels()) text += fmt::format(", meshed at {:.17g} m", extraction_edge_m(spec_.edge_m));
  return text;
}

std::shared_ptr<const image::LabelMap> SurfaceSource::label_map() const {
  if (!from_labels()) return nullptr;
  tbb::collaborative_call_once(
      map_once_, [this] { map_ = std::make_shared<const image::LabelMap>(image::read_label_map(spec_.labels_file)); });
  return map_;
}

std::shared_ptr<const image::LabelMap> SurfaceSource::separated_map() const {
  const std::shared_ptr<const image::LabelMap> map = label_map();
  tbb::collaborative_call_once(separated_once_, [&] {
    separated_ = std::make_shared<const image::LabelMap>(
        separated_lungs(*map, spec_.lungs[0].label_values, spec_.lungs[1].label_values));
  });
  return separated_;
}

std::vector<std::string> SurfaceSource::edges_touched(std::size_t i) const {
  if (!from_labels()) return {};
  const image::LabelMap& map = *label_map();
  const std::vector<int>& values = spec_.lungs[i].label_values;
  const auto& n = map.size;
  std::vector<std::string> faces;
  for (std::size_t axis = 0; axis < 3; ++axis) {
    // The LPS direction of index axis `axis`, named by its largest component: +x left, +y
    // posterior, +z superior.
    const Eigen::Vector3d along = map.ijk_to_lps.block<3, 1>(0, static_cast<Eigen::Index>(axis));
    Eigen::Index major = 0;
    along.cwiseAbs().maxCoeff(&major);
    static constexpr std::array<std::array<const char*, 2>, 3> kSides{
        {{"right", "left"}, {"anterior", "posterior"}, {"inferior", "superior"}}};
    const std::size_t a = (axis + 1) % 3, b = (axis + 2) % 3;
    for (const bool last : {false, true}) {
      const std::size_t at = last ? n[axis] - 1 : 0;
      bool touches = false;
      for (std::size_t u = 0; u < n[a] && !touches; ++u) {
        for (std::size_t v = 0; v < n[b] && !touches; ++v) {
          std::array<std::size_t, 3> ijk{};
          ijk[axis] = at;
          ijk[a] = u;
          ijk[b] = v;
          touches = contains(values, map.labels[ijk[0] + n[0] * (ijk[1] + n[1] * ijk[2])]);
        }
      }
      // The first slice faces away from the axis' direction, the last along it.
      const bool positive = (along[major] > 0.0) == last;
      if (touches)
        faces.push_back(fmt::format("{} face ({} = {})", kSides[static_cast<std::size_t>(major)][positive ? 1 : 0],
                                    "ijk"[axis], at));
    }
  }
  return faces;
}

TriangleMesh SurfaceSource::original_surface(std::size_t i) const {
  ReadOptions read;
  read.metres_per_unit = spec_.metres_per_unit;
  read.unit_from_file = spec_.unit_from_file;
  TriangleMesh surface = read_mesh(spec_.lungs[i].file, read);
  if (spec_.repair) surface = repair_or_throw(surface, spec_.lungs[i].file.string());
  return surface;
}

// A file with a remeshing target is repaired, remeshed, and only then judged: remeshing removes
// slivers repair left. A label map is extracted at the target up to 4 mm (extraction_edge_m;
// 2 mm for a coarser one) and remeshed to it.
TriangleMesh SurfaceSource::surface(std::size_t i) const {
  const LungSource& lung = spec_.lungs[i];
  const double edge_m = spec_.edge_m;
  if (lung.phantom) {
    check_surface_size(spec_, surface_area(phantom_surface(*lung.phantom, 0.01)), edge_m);
    return phantom_surface(*lung.phantom, edge_m);
  }
  if (from_labels()) {
    LabelSurfaceOptions extract;
    extract.edge_length_m = extraction_edge_m(edge_m);
    const std::shared_ptr<const image::LabelMap> map = label_map();
    // A lung of two is extracted from the map with the contact band removed (its messages name
    // the file, where one lung's name the path).
    TriangleMesh surface =
        !two_lungs()
            ? surface_from_labels(*map, spec_.labels_file.string(), lung.label_values, extract).mesh
            : surface_from_labels(*separated_map(), spec_.labels_file.filename().string(), lung.label_values, extract)
                  .mesh;
    check_surface_size(spec_, surface_area(surface), edge_m);
    return remeshed(std::move(surface), edge_m);
  }
  ReadOptions read;
  read.metres_per_unit = spec_.metres_per_unit;
  read.unit_from_file = spec_.unit_from_file;
  TriangleMesh surface = read_mesh(lung.file, read);
  require_lung_sized(lung.file.string(), surface, "mesh.unit");
  check_surface_size(spec_, surface_area(surface), edge_m);
  if (!spec_.repair) return remeshed(std::move(surface), edge_m);
  if (edge_m <= 0.0) return repair_or_throw(surface, lung.file.string());
  return repair_and_remesh(surface, lung.file.string(), {}, remesh_options(edge_m)).remesh.mesh;
}

}  // namespace pneuma::mesh
