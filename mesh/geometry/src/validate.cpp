// Topological validation on the index list: sorted half-edges, union-find over faces and over
// corners (vertex fans). Deterministic: every pass runs in face order or sorted order.
#include <Eigen/Geometry>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>

#include "pneuma/core/error.h"
#include "pneuma/mesh/cgal/cgal_internal.h"
#include "pneuma/mesh/geometry/validate.h"

namespace pneuma::mesh {
namespace {

class UnionFind {
 public:
  explicit UnionFind(std::size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), std::size_t{0}); }
  std::size_t find(std::size_t x) {
    while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
    return x;
  }
  void unite(std::size_t a, std::size_t b) {
    a = find(a), b = find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);  // the smallest index is the root
  }

 private:
  std::vector<std::size_t> parent_;
};

struct HalfEdge {
  std::uint32_t lo, hi;  // the undirected edge
  std::uint32_t face;
  std::uint8_t corner;  // the edge runs from corner to corner+1 of the face
  bool forward;         // true when it runs lo -> hi
};

std::string plural(std::size_t n, const char* one, const char* many) {
  return n == 1 ? std::string(one) : fmt::format("{} {}", n, many);
}

}  // namespace

std::string ValidationReport::summary() const {
  std::string s;
  for (const auto& p : problems) s += (s.empty() ? "" : "; ") + p;
  return s;
}

ValidationReport validate(const TriangleMesh& mesh, const ValidateOptions& options) {
  ValidationReport r;
  const auto& tris = mesh.triangles;
  const std::size_t nf = tris.size();
  r.vertex_count = mesh.vertex_count();
  r.triangle_count = nf;
  r.area_m2 = surface_area(mesh);
  r.volume_m3 = enclosed_volume(mesh);

  // Degenerate (repeated vertex) and duplicated faces are set aside; the topology below is that
  // of the remaining faces, so that a duplicate does not also show up as non-manifold edges.
  std::vector<char> active(nf, 1);
  std::size_t first_degenerate = nf;
  for (std::size_t f = 0; f < nf; ++f) {
    const Triangle& t = tris[f];
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) {
      active[f] = 0;
      ++r.degenerate_face_count;
      first_degenerate = std::min(first_degenerate, f);
    }
  }
  for (std::size_t f : detail::collinear_faces(mesh)) {
    ++r.degenerate_face_count;  // still part of the topology: it is a valid triangle, of zero area
    first_degenerate = std::min(first_degenerate, f);
  }
  if (r.degenerate_face_count > 0) {
    const Triangle& t = tris[first_degenerate];
    const bool repeated = t[0] == t[1] || t[1] == t[2] || t[2] == t[0];
    r.problems.push_back(fmt::format("{} face {} ({}vertices {}, {}, {})",
                                     r.degenerate_face_count == 1
                                         ? std::string("degenerate")
                                         : fmt::format("{} degenerate faces, first", r.degenerate_face_count),
                                     first_degenerate, repeated ? "" : "collinear ", t[0], t[1], t[2]));
  }
  {
    std::vector<std::pair<Triangle, std::uint32_t>> sorted;
    sorted.reserve(nf);
    for (std::size_t f = 0; f < nf; ++f) {
      if (!active[f]) continue;
      Triangle t = tris[f];
      std::sort(t.begin(), t.end());
      sorted.emplace_back(t, static_cast<std::uint32_t>(f));
    }
    std::sort(sorted.begin(), sorted.end());
    std::pair<std::size_t, std::size_t> first{nf, nf};  // (duplicate, original)
    for (std::size_t i = 1; i < sorted.size(); ++i) {
      if (sorted[i].first != sorted[i - 1].first) continue;
      std::size_t j = i - 1;
      while (j > 0 && sorted[j - 1].first == sorted[i].first) --j;
      active[sorted[i].second] = 0;
      ++r.duplicated_face_count;
      if (sorted[i].second < first.first) first = {sorted[i].second, sorted[j].second};
    }
    if (r.duplicated_face_count > 0) {
      r.problems.push_back(fmt::format("{} face {} (same vertices as face {})",
                                       r.duplicated_face_count == 1
                                           ? std::string("duplicated")
                                           : fmt::format("{} duplicated faces, first", r.duplicated_face_count),
                                       first.first, first.second));
    }
  }

  // Half-edges sorted by undirected edge, then face: each run is one edge and its faces.
  std::vector<HalfEdge> he;
  he.reserve(3 * nf);
  for (std::size_t f = 0; f < nf; ++f) {
    if (!active[f]) continue;
    for (std::uint8_t k = 0; k < 3; ++k) {
      const std::uint32_t a = tris[f][k], b = tris[f][(k + 1) % 3];
      he.push_back({std::min(a, b), std::max(a, b), static_cast<std::uint32_t>(f), k, a < b});
    }
  }
  std::sort(he.begin(), he.end(), [](const HalfEdge& x, const HalfEdge& y) {
    return std::tie(x.lo, x.hi, x.face, x.corner) < std::tie(y.lo, y.hi, y.face, y.corner);
  });

  UnionFind faces(nf), corners(3 * nf), border_vertices(mesh.vertex_count());
  struct Link {
    std::uint32_t a, b;
    bool same_direction;
  };
  std::vector<Link> links;
  links.reserve(3 * nf / 2);
  std::vector<char> face_on_border(nf, 0);
  const HalfEdge* first_border = nullptr;
  const HalfEdge* first_non_manifold = nullptr;
  std::size_t first_non_manifold_count = 0;
  for (std::size_t i = 0; i < he.size();) {
    std::size_t j = i + 1;
    while (j < he.size() && he[j].lo == he[i].lo && he[j].hi == he[i].hi) ++j;
    const std::size_t count = j - i;
    ++r.edge_count;
    for (std::size_t k = i + 1; k < j; ++k) {
      faces.unite(he[i].face, he[k].face);
      // The faces around this edge belong to one fan at each of its two endpoints.
      for (std::uint32_t v : {he[i].lo, he[i].hi}) {
        auto corner_of = [&](const HalfEdge& h) {
          const Triangle& t = tris[h.face];
          const std::uint8_t c = t[h.corner] == v ? h.corner : static_cast<std::uint8_t>((h.corner + 1) % 3);
          return 3 * std::size_t{h.face} + c;
        };
        corners.unite(corner_of(he[i]), corner_of(he[k]));
      }
    }
    if (count == 1) {
      ++r.boundary_edge_count;
      border_vertices.unite(he[i].lo, he[i].hi);
      face_on_border[he[i].face] = 1;
      if (first_border == nullptr) first_border = &he[i];
    } else if (count == 2) {
      links.push_back({he[i].face, he[i + 1].face, he[i].forward == he[i + 1].forward});
    } else {
      ++r.non_manifold_edge_count;
      for (std::size_t k = i; k < j; ++k) face_on_border[he[k].face] = 1;
      if (first_non_manifold == nullptr) first_non_manifold = &he[i], first_non_manifold_count = count;
    }
    i = j;
  }
  if (first_non_manifold != nullptr) {
    std::string shared;
    for (std::size_t k = 0; k < first_non_manifold_count; ++k) {
      shared += fmt::format("{}{}", k == 0 ? "" : ", ", first_non_manifold[k].face);
    }
    r.problems.push_back(fmt::format("{} {}-{} (shared by faces {})",
                                     r.non_manifold_edge_count == 1
                                         ? std::string("non-manifold edge")
                                         : fmt::format("{} non-manifold edges, first", r.non_manifold_edge_count),
                                     first_non_manifold->lo, first_non_manifold->hi, shared));
  }

  // Vertices: isolated ones, and those whose corners fall into more than one fan.
  {
    constexpr std::size_t none = ~std::size_t{0};
    std::vector<std::size_t> fan(mesh.vertex_count(), none);
    std::vector<char> counted(mesh.vertex_count(), 0);
    std::size_t first_vertex = none;
    for (std::size_t f = 0; f < nf; ++f) {
      if (!active[f]) continue;
      for (std::size_t k = 0; k < 3; ++k) {
        const std::uint32_t v = tris[f][k];
        const std::size_t root = corners.find(3 * f + k);
        if (fan[v] == none) {
          fan[v] = root;
        } else if (fan[v] != root && !counted[v]) {
          counted[v] = 1;
          ++r.non_manifold_vertex_count;
          first_vertex = std::min<std::size_t>(first_vertex, v);
        }
      }
    }
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) r.isolated_vertex_count += fan[v] == none;
    if (r.non_manifold_vertex_count > 0) {
      r.problems.push_back(fmt::format("{} {} (its faces meet only at the vertex)",
                                       r.non_manifold_vertex_count == 1 ? std::string("non-manifold vertex")
                                                                        : fmt::format("{} non-manifold vertices, first",
                                                                                      r.non_manifold_vertex_count),
                                       first_vertex));
    }
  }

  if (r.boundary_edge_count > 0) {
    std::vector<std::size_t> roots;
    for (std::size_t i = 0; i < he.size();) {
      std::size_t j = i + 1;
      while (j < he.size() && he[j].lo == he[i].lo && he[j].hi == he[i].hi) ++j;
      if (j - i == 1) roots.push_back(border_vertices.find(he[i].lo));
      i = j;
    }
    std::sort(roots.begin(), roots.end());
    r.hole_count = static_cast<std::size_t>(std::unique(roots.begin(), roots.end()) - roots.begin());
    r.problems.push_back(fmt::format("open surface: {} ({}), first at edge {}-{} of face {}",
                                     plural(r.hole_count, "1 hole", "holes"),
                                     plural(r.boundary_edge_count, "1 boundary edge", "boundary edges"),
                                     first_border->lo, first_border->hi, first_border->face));
  }

  // Orientation: propagate across manifold edges (breadth-first, in face order).
  std::vector<std::uint32_t> adjacency_start(nf + 1, 0);
  for (const Link& l : links) ++adjacency_start[l.a + 1], ++adjacency_start[l.b + 1];
  std::partial_sum(adjacency_start.begin(), adjacency_start.end(), adjacency_start.begin());
  std::vector<std::pair<std::uint32_t, bool>> adjacency(adjacency_start.back());
  {
    std::vector<std::uint32_t> fill(adjacency_start.begin(), adjacency_start.end() - 1);
    for (const Link& l : links) {
      adjacency[fill[l.a]++] = {l.b, l.same_direction};
      adjacency[fill[l.b]++] = {l.a, l.same_direction};
    }
  }
  std::vector<signed char> orientation(nf, 0);
  std::size_t first_misoriented = nf, first_non_orientable = nf, first_inside_out = nf;
  double inside_out_volume = 0.0;
  std::vector<std::uint32_t> queue;
  for (std::size_t seed = 0; seed < nf; ++seed) {
    if (!active[seed] || orientation[seed] != 0) continue;
    queue.assign(1, static_cast<std::uint32_t>(seed));
    orientation[seed] = 1;
    bool region_open = false;
    for (std::size_t q = 0; q < queue.size(); ++q) {
      const std::uint32_t f = queue[q];
      region_open |= face_on_border[f] != 0;
      for (std::uint32_t k = adjacency_start[f]; k < adjacency_start[f + 1]; ++k) {
        const auto [g, same] = adjacency[k];
        const signed char want = static_cast<signed char>(same ? -orientation[f] : orientation[f]);
        if (orientation[g] == 0) {
          orientation[g] = want;
          queue.push_back(g);
        } else if (orientation[g] != want && r.orientable) {
          r.orientable = false;
          first_non_orientable = g;
        }
      }
    }
    // The minority is misoriented; on a tie, the faces that disagree with the region's first face.
    std::size_t flipped = 0;
    for (std::uint32_t f : queue) flipped += orientation[f] < 0;
    const signed char majority = 2 * flipped > queue.size() ? -1 : 1;
    double six_volume = 0.0;
    for (std::uint32_t f : queue) {
      if (orientation[f] != majority) {
        ++r.misoriented_face_count;
        first_misoriented = std::min<std::size_t>(first_misoriented, f);
      }
      const auto& p = mesh.vertices;
      const Triangle& t = tris[f];
      six_volume += majority * p[t[0]].dot(p[t[1]].cross(p[t[2]]));
    }
    if (!region_open && six_volume < 0.0) {
      if (++r.inside_out_component_count == 1) first_inside_out = seed, inside_out_volume = six_volume / 6.0;
    }
  }
  if (!r.orientable) {
    r.problems.push_back(
        fmt::format("non-orientable surface: no consistent orientation exists around face {}", first_non_orientable));
  } else if (r.misoriented_face_count > 0) {
    r.problems.push_back(r.misoriented_face_count == 1
                             ? fmt::format("face {} is oriented against its neighbours", first_misoriented)
                             : fmt::format("{} faces are oriented against their neighbours, first face {}",
                                           r.misoriented_face_count, first_misoriented));
  }

  // Components through shared edges.
  {
    std::vector<std::size_t> roots;
    for (std::size_t f = 0; f < nf; ++f) {
      if (active[f]) roots.push_back(faces.find(f));
    }
    std::sort(roots.begin(), roots.end());
    r.component_count = static_cast<std::size_t>(std::unique(roots.begin(), roots.end()) - roots.begin());
  }
  if (r.inside_out_component_count > 0) {
    r.problems.push_back(fmt::format(
        "inside out: {} encloses a negative volume ({:.4g} mL)",
        r.component_count == 1 ? std::string("the surface") : fmt::format("the component of face {}", first_inside_out),
        inside_out_volume * 1e6));
  }

  if (r.closed() && r.manifold() && r.orientable) {
    std::vector<char> used(mesh.vertex_count(), 0);
    std::size_t used_count = 0, active_count = 0;
    for (std::size_t f = 0; f < nf; ++f) {
      if (!active[f]) continue;
      ++active_count;
      for (std::uint32_t v : tris[f]) used_count += !used[v], used[v] = 1;
    }
    const long long chi = static_cast<long long>(used_count) - static_cast<long long>(r.edge_count) +
                          static_cast<long long>(active_count);
    r.genus = static_cast<int>((2 * static_cast<long long>(r.component_count) - chi) / 2);
  }

  if (options.check_self_intersections) {
    std::vector<std::size_t> checked;
    checked.reserve(nf);
    const auto collinear = detail::collinear_faces(mesh);
    std::vector<char> skip(nf, 0);
    for (std::size_t f : collinear) skip[f] = 1;
    for (std::size_t f = 0; f < nf; ++f) {
      if (active[f] && !skip[f]) checked.push_back(f);
    }
    const auto pairs = detail::self_intersecting_pairs(mesh, checked, 1000);
    r.self_intersection_count = pairs.size();
    if (!pairs.empty()) {
      r.problems.push_back(
          pairs.size() == 1
              ? fmt::format("self-intersection: faces {} and {} intersect", pairs[0].first, pairs[0].second)
              : fmt::format("self-intersections: {}{} pairs of faces intersect, first faces {} and {}",
                            pairs.size() >= 1000 ? "at least " : "", pairs.size(), pairs[0].first, pairs[0].second));
    }
  }
  return r;
}

MeshQuality measure_quality(const TriangleMesh& mesh) {
  MeshQuality q;
  if (mesh.triangles.empty()) return q;
  const auto edges = unique_edges(mesh.triangles);
  q.min_edge_m = std::numeric_limits<double>::infinity();
  double sum = 0.0;
  for (const auto& e : edges) {
    const double len = (mesh.vertices[e[0]] - mesh.vertices[e[1]]).norm();
    q.min_edge_m = std::min(q.min_edge_m, len);
    q.max_edge_m = std::max(q.max_edge_m, len);
    sum += len;
  }
  q.mean_edge_m = sum / static_cast<double>(edges.size());
  q.min_angle_deg = 180.0;
  double sum_min = 0.0;
  std::size_t below = 0;
  for (const Triangle& t : mesh.triangles) {
    double smallest = 180.0;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d a = mesh.vertices[t[(k + 1) % 3]] - mesh.vertices[t[k]];
      const Eigen::Vector3d b = mesh.vertices[t[(k + 2) % 3]] - mesh.vertices[t[k]];
      const double angle = std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / std::numbers::pi;
      smallest = std::min(smallest, angle);
      q.max_angle_deg = std::max(q.max_angle_deg, angle);
    }
    q.min_angle_deg = std::min(q.min_angle_deg, smallest);
    sum_min += smallest;
    below += smallest < 30.0;
  }
  q.mean_min_angle_deg = sum_min / static_cast<double>(mesh.triangles.size());
  q.fraction_below_30_deg = static_cast<double>(below) / static_cast<double>(mesh.triangles.size());
  return q;
}

void require_lung_sized(const std::string& name, const TriangleMesh& surface, const std::string& unit_key) {
  if (surface.vertices.empty()) return;
  const auto [lo, hi] = bounding_box(surface.vertices);
  const Eigen::Vector3d size = hi - lo;
  Eigen::Index axis = 0;
  const double largest = size.maxCoeff(&axis);
  if (largest <= 1.0) return;
  throw InputError(fmt::format("{}: the surface spans {:.4g} m along {} ({:.4g} x {:.4g} x {:.4g} m); expected a lung, "
                               "at most 1 m across (is {} right, or a vertex damaged?)",
                               name, largest, "xyz"[axis], size.x(), size.y(), size.z(), unit_key));
}

}  // namespace pneuma::mesh
