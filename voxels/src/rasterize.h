#pragma once
// Private to voxels/: tets onto a voxel grid, each voxel to one tet by a fixed rule.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Core>
#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/core/fresh_pages.h"
#include "pneuma/core/tsan.h"
#include "pneuma/mesh/geometry/tet_mesh.h"
#include "pneuma/voxels/dvf.h"
#include "pneuma/voxels/grid.h"

namespace pneuma::voxels::detail {

// One lung's tets with the node positions to rasterise them at (rest or deformed), LPS metres.
struct TetSet {
  std::span<const mesh::Tetrahedron> tets;
  std::span<const Eigen::Vector3d> nodes;
};

inline constexpr std::size_t kSlabVoxels = 4;  // k-slices per parallel task

// The lungs' tets at rest, each lung checked (check_lung_motion), at most 255 of them (a voxel's
// owner is a byte). Throws ValueError.
inline std::vector<TetSet> rest_tet_sets(std::span<const LungMotion> lungs) {
  if (lungs.size() > 255) throw ValueError(std::to_string(lungs.size()) + " lungs: expected at most 255");
  std::vector<TetSet> sets;
  sets.reserve(lungs.size());
  for (const LungMotion& lung : lungs) {
    check_lung_motion(lung);
    sets.push_back({lung.mesh.tets, lung.mesh.nodes});
  }
  return sets;
}

// s sum l_c U_c: the lung's displacement at barycentric coordinates `l` of its tet `t` (the
// forward field there; the pull-back field of the deformed tet is its negative).
inline Eigen::Vector3d tet_displacement(const LungMotion& lung, std::size_t t, const Eigen::Vector4d& l) {
  const mesh::Tetrahedron& tet = lung.mesh.tets[t];
  Eigen::Vector3d u = Eigen::Vector3d::Zero();
  for (std::size_t c = 0; c < 4; ++c) u += l[static_cast<Eigen::Index>(c)] * lung.unit_displacement_m[tet[c]];
  return lung.scale * u;
}

// Calls visit(voxel, set, tet, l, i, j, k) once for every voxel whose centre lies in the closed
// simplex of some tet (barycentric coordinates l >= -kBarycentricTolerance), for the first set
// and in it the lowest tet holding it, and empty(voxel, i, j, k) once for every other voxel (from
// the same task, after its slab's tets, in index order, i fastest: the outputs are first touched
// in parallel, and a voxel's row neighbour i - 1 is final when it is called). Sets `owner`
// per voxel to 0 (no tet) or 1 + the set's index (its storage reused).
// Parallel over slabs of k, each slab's tets in increasing order: the same result at any thread
// count. Degenerate tets (|6V| below 1e-12 of their bounding box's volume, in index space) hold
// no voxel.
template <typename Visit, typename Empty>
void rasterize(const Grid& grid, std::span<const TetSet> sets, std::vector<std::uint8_t>& owner, const Visit& visit,
               const Empty& empty) {
  const std::size_t nx = grid.size[0], ny = grid.size[1], nz = grid.size[2];
  core::assign_mapped(owner, grid.voxel_count(), std::uint8_t{0});
  if (owner.empty()) return;
  const Eigen::Matrix4d to_ijk = grid.lps_to_ijk();
  const Eigen::Matrix3d linear = to_ijk.block<3, 3>(0, 0);
  const Eigen::Vector3d offset = to_ijk.block<3, 1>(0, 3);
  constexpr double kPad = 1e-6;  // index units: the boxes are a little larger than the tets

  // The nodes in index space, each once (a node is a corner of about twenty tets, and each tet's
  // corners are read again by every slab it crosses: #50). The same arithmetic as per corner.
  std::vector<std::vector<Eigen::Vector3d>> ijk(sets.size());
  for (std::size_t s = 0; s < sets.size(); ++s) {
    ijk[s].resize(sets[s].nodes.size());
    const tsan::Region region;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, ijk[s].size(), 16384), region.wrap([&](const auto& r) {
      for (std::size_t n = r.begin(); n != r.end(); ++n) ijk[s][n] = linear * sets[s].nodes[n] + offset;
    }));
    region.join();
  }
  const auto corners = [&](std::size_t s, std::size_t t) {
    std::array<Eigen::Vector3d, 4> p;
    for (std::size_t c = 0; c < 4; ++c) p[c] = ijk[s][sets[s].tets[t][c]];
    return p;
  };

  // Tets by slab, in increasing (set, tet) order.
  std::vector<std::size_t> first_tet(sets.size() + 1, 0);
  for (std::size_t s = 0; s < sets.size(); ++s) first_tet[s + 1] = first_tet[s] + sets[s].tets.size();
  const std::size_t tet_count = first_tet.back();
  std::vector<std::array<std::int64_t, 2>> slab_range(tet_count, {1, 0});
  for (std::size_t s = 0; s < sets.size(); ++s) {
    const tsan::Region region;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, sets[s].tets.size(), 4096), region.wrap([&](const auto& r) {
      for (std::size_t t = r.begin(); t != r.end(); ++t) {
        const auto p = corners(s, t);
        Eigen::Vector3d lo = p[0], hi = p[0];
        for (const auto& q : p) lo = lo.cwiseMin(q), hi = hi.cwiseMax(q);
        // A tet beside the grid along i or j holds none of its voxels (the bounds of the voxel
        // loops below): no slab gets it. A thin grid (report.html's one-voxel planes) then
        // visits only the tets that cross it.
        const double i0 = std::max(0.0, std::ceil(lo.x() - kPad));
        const double i1 = std::min(static_cast<double>(nx - 1), std::floor(hi.x() + kPad));
        const double j0 = std::max(0.0, std::ceil(lo.y() - kPad));
        const double j1 = std::min(static_cast<double>(ny - 1), std::floor(hi.y() + kPad));
        const double k0 = std::max(0.0, std::ceil(lo.z() - kPad));
        const double k1 = std::min(static_cast<double>(nz - 1), std::floor(hi.z() + kPad));
        if (!(i0 <= i1) || !(j0 <= j1) || !(k0 <= k1)) continue;  // outside the grid (or not finite)
        const auto slab = static_cast<double>(kSlabVoxels);
        slab_range[first_tet[s] + t] = {static_cast<std::int64_t>(std::floor(k0 / slab)),
                                        static_cast<std::int64_t>(std::floor(k1 / slab))};
      }
    }));
    region.join();
  }
  const std::size_t slabs = (nz + kSlabVoxels - 1) / kSlabVoxels;
  std::vector<std::size_t> slab_start(slabs + 1, 0);
  for (const auto& r : slab_range)
    for (std::int64_t b = r[0]; b <= r[1]; ++b) ++slab_start[static_cast<std::size_t>(b) + 1];
  for (std::size_t b = 0; b < slabs; ++b) slab_start[b + 1] += slab_start[b];
  std::vector<std::uint32_t> slab_tets(slab_start.back());
  {
    std::vector<std::size_t> fill(slab_start.begin(), slab_start.end() - 1);
    for (std::size_t g = 0; g < tet_count; ++g)
      for (std::int64_t b = slab_range[g][0]; b <= slab_range[g][1]; ++b)
        slab_tets[fill[static_cast<std::size_t>(b)]++] = static_cast<std::uint32_t>(g);
  }

  const tsan::Region region;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, slabs, 1), region.wrap([&](const auto& r) {
    for (std::size_t b = r.begin(); b != r.end(); ++b) {
      const double slab_k0 = static_cast<double>(b * kSlabVoxels);
      const double slab_k1 = static_cast<double>(std::min(nz, (b + 1) * kSlabVoxels) - 1);
      std::size_t s = 0;
      for (std::size_t e = slab_start[b]; e < slab_start[b + 1]; ++e) {
        const std::size_t g = slab_tets[e];
        while (g >= first_tet[s + 1]) ++s;
        const std::size_t t = g - first_tet[s];
        const auto p = corners(s, t);
        Eigen::Vector3d lo = p[0], hi = p[0];
        for (const auto& q : p) lo = lo.cwiseMin(q), hi = hi.cwiseMax(q);
        Eigen::Matrix3d edges;
        edges << p[1] - p[0], p[2] - p[0], p[3] - p[0];
        const double det = edges.determinant();
        const Eigen::Vector3d box = hi - lo;
        if (!(std::abs(det) > 1e-12 * box.prod()) || !std::isfinite(det)) continue;
        const Eigen::Matrix3d to_bary = edges.inverse();
        const double k_lo = std::max(slab_k0, std::ceil(lo.z() - kPad));
        const double k_hi = std::min(slab_k1, std::floor(hi.z() + kPad));
        const double j_lo = std::max(0.0, std::ceil(lo.y() - kPad));
        const double j_hi = std::min(static_cast<double>(ny - 1), std::floor(hi.y() + kPad));
        const double i_box_lo = std::max(0.0, std::ceil(lo.x() - kPad));
        const double i_box_hi = std::min(static_cast<double>(nx - 1), std::floor(hi.x() + kPad));
        for (double kd = k_lo; kd <= k_hi; kd += 1.0) {
          for (double jd = j_lo; jd <= j_hi; jd += 1.0) {
            // l123(i) = to_bary ((0, j, k) - p0) + i to_bary.col(0); l0 = 1 - sum: the i
            // where all four are >= -tol, widened a little; each voxel is then tested itself.
            const Eigen::Vector3d base = to_bary * (Eigen::Vector3d(0.0, jd, kd) - p[0]);
            const Eigen::Vector4d c(1.0 - base.sum(), base.x(), base.y(), base.z());
            const Eigen::Vector4d slope(-to_bary.col(0).sum(), to_bary(0, 0), to_bary(1, 0), to_bary(2, 0));
            double i_lo = i_box_lo, i_hi = i_box_hi;
            for (int m = 0; m < 4; ++m) {
              if (slope[m] > 0.0) {
                i_lo = std::max(i_lo, std::ceil((-kBarycentricTolerance - c[m]) / slope[m] - kPad));
              } else if (slope[m] < 0.0) {
                i_hi = std::min(i_hi, std::floor((-kBarycentricTolerance - c[m]) / slope[m] + kPad));
              } else if (c[m] < -kBarycentricTolerance) {
                i_hi = i_lo - 1.0;
              }
            }
            const auto j = static_cast<std::size_t>(jd), k = static_cast<std::size_t>(kd);
            for (double id = i_lo; id <= i_hi; id += 1.0) {
              const auto i = static_cast<std::size_t>(id);
              const std::size_t v = i + nx * (j + ny * k);
              if (owner[v] != 0) continue;
              const Eigen::Vector3d l123 = to_bary * (Eigen::Vector3d(id, jd, kd) - p[0]);
              const Eigen::Vector4d l(1.0 - l123.sum(), l123.x(), l123.y(), l123.z());
              if (!(l.minCoeff() >= -kBarycentricTolerance)) continue;
              owner[v] = static_cast<std::uint8_t>(s + 1);
              visit(v, s, t, l, i, j, k);
            }
          }
        }
      }
      for (auto k = static_cast<std::size_t>(slab_k0); k <= static_cast<std::size_t>(slab_k1); ++k)
        for (std::size_t j = 0; j < ny; ++j)
          for (std::size_t i = 0; i < nx; ++i) {
            const std::size_t v = i + nx * (j + ny * k);
            if (owner[v] == 0) empty(v, i, j, k);
          }
    }
  }));
  region.join();
}

// rasterize(grid, rest sets, owner, visit, empty) through `rest` (RestRaster): replayed when it
// holds this grid and these lungs, else rasterised and kept there. visit(voxel, set, tet, l)
// (without i, j, k); empty as rasterize's, after each slab's lung voxels, in index order. The same
// calls with the same arguments either way (in another order within a slab's lung voxels).
template <typename Visit, typename Empty>
void rasterize_rest(const Grid& grid, std::span<const LungMotion> lungs, RestRaster& rest,
                    std::vector<std::uint8_t>& owner, const Visit& visit, const Empty& empty) {
  const std::size_t nx = grid.size[0], ny = grid.size[1], nz = grid.size[2];
  const std::size_t slabs = (nz + kSlabVoxels - 1) / kSlabVoxels;
  if (rest.holds(grid, lungs)) {
    owner = rest.owner;
    const tsan::Region region;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, slabs, 1), region.wrap([&](const auto& r) {
      for (std::size_t b = r.begin(); b != r.end(); ++b) {
        for (const RestRaster::Entry& e : rest.slabs[b]) {
          const Eigen::Vector4d l(1.0 - e.l123.sum(), e.l123.x(), e.l123.y(), e.l123.z());  // as rasterize()
          visit(std::size_t{e.voxel}, std::size_t{owner[e.voxel]} - 1u, std::size_t{e.tet}, l);
        }
        for (std::size_t k = b * kSlabVoxels; k < std::min(nz, (b + 1) * kSlabVoxels); ++k)
          for (std::size_t j = 0; j < ny; ++j)
            for (std::size_t i = 0; i < nx; ++i) {
              const std::size_t v = i + nx * (j + ny * k);
              if (owner[v] == 0) empty(v, i, j, k);
            }
      }
    }));
    region.join();
    return;
  }
  const std::vector<TetSet> sets = rest_tet_sets(lungs);
  // Kept only where a voxel's index fits the entry (4 G voxels).
  const bool keep = grid.voxel_count() <= std::size_t{0xffffffffu};
  rest.grid = Grid{};  // not valid until complete (an exception leaves it empty)
  rest.tets.clear();
  rest.nodes.clear();
  rest.slabs.assign(keep ? slabs : 0, {});
  rasterize(
      grid, std::span<const TetSet>(sets), owner,
      [&](std::size_t v, std::size_t s, std::size_t t, const Eigen::Vector4d& l, std::size_t, std::size_t,
          std::size_t k) {
        visit(v, s, t, l);
        if (keep)
          rest.slabs[k / kSlabVoxels].push_back(
              {static_cast<std::uint32_t>(v), static_cast<std::uint32_t>(t), Eigen::Vector3d(l[1], l[2], l[3])});
      },
      empty);
  if (!keep) return;
  for (std::vector<RestRaster::Entry>& slab : rest.slabs) slab.shrink_to_fit();
  rest.owner = owner;
  for (const LungMotion& lung : lungs) {
    rest.tets.emplace_back(lung.mesh.tets.begin(), lung.mesh.tets.end());
    rest.nodes.emplace_back(lung.mesh.nodes.begin(), lung.mesh.nodes.end());
  }
  rest.grid = grid;
}

// The rest tets rasterised through `rest` where one is given (rasterize_rest), else afresh
// (rasterize): visit(voxel, set, tet, l) and empty as rasterize_rest's, the same calls either way.
template <typename Visit, typename Empty>
void rasterize_rest_tets(const Grid& grid, std::span<const LungMotion> lungs, RestRaster* rest,
                         std::vector<std::uint8_t>& owner, const Visit& visit, const Empty& empty) {
  if (rest != nullptr) {
    rasterize_rest(grid, lungs, *rest, owner, visit, empty);
    return;
  }
  const std::vector<TetSet> sets = rest_tet_sets(lungs);
  rasterize(
      grid, std::span<const TetSet>(sets), owner,
      [&](std::size_t v, std::size_t s, std::size_t t, const Eigen::Vector4d& l, std::size_t, std::size_t,
          std::size_t) { visit(v, s, t, l); },
      empty);
}

// The value of a voxel that no tet holds: outside(x), or 0. rasterize() calls this in row order
// after the slab's tets, so voxels v - 1 and v - 2 (same row) are final when they are outside too.
inline void set_outside(DisplacementField& field, const OutsideField& outside, std::size_t v, std::size_t i,
                        std::size_t j, std::size_t k) {
  if (!outside) {
    field.displacement_m[v] = Eigen::Vector3f::Zero();
    return;
  }
  const bool has_previous = i > 0 && field.lung[v - 1] == 0;
  const bool has_two = has_previous && i > 1 && field.lung[v - 2] == 0;
  Eigen::Vector3d guess = Eigen::Vector3d::Zero();
  if (has_previous) guess = field.displacement_m[v - 1].cast<double>();
  if (has_two) guess = 2.0 * guess - field.displacement_m[v - 2].cast<double>();
  field.displacement_m[v] = outside(field.grid.centre_m(i, j, k), has_previous ? &guess : nullptr).cast<float>();
}

}  // namespace pneuma::voxels::detail
