#include "pneuma/field/untangle.h"

#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <utility>

#include "fixed_blocks.h"
#include "pneuma/core/error.h"

namespace pneuma::field {
namespace {

// The breaths, as fractions of `scale`, at which the star of a moved node is kept unfolded (the
// Jacobian is cubic in s, so a map unfolded at the deepest breath can fold at a lighter one).
constexpr std::array<double, 8> kFractions{0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875, 1.0};

// How far a move for a deeper breath may lower a lighter one's Jacobian, at the fraction f of
// `scale`: not at all up to half of it (quiet breaths keep the elastic field's inside), then
// down to the floor at the whole of it.
double lighter_floor(double f, double min_jacobian) {
  return f <= 0.5 ? 1.0 : 1.0 - (1.0 - min_jacobian) * (2.0 * f - 1.0);
}

// The mirror of lighter_floor: how far a move may raise the largest Jacobian in the star at its own
// breath or a lighter one: to twice the rest volume (the no-tear check's pull-back J of 1/2) up to
// half of `scale`, to 1 / the floor beyond. Without it a move that lifts a compressed tet stretched
// the tet across the node instead: on the phantom the moves for 1 L left J = 2-3 inside a 500 mL
// breath, 3.5-14 mm inside the base (#45 at 2 mm voxels; docs/voxels.md, "The phantom's interior
// tears at 2 mm, diagnosed").
constexpr double kQuietCeiling = 2.0;
double lighter_ceiling(double f, double min_jacobian) {
  return std::max(kQuietCeiling, 1.0 / lighter_floor(f, min_jacobian));
}

// Whether tet `q` folds at one of the breaths checked up to `scale`.
bool folds_by(const mesh::TetMesh& mesh, const mesh::Tetrahedron& q, const std::vector<Eigen::Vector3d>& displacement,
              double scale) {
  return std::any_of(kFractions.begin(), kFractions.end(), [&](double fraction) {
    return mesh::deformed_volume6(mesh, q, displacement, fraction * scale) <= 0.0;
  });
}

// One tetrahedron's Jacobian as an affine function of one node's deformed position p:
// J(p) = a . p + b (its deformed volume over its rest volume).
struct AffineJacobian {
  Eigen::Vector3d a;
  double b = 0.0;
};

// The Jacobian of (p0, p1, p2, p3) with node `k` replaced by p, as a . p + b: the signed volume
// is affine in any one node, so four evaluations give it exactly (to rounding).
AffineJacobian affine_in_node(std::array<Eigen::Vector3d, 4> p, std::size_t k, double rest_volume6) {
  auto volume6 = [&] { return mesh::tet_volume6(p[0], p[1], p[2], p[3]); };
  const Eigen::Vector3d at = p[k];
  const double here = volume6();
  Eigen::Vector3d a;
  for (int d = 0; d < 3; ++d) {
    p[k] = at + Eigen::Vector3d::Unit(d) * 1e-3;  // 1 mm: the size of the moves sought
    a(d) = (volume6() - here) / 1e-3;
  }
  return {a / rest_volume6, (here - a.dot(at)) / rest_volume6};
}

// The vertex of max over p of min over i of (a_i . p + b_i) where the four constraints `rows`
// are active: x = (p, t). False when they do not meet in one point.
bool vertex_of(const std::vector<AffineJacobian>& f, const std::array<std::size_t, 4>& rows, Eigen::Vector4d& x,
               Eigen::Matrix4d& inverse) {
  Eigen::Matrix4d a;
  Eigen::Vector4d rhs;
  for (int r = 0; r < 4; ++r) {
    const AffineJacobian& g = f[rows[static_cast<std::size_t>(r)]];
    a.row(r) << g.a.x(), g.a.y(), g.a.z(), -1.0;
    rhs(r) = -g.b;
  }
  double determinant = 0.0;
  bool invertible = false;
  a.computeInverseAndDetWithCheck(inverse, determinant, invertible, 1e-14);
  if (!invertible) return false;
  x = inverse * rhs;
  return x.allFinite();
}

bool satisfies(const AffineJacobian& g, const Eigen::Vector3d& p, double t) {
  return g.a.dot(p) + g.b >= t - 1e-12 * (1.0 + std::abs(t));
}

// visit(rows, x, inverse) for each 4-subset of `rows` (ascending, in lexicographic order) whose
// constraints meet in one vertex x (vertex_of).
template <typename Visit>
void for_each_vertex(const std::vector<AffineJacobian>& f, const std::vector<std::size_t>& rows, const Visit& visit) {
  Eigen::Vector4d x;
  Eigen::Matrix4d inverse;
  const std::size_t m = rows.size();
  for (std::size_t i = 0; i < m; ++i) {
    for (std::size_t j = i + 1; j < m; ++j) {
      for (std::size_t k = j + 1; k < m; ++k) {
        for (std::size_t l = k + 1; l < m; ++l) {
          const std::array<std::size_t, 4> four{rows[i], rows[j], rows[k], rows[l]};
          if (vertex_of(f, four, x, inverse)) visit(four, x, inverse);
        }
      }
    }
  }
}

// The optimum of the constraints `subset` (ascending) among the vertices of their 4-subsets
// where the objective's gradient lies in the cone of the active constraints' (KKT multipliers
// >= 0) and every constraint of `subset` holds; its rows and multipliers.
struct Vertex {
  std::array<std::size_t, 4> rows{};
  Eigen::Vector4d x, multipliers;
};
std::optional<Vertex> subset_optimum(const std::vector<AffineJacobian>& f, const std::vector<std::size_t>& subset) {
  std::optional<Vertex> best;
  for_each_vertex(
      f, subset, [&](const std::array<std::size_t, 4>& rows, const Eigen::Vector4d& x, const Eigen::Matrix4d& inverse) {
        const double t = x(3);
        if (best && !(t > best->x(3))) return;
        // Stationarity: sum lambda_r (a_r, -1) = -(0, 0, 0, 1), so lambda = -(row 3 of A^-1).
        const Eigen::Vector4d lambda = -inverse.row(3).transpose();
        if ((lambda.array() < -1e-12).any()) return;
        const Eigen::Vector3d p = x.head<3>();
        if (!std::all_of(subset.begin(), subset.end(), [&](std::size_t r) { return satisfies(f[r], p, t); })) return;
        best = Vertex{rows, x, lambda};
      });
  return best;
}

// The constraints active at the optimum of all constraints (ascending), when that optimum is one
// point: by active sets, the optimum of the constraints lowest at `current`, grown by the one it
// violates most until it violates none (then it is the whole program's optimum: feasible, with
// multipliers >= 0); tens of 4 x 4 solves. One point where its four multipliers are clearly > 0
// (> 1e-9); active: within 1e-9 of the terms' size. Nothing where a multiplier is near 0 (the
// optimum may be an edge or a face).
std::optional<std::vector<std::size_t>> optimum_active_set(const std::vector<AffineJacobian>& f,
                                                           const Eigen::Vector3d& current) {
  const std::size_t m = f.size();
  std::vector<std::size_t> order(m);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::vector<double> value(m);
  for (std::size_t i = 0; i < m; ++i) value[i] = f[i].a.dot(current) + f[i].b;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) { return value[x] < value[y]; });
  std::vector<char> active(m, 0);
  std::vector<std::size_t> subset;
  std::size_t next = 0;  // into `order`: the lowest constraint not yet active
  auto add = [&](std::size_t r) {
    active[r] = 1;
    subset.insert(std::upper_bound(subset.begin(), subset.end(), r), r);
  };
  while (next < m && subset.size() < 6) add(order[next++]);
  for (;;) {
    if (const std::optional<Vertex> v = subset_optimum(f, subset)) {
      const Eigen::Vector3d p = v->x.head<3>();
      const double t = v->x(3);
      std::size_t worst = m;
      double worst_slack = 0.0;
      for (std::size_t r = 0; r < m; ++r) {
        const double slack = f[r].a.dot(p) + f[r].b - t;
        if (!active[r] && !satisfies(f[r], p, t) && (worst == m || slack < worst_slack)) {
          worst = r;
          worst_slack = slack;
        }
      }
      if (worst < m) {
        add(worst);
        continue;
      }
      if ((v->multipliers.array() <= 1e-9).any()) return std::nullopt;
      double size = 1.0 + std::abs(t);
      for (const AffineJacobian& g : f) size = std::max(size, g.a.norm() * p.norm() + std::abs(g.b));
      std::vector<std::size_t> near_active;
      for (std::size_t r = 0; r < m; ++r) {
        if (f[r].a.dot(p) + f[r].b - t <= 1e-9 * size) near_active.push_back(r);
      }
      return near_active;
    }
    // No bounded optimum among these yet: twice as many of the lowest constraints (one more at a
    // time would enumerate every subset again and again).
    const std::size_t target = 2 * subset.size();
    while (next < m && subset.size() < target) {
      if (!active[order[next]]) add(order[next]);
      ++next;
    }
    if (subset.size() < target) return std::nullopt;
  }
}

// The best feasible vertex among the 4-subsets of `rows` (ascending), the first in their order
// where several are best: every vertex is solved and checked the same way, so a subset of the
// rows that holds every best vertex gives the same answer, bit for bit, as all of them.
bool best_feasible_vertex(const std::vector<AffineJacobian>& f, const std::vector<std::size_t>& rows,
                          Eigen::Vector3d& best_p, double& best_t) {
  bool found = false;
  best_t = -std::numeric_limits<double>::infinity();
  for_each_vertex(f, rows, [&](const std::array<std::size_t, 4>&, const Eigen::Vector4d& x, const Eigen::Matrix4d&) {
    const double t = x(3);
    if (!(t > best_t)) return;
    const Eigen::Vector3d p = x.head<3>();
    if (!std::all_of(f.begin(), f.end(), [&](const AffineJacobian& g) { return satisfies(g, p, t); })) return;
    best_t = t;
    best_p = p;
    found = true;
  });
  return found;
}

// max over p of min over i of (a_i . p + b_i): a linear program in (p, t); its optimum (bounded
// when the a_i surround the origin, as for a node inside its star) lies at a vertex where four
// constraints are active. The answer is the best feasible vertex, the first in the constraints'
// order where several are best (an active-set answer alone picked other optimal vertices, and on
// case007 that sent the node-by-node unfolding down a path that left a tet folded). Where the
// optimum is one point, only the constraints active there can make a best vertex, so only their
// 4-subsets are visited (1 to tens); else all of them (10,626 for 24 tets). Returns false when no
// vertex is feasible.
bool maximise_smallest(const std::vector<AffineJacobian>& f, const Eigen::Vector3d& current, Eigen::Vector3d& best_p,
                       double& best_t) {
  if (const auto active = optimum_active_set(f, current)) {
    if (best_feasible_vertex(f, *active, best_p, best_t)) return true;
  }
  std::vector<std::size_t> all(f.size());
  std::iota(all.begin(), all.end(), std::size_t{0});
  return best_feasible_vertex(f, all, best_p, best_t);
}

}  // namespace

std::vector<KeptBreath> unfolding_breaths(double scale, double min_jacobian, double sign) {
  std::vector<KeptBreath> breaths;
  breaths.reserve(kFractions.size());
  for (const double fraction : kFractions)
    breaths.push_back({sign * fraction * scale, lighter_floor(fraction, min_jacobian)});
  return breaths;
}

UntangleReport untangle_interior(const mesh::TetMesh& mesh, std::span<const std::uint32_t> boundary_nodes,
                                 std::vector<Eigen::Vector3d>& displacement, double scale, double min_jacobian,
                                 std::size_t max_sweeps, std::span<const KeptBreath> kept) {
  const std::size_t n = mesh.node_count();
  if (displacement.size() != n) throw ValueError("untangle_interior: one displacement per node");
  if (!(scale > 0.0) || !std::isfinite(scale)) throw ValueError("untangle_interior: the scale must be positive");
  if (!(min_jacobian > 0.0 && min_jacobian < 1.0))
    throw ValueError("untangle_interior: the smallest Jacobian sought must lie in (0, 1)");
  if (!std::all_of(kept.begin(), kept.end(),
                   [](const KeptBreath& b) { return std::isfinite(b.scale) && std::isfinite(b.floor); }))
    throw ValueError("untangle_interior: a kept breath must have a finite scale and floor");
  std::vector<char> fixed(n, 0);
  for (const std::uint32_t b : boundary_nodes) {
    if (b >= n) throw ValueError("untangle_interior: boundary node out of range");
    fixed[b] = 1;
  }
  // The tets around each node (CSR), and each tet's rest volume (times 6).
  std::vector<std::uint32_t> start(n + 1, 0), star;
  for (const auto& t : mesh.tets)
    for (const std::uint32_t v : t) ++start[v + 1];
  for (std::size_t i = 0; i < n; ++i) start[i + 1] += start[i];
  star.resize(start[n]);
  {
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    for (std::size_t t = 0; t < mesh.tet_count(); ++t)
      for (const std::uint32_t v : mesh.tets[t]) star[fill[v]++] = static_cast<std::uint32_t>(t);
  }
  std::vector<double> rest6(mesh.tet_count());
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const auto& q = mesh.tets[t];
    rest6[t] = mesh::tet_volume6(mesh.nodes[q[0]], mesh.nodes[q[1]], mesh.nodes[q[2]], mesh.nodes[q[3]]);
    if (!(rest6[t] > 0.0)) throw ValueError("untangle_interior: a tetrahedron with no positive rest volume");
  }
  auto jacobian_at = [&](std::size_t t, double s) {
    return mesh::deformed_volume6(mesh, mesh.tets[t], displacement, s) / rest6[t];
  };
  // Below the floor at `scale`; folded and the smallest over every breath checked. In parallel
  // blocks: counts and a minimum do not depend on the order.
  auto census = [&](std::size_t& below, std::size_t& folded, double& smallest) {
    const std::size_t blocks = detail::block_count(mesh.tet_count());
    std::vector<std::size_t> block_below(blocks, 0), block_folded(blocks, 0);
    std::vector<double> block_smallest(blocks, std::numeric_limits<double>::infinity());
    detail::for_blocks(mesh.tet_count(), [&](std::size_t block, std::size_t lo, std::size_t hi) {
      for (std::size_t t = lo; t < hi; ++t) {
        bool folds = false;
        for (const double fraction : kFractions) {
          const double j = jacobian_at(t, fraction * scale);
          if (fraction == 1.0) block_below[block] += j < min_jacobian;
          folds = folds || j <= 0.0;
          block_smallest[block] = std::min(block_smallest[block], j);
        }
        block_folded[block] += folds;
      }
    });
    below = folded = 0;
    smallest = std::numeric_limits<double>::infinity();
    for (std::size_t b = 0; b < blocks; ++b) {
      below += block_below[b];
      folded += block_folded[b];
      smallest = std::min(smallest, block_smallest[b]);
    }
  };
  // The tets below the floor at the breath s, ascending.
  auto below_at = [&](double s) {
    const std::size_t blocks = detail::block_count(mesh.tet_count());
    std::vector<std::vector<std::uint32_t>> found(blocks);
    detail::for_blocks(mesh.tet_count(), [&](std::size_t block, std::size_t lo, std::size_t hi) {
      for (std::size_t t = lo; t < hi; ++t) {
        if (jacobian_at(t, s) < min_jacobian) found[block].push_back(static_cast<std::uint32_t>(t));
      }
    });
    std::vector<std::uint32_t> all;
    for (const auto& f : found) all.insert(all.end(), f.begin(), f.end());
    return all;
  };
  UntangleReport report;
  census(report.tets_below_before, report.folded_before, report.min_jacobian_before);
  std::vector<char> touched(n, 0);
  std::vector<AffineJacobian> f;
  std::vector<double> kept_floor, kept_ceiling;
  // The lightest breath first; a deeper one may not push a lighter one below the floor again.
  for (std::size_t level = 0; level < kFractions.size(); ++level) {
    const double s = kFractions[level] * scale;
    // Kept from sweep to sweep: a tet's Jacobian changes only where one of its nodes moved.
    std::vector<std::uint32_t> below = below_at(s), moved;
    for (std::size_t sweep = 0; sweep < max_sweeps; ++sweep) {
      if (sweep > 0) {
        for (const std::uint32_t v : moved)
          below.insert(below.end(), star.begin() + start[v], star.begin() + start[v + 1]);
        std::sort(below.begin(), below.end());
        below.erase(std::unique(below.begin(), below.end()), below.end());
        std::erase_if(below, [&](std::uint32_t t) { return jacobian_at(t, s) >= min_jacobian; });
        moved.clear();
      }
      // The free nodes of the tets below the floor at this breath, ascending.
      std::vector<std::uint32_t> nodes;
      for (const std::uint32_t t : below) {
        for (const std::uint32_t v : mesh.tets[t])
          if (!fixed[v]) nodes.push_back(v);
      }
      if (nodes.empty()) break;
      std::sort(nodes.begin(), nodes.end());
      nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
      report.sweeps = std::max(report.sweeps, sweep + 1);
      bool improved = false;
      for (const std::uint32_t v : nodes) {
        f.clear();
        for (std::uint32_t k = start[v]; k < start[v + 1]; ++k) {
          const auto& q = mesh.tets[star[k]];
          const std::array<Eigen::Vector3d, 4> p = mesh::moved_corners(mesh, q, displacement, s);
          f.push_back(affine_in_node(p, static_cast<std::size_t>(std::find(q.begin(), q.end(), v) - q.begin()),
                                     rest6[star[k]]));
        }
        Eigen::Vector3d optimum;
        double best = 0.0;
        if (!maximise_smallest(f, mesh::moved_node(mesh.nodes[v], displacement[v], s), optimum, best)) continue;
        // On the way from the node's U to the one that reaches the optimum at this breath, the
        // star's smallest Jacobian at this breath (`here`) and at each lighter one (`lighter`) is
        // concave in lambda: go no further than the lighter breaths allow (not below their envelope, or
        // below where they are), and there as far as needed to reach the floor, else to the best.
        const Eigen::Vector3d u0 = displacement[v], u1 = (optimum - mesh.nodes[v]) / s;
        // The star's smallest and largest Jacobian at `breath`: each tet's is affine in lambda, so
        // the smallest is concave and the largest convex in it.
        auto extremes_at = [&](double lambda, double breath) {
          const Eigen::Vector3d u = u0 + lambda * (u1 - u0);
          double lo = std::numeric_limits<double>::infinity(), hi = -lo;
          for (std::uint32_t k = start[v]; k < start[v + 1]; ++k) {
            const auto& q = mesh.tets[star[k]];
            std::array<Eigen::Vector3d, 4> x;
            for (std::size_t c = 0; c < 4; ++c)
              x[c] = mesh::moved_node(mesh.nodes[q[c]], q[c] == v ? u : displacement[q[c]], breath);
            const double j = mesh::tet_volume6(x[0], x[1], x[2], x[3]) / rest6[star[k]];
            lo = std::min(lo, j);
            hi = std::max(hi, j);
          }
          return std::pair{lo, hi};
        };
        auto smallest_at = [&](double lambda, double breath) { return extremes_at(lambda, breath).first; };
        auto smallest = [&](double lambda, std::size_t l) { return smallest_at(lambda, kFractions[l] * scale); };
        auto here = [&](double lambda) { return smallest(lambda, level); };
        // A lighter breath l keeps the star's smallest Jacobian at or above lighter_floor (or where
        // it was, if lower): a quiet breath's inside, which the elastic field leaves near 1, is
        // not traded for a deep one's (a floor of 0.2 at every breath let the moves for 1 L leave
        // J = 0.25-0.55 in a 250 mL breath beside the heart).
        // So does each kept breath of the other direction.
        // Nor, at this breath or a lighter one, its largest above lighter_ceiling (or where it was,
        // if higher): a move does not tear the tets on the node's other side.
        std::array<double, kFractions.size()> keep{}, keep_top{};
        for (std::size_t l = 0; l <= level; ++l) {
          const auto [lo, hi] = extremes_at(0.0, kFractions[l] * scale);
          keep[l] = std::min(lighter_floor(kFractions[l], min_jacobian), lo);
          keep_top[l] = std::max(lighter_ceiling(kFractions[l], min_jacobian), hi);
        }
        kept_floor.clear();
        kept_ceiling.clear();
        for (const KeptBreath& b : kept) {
          const auto [lo, hi] = extremes_at(0.0, b.scale);
          kept_floor.push_back(std::min(b.floor, lo));
          kept_ceiling.push_back(
              std::max({kQuietCeiling, b.floor > 0.0 ? 1.0 / b.floor : std::numeric_limits<double>::infinity(), hi}));
        }
        auto lighter_keep = [&](double lambda) {
          for (std::size_t l = 0; l <= level; ++l) {
            const auto [lo, hi] = extremes_at(lambda, kFractions[l] * scale);
            if ((l < level && lo < keep[l]) || hi > keep_top[l]) return false;
          }
          for (std::size_t b = 0; b < kept.size(); ++b) {
            const auto [lo, hi] = extremes_at(lambda, kept[b].scale);
            if (lo < kept_floor[b] || hi > kept_ceiling[b]) return false;
          }
          return true;
        };
        const double start_here = here(0.0);
        if (!(best > start_here + 1e-9)) continue;
        double reach = 1.0;  // the lighter breaths allow [0, reach] (each is concave in lambda)
        if (!lighter_keep(1.0)) {
          double lo = 0.0, hi = 1.0;
          for (int it = 0; it < 40; ++it) {
            const double mid = 0.5 * (lo + hi);
            (lighter_keep(mid) ? lo : hi) = mid;
          }
          reach = lo;
        }
        double lambda = reach;
        if (here(reach) >= min_jacobian) {
          double lo = 0.0, hi = reach;  // the first point at the floor
          for (int it = 0; it < 40; ++it) {
            const double mid = 0.5 * (lo + hi);
            (here(mid) >= min_jacobian ? hi : lo) = mid;
          }
          lambda = hi;
        } else {
          double lo = 0.0, hi = reach;  // golden-section search for the best
          constexpr double kGolden = 0.6180339887498949;
          for (int it = 0; it < 40; ++it) {
            const double a = hi - kGolden * (hi - lo), b = lo + kGolden * (hi - lo);
            if (here(a) < here(b)) {
              lo = a;
            } else {
              hi = b;
            }
          }
          lambda = 0.5 * (lo + hi);
        }
        if (!(here(lambda) > start_here + 1e-9)) continue;
        displacement[v] = u0 + lambda * (u1 - u0);
        if (!touched[v]) {
          touched[v] = 1;
          ++report.nodes_moved;
        }
        moved.push_back(v);
        improved = true;
      }
      if (!improved) break;
    }
  }
  census(report.tets_below_after, report.folded_after, report.min_jacobian_after);
  for (std::size_t t = 0; t < mesh.tet_count(); ++t) {
    const auto& q = mesh.tets[t];
    if (!(fixed[q[0]] && fixed[q[1]] && fixed[q[2]] && fixed[q[3]])) continue;
    report.folded_all_boundary += folds_by(mesh, q, displacement, scale);
  }
  return report;
}

DroppedTets drop_folded_boundary_tets(mesh::TetMesh& mesh, std::span<const std::uint32_t> boundary_nodes,
                                      const std::vector<Eigen::Vector3d>& displacement, double scale) {
  if (displacement.size() != mesh.node_count())
    throw ValueError("drop_folded_boundary_tets: one displacement per node");
  auto on_boundary = [&](std::uint32_t v) {
    return std::binary_search(boundary_nodes.begin(), boundary_nodes.end(), v);
  };
  DroppedTets dropped;
  std::vector<mesh::Tetrahedron> kept;
  kept.reserve(mesh.tet_count());
  for (const mesh::Tetrahedron& q : mesh.tets) {
    if (on_boundary(q[0]) && on_boundary(q[1]) && on_boundary(q[2]) && on_boundary(q[3]) &&
        folds_by(mesh, q, displacement, scale)) {
      ++dropped.count;
      dropped.rest_volume_m3 +=
          mesh::tet_volume6(mesh.nodes[q[0]], mesh.nodes[q[1]], mesh.nodes[q[2]], mesh.nodes[q[3]]) / 6.0;
    } else {
      kept.push_back(q);
    }
  }
  mesh.tets = std::move(kept);
  return dropped;
}

}  // namespace pneuma::field
