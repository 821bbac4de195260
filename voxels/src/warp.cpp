// Pulling label maps and images back through a pull-back DVF, in parallel over k (each output
// voxel computed on its own: the same bytes at any thread count).
#include "pneuma/voxels/warp.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/core/fresh_pages.h"
#include "pneuma/core/tsan.h"

namespace pneuma::voxels {
namespace {

// Calls f(out voxel, continuous index of x + v(x) in `source`) for every voxel of the field.
template <typename F>
void for_each_sample(const DisplacementField& field, const Grid& source, const F& f) {
  const Grid& grid = field.grid;
  const Eigen::Matrix4d to_source = source.lps_to_ijk();
  const Eigen::Matrix3d linear = to_source.block<3, 3>(0, 0);
  const Eigen::Vector3d offset = to_source.block<3, 1>(0, 3);
  const tsan::Region region;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, grid.size[2]), region.wrap([&](const auto& r) {
    for (std::size_t k = r.begin(); k != r.end(); ++k)
      for (std::size_t j = 0; j < grid.size[1]; ++j)
        for (std::size_t i = 0; i < grid.size[0]; ++i) {
          const std::size_t v = grid.index(i, j, k);
          const Eigen::Vector3d y = grid.centre_m(i, j, k) + field.displacement_m[v].cast<double>();
          f(v, Eigen::Vector3d(linear * y + offset));
        }
  }));
  region.join();
}

// The voxel on `side` of the pleura (rest_lung == side) nearest to the continuous index q, looked
// for ring by ring (cubes of growing half-width around q's nearest voxel) up to kFarthestRing:
// the nearest by distance in the first ring that holds one, the first in k, j, i order on a tie.
// For a voxel whose pull-back lands more than half a voxel across the pleura: the body field
// lags the pleura by its 12 mm blur (docs/voxels.md, "Around the lungs"), which a lung that
// deflates below its scan leaves as a gap of several voxels between its moved and its rest
// surface (docs/voxels.md, "The scan's place on the breath").
constexpr long kFarthestRing = 16;

// A corner with less of the trilinear weight than this does not count for the tissue rule: a
// sample that close to a voxel centre is on it (a NIfTI CT's float32 affine moves the samples of a
// zero field by about 1e-6 voxel, which would otherwise pick a neighbour of the other tissue).
constexpr double kNegligibleWeight = 1e-4;

// The index of the voxel nearest to the continuous index q in a grid of `size`, if q rounds to
// one inside it (a q that is not finite rounds to none).
std::optional<std::size_t> nearest_voxel(const Eigen::Vector3d& q, const std::array<std::size_t, 3>& size) {
  std::array<std::size_t, 3> at{};
  for (std::size_t a = 0; a < 3; ++a) {
    // floor(x) lies in [0, n) exactly where x does (n a whole number), and is x truncated there:
    // no floor() per axis and voxel (SSE2 has no rounding instruction; #50).
    const double x = q[static_cast<Eigen::Index>(a)] + 0.5;
    if (!(x >= 0.0 && x < static_cast<double>(size[a]))) return std::nullopt;
    at[a] = static_cast<std::size_t>(static_cast<std::int64_t>(x));
  }
  return at[0] + size[0] * (at[1] + size[1] * at[2]);
}

// Calls f(index, weight, corner) for each of the eight voxels around the continuous index q that
// lie inside a grid of `size` (corner by corner, i fastest): its index, its trilinear weight at q
// and its own continuous index.
template <typename F>
void for_each_corner(const Eigen::Vector3d& q, const std::array<std::size_t, 3>& size, const F& f) {
  for (int corner = 0; corner < 8; ++corner) {
    double weight = 1.0;
    Eigen::Vector3d c;
    bool inside = true;
    for (Eigen::Index a = 0; a < 3; ++a) {
      const double base = std::floor(q[a]);
      const double t = q[a] - base;
      const bool up = ((corner >> a) & 1) != 0;
      c[a] = base + (up ? 1.0 : 0.0);
      weight *= up ? t : 1.0 - t;
      inside = inside && c[a] >= 0.0 && c[a] < static_cast<double>(size[static_cast<std::size_t>(a)]);
    }
    if (!inside) continue;
    f(static_cast<std::size_t>(c[0]) +
          size[0] * (static_cast<std::size_t>(c[1]) + size[1] * static_cast<std::size_t>(c[2])),
      weight, c);
  }
}

// `takes(index)`: whether a voxel on `side` may be taken (the label warp refuses lung labels outside
// every lung); every voxel on the side where it is not given.
template <typename Takes>
std::optional<std::size_t> nearest_on_side(const std::vector<std::uint8_t>& rest_lung,
                                           const std::array<std::size_t, 3>& size, const Eigen::Vector3d& q,
                                           std::uint8_t side, const Takes& takes) {
  std::array<long, 3> centre{}, n{};
  for (std::size_t a = 0; a < 3; ++a) {
    centre[a] = static_cast<long>(std::floor(q[static_cast<Eigen::Index>(a)] + 0.5));
    n[a] = static_cast<long>(size[a]);
  }
  for (long ring = 1; ring <= kFarthestRing; ++ring) {
    double best = std::numeric_limits<double>::infinity();
    std::optional<std::size_t> found;
    for (long k = std::max(centre[2] - ring, 0L); k <= std::min(centre[2] + ring, n[2] - 1); ++k)
      for (long j = std::max(centre[1] - ring, 0L); j <= std::min(centre[1] + ring, n[1] - 1); ++j)
        for (long i = std::max(centre[0] - ring, 0L); i <= std::min(centre[0] + ring, n[0] - 1); ++i) {
          const long chebyshev = std::max({std::abs(i - centre[0]), std::abs(j - centre[1]), std::abs(k - centre[2])});
          if (chebyshev != ring) continue;  // inner rings were searched already
          const auto index = static_cast<std::size_t>(i + n[0] * (j + n[1] * k));
          if (rest_lung[index] != side || !takes(index)) continue;
          const double d = (Eigen::Vector3d(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k)) - q)
                               .squaredNorm();
          if (d < best) best = d, found = index;
        }
    if (found) return found;
  }
  return std::nullopt;
}

std::optional<std::size_t> nearest_on_side(const std::vector<std::uint8_t>& rest_lung,
                                           const std::array<std::size_t, 3>& size, const Eigen::Vector3d& q,
                                           std::uint8_t side) {
  return nearest_on_side(rest_lung, size, q, side, [](std::size_t) { return true; });
}

}  // namespace

image::LabelMap warp_labels(const image::LabelMap& labels, const DisplacementField& pullback,
                            const std::vector<std::uint8_t>* rest_lung, std::span<const int> lung_labels) {
  image::LabelMap out;
  warp_labels(labels, pullback, out, rest_lung, lung_labels);
  return out;
}

namespace {

// warp_labels' label at voxel v of the field, whose x + v(x) is at continuous index q of `labels`.
auto label_rule(const image::LabelMap& labels, const DisplacementField& pullback,
                const std::vector<std::uint8_t>* rest_lung, std::span<const int> lung_labels) {
  return [&labels, &pullback, rest_lung, lung_labels](std::size_t v, const Eigen::Vector3d& q) {
    const std::optional<std::size_t> rounded = nearest_voxel(q, labels.size);
    if (!rounded) {  // outside the label map (or not finite)
      return std::int32_t{0};
    }
    std::size_t nearest = *rounded;
    const std::uint8_t lung = pullback.lung[v];
    // Outside every deformed lung, a voxel carried across the pleura is the body's: it takes the
    // body's own nearest tissue, never the lobe map's lung rim outside the rest mesh (a lung
    // deflating below its scan leaves a gap the lagging body field pulls back into the rest lung,
    // and the rim's lung labels filled it: docs/voxels.md, "The warped lung below the scan").
    // Only where x + v(x) itself lies in a rest mesh (its eight voxels' trilinear share of the
    // rest meshes above one half): a voxel just outside the pleura whose nearest voxel is inside
    // (grids that do not coincide, a zero field) keeps the rim's label, as the label map has it.
    bool carried_in = false;
    if (rest_lung && lung == 0 && !lung_labels.empty() && (*rest_lung)[nearest] != 0) {
      double share = 0.0;
      for_each_corner(q, labels.size, [&](std::size_t candidate, double weight, const Eigen::Vector3d&) {
        if ((*rest_lung)[candidate] != 0) share += weight;
      });
      carried_in = share > 0.5;
    }
    const auto takes = [&](std::size_t index) {
      return !carried_in ||
             std::find(lung_labels.begin(), lung_labels.end(), labels.labels[index]) == lung_labels.end();
    };
    if (rest_lung && (*rest_lung)[nearest] != lung) {
      // The nearest of the eight voxels around q on x's side of the pleura: inside this lung's
      // rest mesh, or (x outside every deformed lung: tissue the body field carries) outside
      // every rest mesh and not lung.
      double best = std::numeric_limits<double>::infinity();
      for_each_corner(q, labels.size, [&](std::size_t candidate, double, const Eigen::Vector3d& c) {
        const double d = (c - q).squaredNorm();
        if ((*rest_lung)[candidate] == lung && takes(candidate) && d < best) {
          best = d;
          nearest = candidate;
        }
      });
      if (std::isinf(best)) {
        if (const auto far = nearest_on_side(*rest_lung, labels.size, q, lung, takes)) {
          nearest = *far;
        } else if (carried_in) {  // otherwise `takes` refused nothing: the search above was this one
          if (const auto any = nearest_on_side(*rest_lung, labels.size, q, lung)) {
            nearest = *any;  // no tissue of the body near: its side as before
          }
        }
      }
    }
    return labels.labels[nearest];
  };
}

void check_labels_warp(const image::LabelMap& labels, const std::vector<std::uint8_t>* rest_lung) {
  if (rest_lung && rest_lung->size() != labels.labels.size()) {
    throw ValueError("warp_labels: the rest lungs' voxels are not those of the label map");
  }
}

void labels_like(const image::LabelMap& labels, const DisplacementField& pullback, image::LabelMap& out) {
  out.size = pullback.grid.size;
  out.ijk_to_lps = pullback.grid.ijk_to_lps;
  out.transform_source = labels.transform_source;
  out.segments = labels.segments;
  core::resize_mapped(out.labels, pullback.grid.voxel_count());
}

}  // namespace

void warp_labels(const image::LabelMap& labels, const DisplacementField& pullback, image::LabelMap& out,
                 const std::vector<std::uint8_t>* rest_lung, std::span<const int> lung_labels) {
  check_labels_warp(labels, rest_lung);
  labels_like(labels, pullback, out);
  const auto rule = label_rule(labels, pullback, rest_lung, lung_labels);
  for_each_sample(pullback, grid_of(labels),
                  [&](std::size_t v, const Eigen::Vector3d& q) { out.labels[v] = rule(v, q); });
}

Image warp_image(const Image& image, const DisplacementField& pullback, float outside,
                 const std::vector<std::uint8_t>* rest_lung, const Tissue& tissue) {
  Image out;
  warp_image(image, pullback, out, outside, rest_lung, tissue);
  return out;
}

namespace {

// A voxel's eight trilinear corners in `image`, corner by corner (i fastest): each one's weight
// (the product of its axes', i then j then k) and index.
struct Corners {
  std::array<double, 8> weight{};
  std::array<std::size_t, 8> index{};
};

// Every corner with a weight blended: the value without the rest lungs (and their last resort).
double blended(const Image& image, const Corners& corners) {
  double value = 0.0;
  for (std::size_t corner = 0; corner < 8; ++corner) {
    if (corners.weight[corner] == 0.0) continue;
    value += corners.weight[corner] * static_cast<double>(image.values[corners.index[corner]]);
  }
  return value;
}

// image_rule's value where the corners are not all on x's side and of x's tissue (the pleura,
// a tissue's edge): out of line, so that the loop keeps the short way's registers. With the rest
// lungs, only the corners on x's side of the pleura count (renormalised): the tissue at x is that
// side's, and the pleura slides, so nothing is blended across it. With the tissue masks, a corner
// must show x's tissue as well; where none of those with kNegligibleWeight or more does, the
// corners on x's side as without them (so that a zero field gives the image back where the warped
// label map and the image's own disagree).
[[gnu::noinline]] float across_corners(const Image& image, const Corners& corners, const Eigen::Vector3d& q,
                                       std::uint8_t side, std::uint8_t lung_tissue,
                                       const std::vector<std::uint8_t>& rest_lung,
                                       const std::vector<std::uint8_t>* rest_tissue) {
  double same_side_value = 0.0, same_side_weight = 0.0, same_tissue_value = 0.0, same_tissue_weight = 0.0;
  for (std::size_t corner = 0; corner < 8; ++corner) {
    const double weight = corners.weight[corner];
    if (weight == 0.0) continue;
    const std::size_t c = corners.index[corner];
    if (rest_lung[c] != side) continue;
    const double at = static_cast<double>(image.values[c]);
    same_side_value += weight * at;
    same_side_weight += weight;
    if (rest_tissue != nullptr && weight >= kNegligibleWeight && (*rest_tissue)[c] == lung_tissue) {
      same_tissue_value += weight * at;
      same_tissue_weight += weight;
    }
  }
  if (same_tissue_weight > 0.0) {
    return static_cast<float>(same_tissue_value / same_tissue_weight);
  }
  if (same_side_weight == 0.0) {
    // Every corner across the pleura: the nearest voxel on x's side, where there is one.
    if (const auto far = nearest_on_side(rest_lung, image.grid.size, q, side)) {
      return image.values[*far];
    }
    return static_cast<float>(blended(image, corners));
  }
  return static_cast<float>(same_side_value / same_side_weight);
}

// warp_image's value at voxel v of the field, whose x + v(x) is at continuous index q of `image`;
// `lung_tissue` the warped label map's tissue at v (Tissue::warped), read when `rest_tissue` is
// given (Tissue::rest).
auto image_rule(const Image& image, const DisplacementField& pullback, float outside,
                const std::vector<std::uint8_t>* rest_lung, const std::vector<std::uint8_t>* rest_tissue) {
  return [&image, &pullback, outside, rest_lung, rest_tissue ](std::size_t v, const Eigen::Vector3d& q,
                                                               std::uint8_t lung_tissue) __attribute__((always_inline))
      ->float {
    const std::array<std::size_t, 3> size = image.grid.size;
    std::array<std::size_t, 3> lo{}, hi{};
    std::array<double, 3> w{};
    for (std::size_t a = 0; a < 3; ++a) {
      const double top = static_cast<double>(size[a] - 1);
      const double c = q[static_cast<Eigen::Index>(a)];
      if (!(c >= -0.5 && c <= top + 0.5)) {  // outside the image (or not finite)
        return outside;
      }
      const double clamped = std::clamp(c, 0.0, top);
      // floor(clamped) as its truncation (clamped >= 0: the same value, without floor()).
      const double base = std::min(static_cast<double>(static_cast<std::int64_t>(clamped)), std::max(top - 1.0, 0.0));
      lo[a] = static_cast<std::size_t>(base);
      hi[a] = std::min(lo[a] + 1, size[a] - 1);
      w[a] = clamped - base;
    }
    // The eight corners' weights and indices from their axes' (the same products and sums as
    // weighting and indexing each corner whole: the same bits).
    const std::array<std::array<double, 2>, 3> wa{{{1.0 - w[0], w[0]}, {1.0 - w[1], w[1]}, {1.0 - w[2], w[2]}}};
    const std::array<std::array<std::size_t, 2>, 3> ia{
        {{lo[0], hi[0]}, {size[0] * lo[1], size[0] * hi[1]}, {size[0] * size[1] * lo[2], size[0] * size[1] * hi[2]}}};
    Corners corners;
    for (std::size_t corner = 0; corner < 8; ++corner) {
      const std::size_t a = corner & 1, b = (corner >> 1) & 1, c = (corner >> 2) & 1;
      corners.weight[corner] = wa[0][a] * wa[1][b] * wa[2][c];
      corners.index[corner] = ia[0][a] + ia[1][b] + ia[2][c];
    }
    if (!rest_lung) {
      return static_cast<float>(blended(image, corners));
    }
    const std::uint8_t side = pullback.lung[v];
    // The short way (#50): all eight corners on x's side and of x's tissue, as almost every voxel
    // away from the pleura and the tissues' edges is. across_corners then takes every corner
    // (with the tissue masks, those of kNegligibleWeight or more) in the same order with the same
    // products: the same bits here, without a branch per corner. A corner left out adds +0.0,
    // which changes no sum here (a sum of products from +0.0 is never -0.0).
    bool uniform = true;
    for (std::size_t corner = 0; corner < 8; ++corner) {
      uniform &= (*rest_lung)[corners.index[corner]] == side;
      if (rest_tissue != nullptr) uniform &= (*rest_tissue)[corners.index[corner]] == lung_tissue;
    }
    if (!uniform) {
      return across_corners(image, corners, q, side, lung_tissue, *rest_lung, rest_tissue);
    }
    double value = 0.0, weight = 0.0;
    for (std::size_t corner = 0; corner < 8; ++corner) {
      const double cw = corners.weight[corner];
      const bool counts = rest_tissue != nullptr ? cw >= kNegligibleWeight : cw != 0.0;
      value += counts ? cw * static_cast<double>(image.values[corners.index[corner]]) : 0.0;
      weight += counts ? cw : 0.0;
    }
    return static_cast<float>(value / weight);
  };
}

// The image's rest masks (either may be null) on the image's own grid; `who` names the caller.
void check_rest_masks(const char* who, const Image& image, const std::vector<std::uint8_t>* rest_lung,
                      const std::vector<std::uint8_t>* rest_tissue) {
  if (rest_lung && rest_lung->size() != image.values.size()) {
    throw ValueError(std::string(who) + ": the rest lungs' voxels are not those of the image");
  }
  if (rest_tissue && rest_tissue->size() != image.values.size()) {
    throw ValueError(std::string(who) + ": the tissue mask is not on the image's grid");
  }
}

// Whether the tissue masks are used (Tissue), after checking the inputs' sizes.
bool check_image_warp(const Image& image, const DisplacementField& pullback, const std::vector<std::uint8_t>* rest_lung,
                      const Tissue& tissue) {
  const bool by_tissue = rest_lung && tissue.rest && tissue.warped;
  check_rest_masks("warp_image", image, rest_lung, by_tissue ? tissue.rest : nullptr);
  if (by_tissue && tissue.warped->size() != pullback.grid.voxel_count()) {
    throw ValueError("warp_image: the warped tissue mask is not on the field's grid");
  }
  return by_tissue;
}

}  // namespace

void warp_image(const Image& image, const DisplacementField& pullback, Image& out, float outside,
                const std::vector<std::uint8_t>* rest_lung, const Tissue& tissue) {
  const bool by_tissue = check_image_warp(image, pullback, rest_lung, tissue);
  out.grid = pullback.grid;
  core::resize_mapped(out.values, pullback.grid.voxel_count());
  const auto rule = image_rule(image, pullback, outside, rest_lung, by_tissue ? tissue.rest : nullptr);
  for_each_sample(pullback, image.grid, [&](std::size_t v, const Eigen::Vector3d& q) {
    out.values[v] = rule(v, q, by_tissue ? (*tissue.warped)[v] : std::uint8_t{0});
  });
}

void warp_labels_and_image(const image::LabelMap& labels, const Image& image, const DisplacementField& pullback,
                           image::LabelMap& out_labels, Image& out_image, const std::vector<std::uint8_t>* rest_lung,
                           std::span<const int> lung_labels, float outside,
                           const std::vector<std::uint8_t>* image_rest_lung,
                           const std::vector<std::uint8_t>* image_rest_tissue) {
  const Grid source = grid_of(labels);
  if (image.grid.size != source.size || image.grid.ijk_to_lps != source.ijk_to_lps)
    throw ValueError("warp_labels_and_image: the image is not on the label map's grid");
  const bool by_tissue = image_rest_lung && image_rest_tissue;
  check_rest_masks("warp_labels_and_image", image, image_rest_lung, by_tissue ? image_rest_tissue : nullptr);
  check_labels_warp(labels, rest_lung);
  labels_like(labels, pullback, out_labels);
  out_image.grid = pullback.grid;
  core::resize_mapped(out_image.values, pullback.grid.voxel_count());
  const auto label = label_rule(labels, pullback, rest_lung, lung_labels);
  const auto value = image_rule(image, pullback, outside, image_rest_lung, by_tissue ? image_rest_tissue : nullptr);
  for_each_sample(pullback, source, [&](std::size_t v, const Eigen::Vector3d& q) {
    const std::int32_t l = label(v, q);
    out_labels.labels[v] = l;
    // The warped label map's tissue at v, as lung_tissue of it gives it.
    const bool lung = by_tissue && std::find(lung_labels.begin(), lung_labels.end(), l) != lung_labels.end();
    out_image.values[v] = value(v, q, lung ? std::uint8_t{1} : std::uint8_t{0});
  });
}

void lung_tissue(const image::LabelMap& labels, std::span<const int> lung_labels, const Grid& grid,
                 std::vector<std::uint8_t>& out) {
  if (grid.size == labels.size && grid.ijk_to_lps == labels.ijk_to_lps) {
    // The label map's own grid (a CT on it): each voxel's nearest is itself (the transform there
    // and back is the identity to rounding, far from half a voxel).
    lung_tissue(labels, lung_labels, out);
    return;
  }
  core::resize_mapped(out, grid.voxel_count());
  const Eigen::Matrix4d to_labels = grid_of(labels).lps_to_ijk() * grid.ijk_to_lps;
  const tsan::Region region;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, grid.size[2]), region.wrap([&](const auto& r) {
    for (std::size_t k = r.begin(); k != r.end(); ++k)
      for (std::size_t j = 0; j < grid.size[1]; ++j)
        for (std::size_t i = 0; i < grid.size[0]; ++i) {
          const Eigen::Vector4d q =
              to_labels * Eigen::Vector4d(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k), 1.0);
          const std::optional<std::size_t> nearest = nearest_voxel(q.head<3>(), labels.size);
          out[grid.index(i, j, k)] =
              nearest && std::find(lung_labels.begin(), lung_labels.end(), labels.labels[*nearest]) != lung_labels.end()
                  ? 1
                  : 0;
        }
  }));
  region.join();
}

void lung_tissue(const image::LabelMap& labels, std::span<const int> lung_labels, std::vector<std::uint8_t>& out) {
  core::resize_mapped(out, labels.labels.size());
  const tsan::Region region;
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, out.size(), std::size_t{1} << 16),
      region.wrap([&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t v = r.begin(); v != r.end(); ++v)
          out[v] = std::find(lung_labels.begin(), lung_labels.end(), labels.labels[v]) != lung_labels.end() ? 1 : 0;
      }));
  region.join();
}

}  // namespace pneuma::voxels
