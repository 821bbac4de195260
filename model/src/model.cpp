#include "pneuma/model/model.h"
#include "pneuma/model/no_fold_record.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <string_view>

#include "pneuma/core/error.h"
#include "pneuma/core/keyed_file.h"
#include "pneuma/core/sha256.h"
#include "pneuma/mesh/geometry/deformed_surface.h"
#include "pneuma/mesh/geometry/surface_queries.h"
#include "pneuma/scenario/scenario.h"

namespace pneuma::model {
namespace {

// A lung's surface at scale s.
mesh::TriangleMesh deformed_surface(const LungModel& lung, double scale) {
  mesh::DeformedSurface kernel(lung.rest.vertices, lung.unit_displacement, lung.rest.triangles);
  mesh::TriangleMesh out{std::vector<Eigen::Vector3d>(lung.rest.vertex_count()), lung.rest.triangles};
  kernel.update(scale, out.vertices);
  return out;
}

// One CGAL check of the most deformed frames: a self-intersecting surface is refused, and so are
// two lungs that cut into each other (both at their lowest scales, then both at their highest:
// end-expiration and end-inspiration).
}  // namespace

void check_no_fold(const Model& model, std::span<const LungScales> scales) {
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
                                           model.scenario_file.string(), which, extreme,
                                           lung.volume_map.volume(extreme) * 1e3));
      }
    }
  }
  if (!model.two_lungs()) return;
  for (const bool highest : {false, true}) {
    const std::array<double, 2> at{highest ? scales[0].max_scale : scales[0].min_scale,
                                   highest ? scales[1].max_scale : scales[1].min_scale};
    // Each lung alone is free of self-intersections (above): an intersection is between them, so
    // only the right lung's faces are tested against the left's (not each lung's own again).
    if (mesh::surfaces_intersect(deformed_surface(model.lungs[0], at[0]), deformed_surface(model.lungs[1], at[1]))) {
      throw UnsupportedError(fmt::format("{}: the right and left lungs intersect each other at their {} scales "
                                         "({:.4g}, {:.4g}); lower the tidal volume or the lungs' shares",
                                         model.scenario_file.string(), highest ? "highest" : "lowest", at[0], at[1]));
    }
  }
}

namespace {
constexpr std::string_view kNoFoldMagic = "pneuma-no-fold 1";
// Part of the key: raise it when check_no_fold() changes what it refuses.
constexpr std::string_view kNoFoldRule = "each lung at its lowest and highest scale, then the two lungs; 1";
}  // namespace

std::string no_fold_key(const Model& model, std::span<const LungScales> scales) {
  if (scales.size() != model.lungs.size())
    throw ValueError(fmt::format("no_fold_key: {} scale ranges for {} lungs", scales.size(), model.lungs.size()));
  core::Sha256 h;
  h.update(kNoFoldMagic.data(), kNoFoldMagic.size()).update(kNoFoldRule.data(), kNoFoldRule.size());
  const auto count = static_cast<std::uint64_t>(model.lungs.size());
  h.update(&count, sizeof count);
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    const LungModel& lung = model.lungs[i];
    const std::array<std::uint64_t, 3> sizes{lung.rest.vertices.size(), lung.rest.triangles.size(),
                                             lung.unit_displacement.size()};
    h.update(sizes.data(), sizeof sizes);
    h.update(lung.rest.vertices.data(), lung.rest.vertices.size() * sizeof(Eigen::Vector3d));
    h.update(lung.rest.triangles.data(), lung.rest.triangles.size() * sizeof(mesh::Triangle));
    h.update(lung.unit_displacement.data(), lung.unit_displacement.size() * sizeof(Eigen::Vector3d));
    const std::array<double, 2> ends{scales[i].min_scale, scales[i].max_scale};
    h.update(ends.data(), sizeof ends);
  }
  return core::to_hex(h.finish());
}

bool check_no_fold(const Model& model, std::span<const LungScales> scales, const NoFoldRecord& record) {
  if (record.lookup.empty() && record.save_to.empty()) {
    check_no_fold(model, scales);
    return false;
  }
  const std::string key = no_fold_key(model, scales);
  std::string discarded;  // a damaged file is checked again and replaced: nothing to say
  const bool passed_before =
      !record.lookup.empty() && core::load_keyed_file(record.lookup, kNoFoldMagic, key, discarded).has_value();
  if (!passed_before) check_no_fold(model, scales);  // throws where it fails: nothing is kept then
  if (!record.save_to.empty()) core::save_keyed_file(record.save_to, kNoFoldMagic, key, {});
  return passed_before;
}

const std::vector<double>& LungModel::volumes(const physiology::SimulationResult& drive) const {
  return lung_volumes(drive, compartment);
}

const std::vector<double>& lung_volumes(const physiology::SimulationResult& drive, int compartment) {
  if (compartment < 0) return drive.series.volume_m3;
  const auto c = static_cast<std::size_t>(compartment);
  if (c >= drive.series.compartment_volume_m3.size())
    throw ValueError(fmt::format("lung_volumes: the drive has no compartment {}", c));
  return drive.series.compartment_volume_m3[c];
}

std::vector<double> LungModel::scales(const std::vector<double>& time_s,
                                      const std::vector<double>& lung_volume_m3) const {
  std::vector<double> out(time_s.size());
  const double rest_volume = volume_map.volume(0.0);
  double guess = 0.0;
  for (std::size_t k = 0; k < time_s.size(); ++k) {
    const double target = rest_volume + share * (lung_volume_m3[k] - reference_volume_m3);
    try {
      out[k] = guess = volume_map.scale_for(target, guess);
    } catch (const UnsupportedError& e) {
      throw UnsupportedError(
          fmt::format("frame {} (t = {:.3f} s): {}; lower the tidal volume or the mesh share", k, time_s[k], e.what()));
    }
  }
  return out;
}

std::vector<LungScales> Model::scales(const physiology::SimulationResult& drive) const {
  std::vector<LungScales> out;
  for (const LungModel& lung : lungs) {
    LungScales l;
    try {
      l.scales = lung.scales(drive.series.time_s, lung.volumes(drive));
    } catch (const UnsupportedError& e) {
      if (!two_lungs()) throw;
      throw UnsupportedError(fmt::format("the {} lung: {}", scenario::lung_name(lung.side), e.what()));
    }
    if (!l.scales.empty()) {
      const auto [lo, hi] = std::minmax_element(l.scales.begin(), l.scales.end());
      l.min_scale = *lo;
      l.max_scale = *hi;
    }
    out.push_back(std::move(l));
  }
  return out;
}

std::size_t Model::vertex_count() const {
  std::size_t n = 0;
  for (const LungModel& lung : lungs) n += lung.rest.vertex_count();
  return n;
}

std::size_t Model::triangle_count() const {
  std::size_t n = 0;
  for (const LungModel& lung : lungs) n += lung.rest.triangle_count();
  return n;
}

LungModel make_model(mesh::TriangleMesh rest, std::vector<Eigen::Vector3d> unit_displacement, double area_unit_m2,
                     const mesh::BodyAxes& axes, const mesh::SurfaceRegions* known_regions,
                     std::optional<mesh::Lung> side) {
  if (known_regions) mesh::require_regions_of(*known_regions, rest, axes, "make_model");
  // Regions found from the geometry name a side; a lung of a two-lung model knows its own.
  if (known_regions && side && known_regions->side != *side) known_regions = nullptr;
  std::vector<Eigen::Vector3d> normals = mesh::vertex_normals(rest);
  VolumeScaleMap map(rest.vertices, unit_displacement, rest.triangles);
  const double area = mesh::surface_area(rest);
  mesh::RegionOptions region_options;
  region_options.axes = axes;
  region_options.side = side;
  mesh::SurfaceRegions regions = known_regions ? *known_regions : mesh::find_regions(rest, region_options);
  LungModel lung{std::move(rest),
                 std::move(normals),
                 area,
                 std::move(regions),
                 std::move(unit_displacement),
                 area_unit_m2,
                 map,
                 side};
  return lung;
}

}  // namespace pneuma::model
