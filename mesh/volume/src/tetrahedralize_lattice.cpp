// The lattice mesher (tetrahedralize.h, TetMesher::lattice): the Kuhn triangulation of a cubic
// lattice, cut at the surface (marching tetrahedra) after lattice nodes close to it were moved
// onto it (the warping of Labelle & Shewchuk's isosurface stuffing, 2007). Linear in the lattice
// and the surface, no CGAL: it is what makes a 1M-tet inside cost seconds, not tens of seconds.
//
//   1. inside or outside at every lattice node: ray parity along z, one ray per lattice column,
//      against the triangles binned by xy cell;
//   2. where an edge of the triangulation joins an inside and an outside node, the nearest
//      crossing of the surface from the inside node (segment-triangle tests in that edge's cell);
//   3. a node closer to a crossing on one of its edges than kWarp of the edge moves onto it and is
//      then on the surface (no edge of it is cut), so no tet is cut into a sliver near a node;
//   4. each tet keeps its inside part: all of it, or the convex polytope of its inside nodes and
//      crossings, split by the pulling rule (a cone from its lowest-numbered node over the faces
//      not holding it, each face fanned from its own lowest-numbered corner). A face's split
//      depends on its corners only, so neighbouring tets split a shared face alike: conforming.
//
// Orientation comes from the unwarped polytope (convex, so the pulling rule cannot invert it);
// where warping flattened or inverted a tet, its warped nodes go back and the cut is made again.
#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/core/tsan.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"
#include "pneuma/mesh/volume/tetrahedralize.h"
#include "tet_quality.h"

namespace pneuma::mesh {
namespace {

// A crossing within this fraction of an edge from a node moves the node onto it. Stuffing's
// proofs use 0.25-0.41 on its BCC lattice; 0.25 keeps every cut piece at least a quarter of an
// edge thick on the Kuhn lattice while moving no node more than a quarter of its longest edge.
constexpr double kWarp = 0.25;
// A tet thinner than this (6 V / h^3) after warping sends its warped nodes back.
constexpr double kFlat = 1e-3;
constexpr int kMaxRounds = 8;

using Vec = Eigen::Vector3d;

// The 7 edge directions of the Kuhn triangulation from a node (corner bit masks x=1, y=2, z=4):
// an edge joins corners a and b of one cube where a's bits are a subset of b's.
constexpr int kDirections = 7;

struct Lattice {
  Vec origin;
  double h = 0.0;
  std::array<std::int64_t, 3> n{};  // nodes per axis

  std::int64_t node(std::int64_t i, std::int64_t j, std::int64_t k) const { return i + n[0] * (j + n[1] * k); }
  std::int64_t node_count() const { return n[0] * n[1] * n[2]; }
  Vec position(std::int64_t id) const {
    const std::int64_t i = id % n[0], j = (id / n[0]) % n[1], k = id / (n[0] * n[1]);
    return origin + h * Vec(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k));
  }
  std::int64_t offset(int bits) const {
    return (bits & 1 ? 1 : 0) + (bits & 2 ? n[0] : 0) + (bits & 4 ? n[0] * n[1] : 0);
  }
};

// Triangles binned by the xy cell [x_i, x_i+1] x [y_j, y_j+1] their bounding box overlaps, by
// index: a triangle that a lattice line (x_i, y_j) or an edge of a cube over cell (i, j) meets is
// in cell (i, j) (the lattice's irrational shift keeps box ends off the lattice lines).
struct CellBins {
  std::vector<std::size_t> first;  // per cell i + n0 * j, into `triangle`
  std::vector<std::uint32_t> triangle;
  std::vector<std::array<double, 2>> z_range;  // per triangle
};

CellBins bin_triangles(const TriangleMesh& surface, const Lattice& lattice) {
  const std::size_t cells = static_cast<std::size_t>(lattice.n[0] * lattice.n[1]);
  CellBins bins;
  bins.first.assign(cells + 1, 0);
  bins.z_range.resize(surface.triangle_count());
  std::vector<std::array<std::int64_t, 4>> span(surface.triangle_count());
  for (std::size_t f = 0; f < surface.triangle_count(); ++f) {
    const auto& t = surface.triangles[f];
    Vec lo = surface.vertices[t[0]], hi = lo;
    for (int c = 1; c < 3; ++c) {
      lo = lo.cwiseMin(surface.vertices[t[static_cast<std::size_t>(c)]]);
      hi = hi.cwiseMax(surface.vertices[t[static_cast<std::size_t>(c)]]);
    }
    bins.z_range[f] = {lo.z(), hi.z()};
    auto cell = [&](double v, int axis) {
      return std::clamp(static_cast<std::int64_t>(std::floor((v - lattice.origin[axis]) / lattice.h)), std::int64_t{0},
                        lattice.n[static_cast<std::size_t>(axis)] - 1);
    };
    // Inclusive: a box ending exactly on x_i also lies in cell i - 1.
    span[f] = {cell(lo.x(), 0), cell(hi.x(), 0), cell(lo.y(), 1), cell(hi.y(), 1)};
    for (std::int64_t j = span[f][2]; j <= span[f][3]; ++j) {
      for (std::int64_t i = span[f][0]; i <= span[f][1]; ++i)
        ++bins.first[static_cast<std::size_t>(i + lattice.n[0] * j) + 1];
    }
  }
  for (std::size_t c = 0; c < cells; ++c) bins.first[c + 1] += bins.first[c];
  bins.triangle.resize(bins.first.back());
  std::vector<std::size_t> fill(bins.first.begin(), bins.first.end() - 1);
  for (std::size_t f = 0; f < surface.triangle_count(); ++f) {
    for (std::int64_t j = span[f][2]; j <= span[f][3]; ++j) {
      for (std::int64_t i = span[f][0]; i <= span[f][1]; ++i) {
        bins.triangle[fill[static_cast<std::size_t>(i + lattice.n[0] * j)]++] = static_cast<std::uint32_t>(f);
      }
    }
  }
  return bins;
}

// Twice the signed area of (a, b, p) in xy, antisymmetric in a and b to the last bit (the two
// triangles of an edge see exactly opposite values, so a ray is not lost between them).
double edge_side(const Vec& a, const Vec& b, double px, double py) {
  const bool ordered = a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  const Vec& u = ordered ? a : b;
  const Vec& v = ordered ? b : a;
  const double side = (v.x() - u.x()) * (py - u.y()) - (v.y() - u.y()) * (px - u.x());
  return ordered ? side : -side;
}

// Where the vertical line (px, py) crosses the triangle, if it does (strictly inside its xy shadow).
bool vertical_crossing(const TriangleMesh& surface, std::uint32_t f, double px, double py, double& z) {
  const auto& t = surface.triangles[f];
  const Vec& a = surface.vertices[t[0]];
  const Vec& b = surface.vertices[t[1]];
  const Vec& c = surface.vertices[t[2]];
  const double wa = edge_side(b, c, px, py), wb = edge_side(c, a, px, py), wc = edge_side(a, b, px, py);
  if (!((wa > 0.0 && wb > 0.0 && wc > 0.0) || (wa < 0.0 && wb < 0.0 && wc < 0.0))) return false;
  const double sum = wa + wb + wc;
  z = (wa * a.z() + wb * b.z() + wc * c.z()) / sum;
  return true;
}

// The parameter t in [0, 1] where segment p + t (q - p) meets triangle f (Moller-Trumbore, ends
// and edges included), or a negative value.
double segment_crossing(const TriangleMesh& surface, std::uint32_t f, const Vec& p, const Vec& q) {
  const auto& t = surface.triangles[f];
  const Vec& a = surface.vertices[t[0]];
  const Vec e1 = surface.vertices[t[1]] - a, e2 = surface.vertices[t[2]] - a, d = q - p;
  const Vec s = d.cross(e2);
  const double det = e1.dot(s);
  if (det == 0.0) return -1.0;
  const double inv = 1.0 / det;
  const Vec r = p - a;
  const double u = r.dot(s) * inv;
  if (u < 0.0 || u > 1.0) return -1.0;
  const Vec rq = r.cross(e1);
  const double v = d.dot(rq) * inv;
  if (v < 0.0 || u + v > 1.0) return -1.0;
  const double tt = e2.dot(rq) * inv;
  return tt >= 0.0 && tt <= 1.0 ? tt : -1.0;
}

struct Cut {
  std::int64_t edge = 0;  // node * 7 + direction - 1
  double t = 0.5;         // from the edge's first node
  Vec position;
};

// The six Kuhn tets of a cube as corner masks, each positively oriented.
constexpr std::array<std::array<int, 4>, 6> kKuhn = [] {
  std::array<std::array<int, 4>, 6> tets{};
  const std::array<std::array<int, 3>, 6> order{{{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}}};
  for (std::size_t p = 0; p < 6; ++p) {
    const int a = 1 << order[p][0], b = a | (1 << order[p][1]);
    // (0, a, b, 7): positive for an even permutation of the axes, so swap for an odd one.
    const bool even = p == 0 || p == 3 || p == 4;
    tets[p] = even ? std::array<int, 4>{0, a, b, 7} : std::array<int, 4>{0, b, a, 7};
  }
  return tets;
}();

// Tets by id: a lattice node, or node_count + a cut's index.
using IdTets = std::vector<std::array<std::int64_t, 4>>;

class LatticeMesher {
 public:
  LatticeMesher(const TriangleMesh& surface, double h) : surface_(surface) {
    const auto box = bounding_box(surface.vertices);
    lattice_.h = h;
    // An irrational shift of the lattice, so that no lattice line runs through a vertex or an
    // edge of a surface made on a grid (marching cubes, a voxel rebuild).
    lattice_.origin = box[0] - h * Vec(1.5 + 0.1234567891, 1.5 + 0.2718281828, 1.5 + 0.3141592653);
    for (int a = 0; a < 3; ++a) {
      lattice_.n[static_cast<std::size_t>(a)] =
          static_cast<std::int64_t>(std::ceil((box[1][a] - lattice_.origin[a]) / h)) + 2;
    }
    if (static_cast<double>(lattice_.node_count()) > 1e8) {
      throw ValueError(fmt::format("tetrahedralize: a {:.3g} mm lattice over this surface would have {:.3g} nodes; "
                                   "choose a larger edge",
                                   h * 1e3, static_cast<double>(lattice_.node_count())));
    }
    bins_ = bin_triangles(surface, lattice_);
  }

  VolumeMesh run();

 private:
  void classify_nodes();
  void find_cuts();
  void warp(const std::vector<char>& pinned);
  IdTets cut_tets(std::vector<std::int64_t>& flat_nodes) const;
  void cut_one(const std::array<std::int64_t, 4>& node, std::vector<std::array<std::int64_t, 4>>& out) const;

  std::int64_t cut_index(std::int64_t a, std::int64_t b) const {
    const std::int64_t lo = std::min(a, b), hi = std::max(a, b);
    const std::int64_t d = hi - lo;
    int bits = 0;
    for (int m = 1; m <= kDirections; ++m) {
      if (lattice_.offset(m) == d) bits = m;
    }
    const std::int64_t edge = lo * kDirections + bits - 1;
    const auto it =
        std::lower_bound(cuts_.begin(), cuts_.end(), edge, [](const Cut& c, std::int64_t e) { return c.edge < e; });
    return static_cast<std::int64_t>(it - cuts_.begin());
  }
  // -1 inside, +1 outside, 0 moved onto the surface.
  int sign(std::int64_t node) const { return warped_[static_cast<std::size_t>(node)] ? 0 : inside_sign(node); }
  int inside_sign(std::int64_t node) const { return inside_[static_cast<std::size_t>(node)] ? -1 : 1; }
  Vec position(std::int64_t id) const {
    const std::int64_t nodes = lattice_.node_count();
    if (id >= nodes) return cuts_[static_cast<std::size_t>(id - nodes)].position;
    return warped_[static_cast<std::size_t>(id)] ? cuts_[warp_to_[static_cast<std::size_t>(id)]].position
                                                 : lattice_.position(id);
  }
  Vec reference_position(std::int64_t id) const {
    const std::int64_t nodes = lattice_.node_count();
    return id >= nodes ? cuts_[static_cast<std::size_t>(id - nodes)].position : lattice_.position(id);
  }

  const TriangleMesh& surface_;
  Lattice lattice_;
  CellBins bins_;
  std::vector<char> inside_;
  std::vector<Cut> cuts_;  // ascending edge
  std::vector<char> warped_;
  std::vector<std::uint32_t> warp_to_;  // cut index, where warped
};

void LatticeMesher::classify_nodes() {
  const std::int64_t nx = lattice_.n[0], ny = lattice_.n[1], nz = lattice_.n[2];
  inside_.assign(static_cast<std::size_t>(lattice_.node_count()), 0);
  std::vector<char> odd(static_cast<std::size_t>(nx * ny), 0);
  const tsan::Region region;
  tbb::parallel_for(std::int64_t{0}, ny, region.wrap([&](std::int64_t j) {
    std::vector<double> z;
    for (std::int64_t i = 0; i < nx; ++i) {
      const std::size_t cell = static_cast<std::size_t>(i + nx * j);
      const Vec line = lattice_.position(lattice_.node(i, j, 0));
      z.clear();
      for (std::size_t k = bins_.first[cell]; k < bins_.first[cell + 1]; ++k) {
        double crossing = 0.0;
        if (vertical_crossing(surface_, bins_.triangle[k], line.x(), line.y(), crossing)) z.push_back(crossing);
      }
      if (z.empty()) continue;
      std::sort(z.begin(), z.end());
      if (z.size() % 2 != 0) odd[cell] = 1;
      std::size_t below = 0;
      for (std::int64_t k = 0; k < nz; ++k) {
        const double zk = line.z() + lattice_.h * static_cast<double>(k);
        while (below < z.size() && z[below] < zk) ++below;
        inside_[static_cast<std::size_t>(lattice_.node(i, j, k))] = static_cast<char>(below % 2);
      }
    }
  }));
  region.join();
  const auto odd_columns = std::count(odd.begin(), odd.end(), 1);
  if (odd_columns > 0) {
    throw ValueError(fmt::format("tetrahedralize: {} lattice lines cross the surface an odd number of times, so it "
                                 "does not bound a volume (holes, or faces that overlap)",
                                 odd_columns));
  }
}

void LatticeMesher::find_cuts() {
  const std::int64_t nx = lattice_.n[0], ny = lattice_.n[1], nz = lattice_.n[2];
  // Per z slab, the cut edges in ascending order: the slabs concatenated are ascending too.
  std::vector<std::vector<Cut>> slab(static_cast<std::size_t>(nz));
  const tsan::Region region;
  tbb::parallel_for(std::int64_t{0}, nz - 1, region.wrap([&](std::int64_t k) {
    auto& out = slab[static_cast<std::size_t>(k)];
    for (std::int64_t j = 0; j + 1 < ny; ++j) {
      for (std::int64_t i = 0; i + 1 < nx; ++i) {
        const std::int64_t a = lattice_.node(i, j, k);
        const int sa = inside_sign(a);
        for (int m = 1; m <= kDirections; ++m) {
          const std::int64_t b = a + lattice_.offset(m);
          if (inside_sign(b) == sa) continue;
          Cut cut;
          cut.edge = a * kDirections + m - 1;
          // The crossing nearest the inside node (the edge may cross a fold more than once).
          const Vec p = lattice_.position(sa < 0 ? a : b), q = lattice_.position(sa < 0 ? b : a);
          const std::size_t cell = static_cast<std::size_t>(i + nx * j);
          const double z_lo = std::min(p.z(), q.z()), z_hi = std::max(p.z(), q.z());
          double best = 2.0;
          for (std::size_t f = bins_.first[cell]; f < bins_.first[cell + 1]; ++f) {
            const std::uint32_t tri = bins_.triangle[f];
            if (bins_.z_range[tri][1] < z_lo || bins_.z_range[tri][0] > z_hi) continue;
            const double t = segment_crossing(surface_, tri, p, q);
            if (t >= 0.0 && t < best) best = t;
          }
          // None found: the parity and the segment test disagree at a grazing hit; the midpoint,
          // whose boundary value still comes from the closest point of the surface.
          if (best > 1.0) best = 0.5;
          const double from_inside = best;
          cut.t = sa < 0 ? from_inside : 1.0 - from_inside;
          cut.position = p + from_inside * (q - p);
          out.push_back(cut);
        }
      }
    }
  }));
  region.join();
  cuts_.clear();
  for (auto& s : slab) cuts_.insert(cuts_.end(), s.begin(), s.end());
}

void LatticeMesher::warp(const std::vector<char>& pinned) {
  const auto nodes = static_cast<std::size_t>(lattice_.node_count());
  warped_.assign(nodes, 0);
  warp_to_.assign(nodes, 0);
  std::vector<double> distance(nodes, std::numeric_limits<double>::infinity());
  for (std::size_t c = 0; c < cuts_.size(); ++c) {
    const Cut& cut = cuts_[c];
    const std::int64_t a = cut.edge / kDirections;
    const std::int64_t b = a + lattice_.offset(static_cast<int>(cut.edge % kDirections) + 1);
    const double length = (lattice_.position(b) - lattice_.position(a)).norm();
    auto offer = [&](std::int64_t node, double fraction) {
      const auto n = static_cast<std::size_t>(node);
      if (fraction < kWarp && !pinned[n] && fraction * length < distance[n]) {
        distance[n] = fraction * length;
        warped_[n] = 1;
        warp_to_[n] = static_cast<std::uint32_t>(c);
      }
    };
    offer(a, cut.t);
    offer(b, 1.0 - cut.t);
  }
}

void LatticeMesher::cut_one(const std::array<std::int64_t, 4>& node,
                            std::vector<std::array<std::int64_t, 4>>& out) const {
  std::array<int, 4> s{};
  int inside = 0, outside = 0;
  for (std::size_t v = 0; v < 4; ++v) {
    s[v] = sign(node[v]);
    inside += s[v] < 0 ? 1 : 0;
    outside += s[v] > 0 ? 1 : 0;
  }
  const std::int64_t nodes = lattice_.node_count();
  if (inside == 0 && outside == 0) {
    // All four on the surface: inside when most of them started inside (ties: kept).
    int started_inside = 0;
    for (const std::int64_t v : node) started_inside += inside_[static_cast<std::size_t>(v)] ? 1 : 0;
    if (started_inside >= 2) out.push_back(node);
    return;
  }
  if (inside == 0) return;
  if (outside == 0) {
    out.push_back(node);
    return;
  }
  auto cut = [&](std::size_t a, std::size_t b) { return nodes + cut_index(node[a], node[b]); };
  // The faces of the inside part: each tet face clipped, and the surface face.
  std::array<std::array<std::int64_t, 4>, 5> face{};
  std::array<int, 5> size{};
  constexpr std::array<std::array<std::size_t, 3>, 4> kFaces{{{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}}};
  for (std::size_t f = 0; f < 4; ++f) {
    int count = 0;
    for (std::size_t e = 0; e < 3; ++e) {
      const std::size_t a = kFaces[f][e], b = kFaces[f][(e + 1) % 3];
      if (s[a] <= 0) face[f][static_cast<std::size_t>(count++)] = node[a];
      if (s[a] * s[b] < 0) face[f][static_cast<std::size_t>(count++)] = cut(a, b);
    }
    size[f] = count;
  }
  {
    int count = 0;
    std::array<std::size_t, 2> in{}, out_side{};
    int n_in = 0, n_out = 0;
    for (std::size_t v = 0; v < 4; ++v) {
      if (s[v] == 0) face[4][static_cast<std::size_t>(count++)] = node[v];
      if (s[v] < 0 && n_in < 2) in[static_cast<std::size_t>(n_in++)] = v;
      if (s[v] > 0 && n_out < 2) out_side[static_cast<std::size_t>(n_out++)] = v;
    }
    if (inside == 2 && outside == 2) {  // a quadrilateral, in cyclic order
      face[4] = {cut(in[0], out_side[0]), cut(in[0], out_side[1]), cut(in[1], out_side[1]), cut(in[1], out_side[0])};
      count = 4;
    } else {
      for (std::size_t a = 0; a < 4; ++a) {
        for (std::size_t b = a + 1; b < 4; ++b) {
          if (s[a] * s[b] < 0) face[4][static_cast<std::size_t>(count++)] = cut(a, b);
        }
      }
    }
    size[4] = count;
  }
  std::int64_t apex = std::numeric_limits<std::int64_t>::max();
  for (std::size_t v = 0; v < 4; ++v) {
    if (s[v] <= 0) apex = std::min(apex, node[v]);
  }
  for (std::size_t f = 0; f < 5; ++f) {
    const auto n = static_cast<std::size_t>(size[f]);
    if (n < 3) continue;
    const auto begin = face[f].begin(), end = face[f].begin() + static_cast<std::ptrdiff_t>(n);
    if (std::find(begin, end, apex) != end) continue;
    const auto first = static_cast<std::size_t>(std::min_element(begin, end) - begin);
    for (std::size_t k = 1; k + 1 < n; ++k) {
      out.push_back({apex, face[f][first], face[f][(first + k) % n], face[f][(first + k + 1) % n]});
    }
  }
}

IdTets LatticeMesher::cut_tets(std::vector<std::int64_t>& flat_nodes) const {
  const std::int64_t nx = lattice_.n[0], ny = lattice_.n[1], nz = lattice_.n[2];
  std::vector<std::vector<std::array<std::int64_t, 4>>> slab(static_cast<std::size_t>(nz));
  std::vector<std::vector<std::int64_t>> flat(static_cast<std::size_t>(nz));
  const double h3 = lattice_.h * lattice_.h * lattice_.h;
  const tsan::Region region;
  tbb::parallel_for(std::int64_t{0}, nz - 1, region.wrap([&](std::int64_t k) {
    auto& out = slab[static_cast<std::size_t>(k)];
    std::vector<std::array<std::int64_t, 4>> pieces;
    for (std::int64_t j = 0; j + 1 < ny; ++j) {
      for (std::int64_t i = 0; i + 1 < nx; ++i) {
        const std::int64_t corner = lattice_.node(i, j, k);
        bool any_inside = false;
        for (int m = 0; m < 8; ++m) any_inside = any_inside || sign(corner + lattice_.offset(m)) <= 0;
        if (!any_inside) continue;
        for (const auto& kuhn : kKuhn) {
          std::array<std::int64_t, 4> tet{};
          for (std::size_t v = 0; v < 4; ++v) tet[v] = corner + lattice_.offset(kuhn[v]);
          pieces.clear();
          cut_one(tet, pieces);
          for (auto& piece : pieces) {
            const double reference = tet_volume6(reference_position(piece[0]), reference_position(piece[1]),
                                                 reference_position(piece[2]), reference_position(piece[3]));
            if (reference < 0.0) std::swap(piece[2], piece[3]);
            const double actual =
                tet_volume6(position(piece[0]), position(piece[1]), position(piece[2]), position(piece[3]));
            if (!(actual > kFlat * h3)) {
              for (const std::int64_t v : piece) {
                if (v < lattice_.node_count() && warped_[static_cast<std::size_t>(v)]) {
                  flat[static_cast<std::size_t>(k)].push_back(v);
                }
              }
            }
            out.push_back(piece);
          }
        }
      }
    }
  }));
  region.join();
  IdTets tets;
  for (std::size_t k = 0; k < slab.size(); ++k) {
    tets.insert(tets.end(), slab[k].begin(), slab[k].end());
    flat_nodes.insert(flat_nodes.end(), flat[k].begin(), flat[k].end());
  }
  return tets;
}

VolumeMesh LatticeMesher::run() {
  classify_nodes();
  find_cuts();
  std::vector<char> pinned(static_cast<std::size_t>(lattice_.node_count()), 0);
  IdTets emitted;
  for (int round = 0;; ++round) {
    warp(pinned);
    std::vector<std::int64_t> flat;
    emitted = cut_tets(flat);
    // After the last round flat tets are kept if they are positive (checked below).
    if (flat.empty() || round + 1 == kMaxRounds) break;
    for (const std::int64_t v : flat) pinned[static_cast<std::size_t>(v)] = 1;
  }
  if (emitted.empty()) throw ValueError("tetrahedralize: no lattice node lies inside the surface");

  // Nodes numbered by first use, lattice order (good locality for the solver).
  VolumeMesh out;
  const std::int64_t lattice_nodes = lattice_.node_count();
  std::vector<std::uint32_t> index(static_cast<std::size_t>(lattice_nodes) + cuts_.size(), ~std::uint32_t{0});
  out.mesh.tets.reserve(emitted.size());
  out.min_volume_m3 = std::numeric_limits<double>::infinity();
  out.min_dihedral_deg = 180.0;
  std::vector<char> on_surface;
  for (const auto& t : emitted) {
    Tetrahedron tet{};
    for (std::size_t v = 0; v < 4; ++v) {
      const auto s = static_cast<std::size_t>(t[v]);
      if (index[s] == ~std::uint32_t{0}) {
        index[s] = static_cast<std::uint32_t>(out.mesh.nodes.size());
        out.mesh.nodes.push_back(position(t[v]));
        on_surface.push_back(t[v] >= lattice_nodes || warped_[static_cast<std::size_t>(t[v])] ? 1 : 0);
      }
      tet[v] = index[s];
    }
    const auto& n = out.mesh.nodes;
    const double v6 = tet_volume6(n[tet[0]], n[tet[1]], n[tet[2]], n[tet[3]]);
    out.mesh.tets.push_back(tet);
    out.volume_m3 += v6 / 6.0;
    out.min_volume_m3 = std::min(out.min_volume_m3, v6 / 6.0);
    out.min_dihedral_deg =
        std::min(out.min_dihedral_deg, detail::min_dihedral_deg(n[tet[0]], n[tet[1]], n[tet[2]], n[tet[3]]));
  }
  if (!(out.min_volume_m3 > 0.0)) {
    throw Error(ExitCode::failure, fmt::format("tetrahedralize: the lattice mesher made a tetrahedron of volume {:.3g} "
                                               "m^3; try the delaunay mesher",
                                               out.min_volume_m3));
  }
  for (std::uint32_t v = 0; v < on_surface.size(); ++v) {
    if (on_surface[v]) out.boundary_nodes.push_back(v);
  }
  return out;
}

}  // namespace

namespace detail {

VolumeMesh tetrahedralize_lattice(const TriangleMesh& closed_surface, double edge_m) {
  LatticeMesher mesher(closed_surface, edge_m);
  return mesher.run();
}

}  // namespace detail
}  // namespace pneuma::mesh
