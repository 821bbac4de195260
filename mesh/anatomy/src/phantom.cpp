// The lung phantom: an implicit surface per lung, sampled along the rays of a geodesic sphere.
// Dimensions in metres, in the frame documented in phantom.h. Anatomical proportions from
// standard adult values: lung height ~25 cm, transverse ~10-12 cm, antero-posterior ~15-17 cm
// at the base, diaphragmatic dome ~5 cm, right dome ~2 cm higher (liver), heart left of the
// midline on the left dome.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "pneuma/core/error.h"
#include "pneuma/core/tsan.h"
#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/mesh/geometry/vertex_neighbours.h"

namespace pneuma::mesh {
namespace {

// One lung in its own frame: u lateral (away from the midline), a anterior, z up.
struct LungShape {
  double side;                   // x = side * u: -1 right, +1 left
  double apex_z;                 // height of the apex
  double taper_z;                // the body narrows above this height
  double centre_u0, centre_u1;   // body axis, lateral, at taper_z and at the apex
  double centre_a0, centre_a1;   // body axis, anterior, at taper_z and at the apex
  double semi_u;                 // lateral half-width of the body
  double semi_front, semi_back;  // anterior / posterior half-depth
  double p_front, p_back;        // superellipse exponents: < 2 sharpens the anterior border
  double medial_u;               // mediastinal surface, distance from the midline
  double dome_height, dome_u, dome_a, dome_width_u, dome_width_a;  // diaphragm (Gaussian dome)
  double base_rise;             // how much higher the base is at the front than at the back
  Eigen::Vector3d star_centre;  // (u, a, z): every ray from here meets the surface once
};

// The heart, in patient coordinates with a = anterior: an ellipsoid left of the midline.
struct Heart {
  Eigen::Vector3d centre{0.022, 0.045, 0.07};  // x, a, z
  Eigen::Vector3d semi_axes{0.062, 0.05, 0.06};
};

const LungShape kRight{.side = -1.0,
                       .apex_z = 0.261,
                       .taper_z = 0.04,
                       .centre_u0 = 0.075,
                       .centre_u1 = 0.042,
                       .centre_a0 = 0.0,
                       .centre_a1 = -0.012,
                       .semi_u = 0.0455,
                       .semi_front = 0.064,
                       .semi_back = 0.078,
                       .p_front = 1.7,
                       .p_back = 2.4,
                       .medial_u = 0.02,
                       .dome_height = 0.05,
                       .dome_u = 0.072,
                       .dome_a = 0.008,
                       .dome_width_u = 0.05,
                       .dome_width_a = 0.065,
                       .base_rise = 0.035,
                       .star_centre = {0.075, -0.012, 0.125}};
const LungShape kLeft{.side = +1.0,
                      .apex_z = 0.266,
                      .taper_z = 0.04,
                      .centre_u0 = 0.075,
                      .centre_u1 = 0.042,
                      .centre_a0 = 0.0,
                      .centre_a1 = -0.014,
                      .semi_u = 0.043,
                      .semi_front = 0.062,
                      .semi_back = 0.078,
                      .p_front = 1.7,
                      .p_back = 2.4,
                      .medial_u = 0.02,
                      .dome_height = 0.038,
                      .dome_u = 0.072,
                      .dome_a = 0.006,
                      .dome_width_u = 0.048,
                      .dome_width_a = 0.065,
                      .base_rise = 0.032,
                      .star_centre = {0.072, -0.008, 0.12}};
const Heart kHeart{};

// The shapes above leave their lowest point this far above z = 0; the output is lowered by it
// so that z = 0 is the bottom of the bases (phantom.h).
constexpr double kLowestPoint = 0.0155;

// Polynomial smooth maximum (Quilez): equals max(a, b) when they differ by more than k, and
// rounds the crease between the two surfaces over a width of about k.
double smooth_max(double a, double b, double k) {
  const double h = std::max(k - std::abs(a - b), 0.0) / k;
  return std::max(a, b) + 0.25 * k * h * h;
}

// Negative inside the lung, positive outside, roughly a distance in metres near the surface.
double lung_field(const LungShape& s, const Eigen::Vector3d& p) {
  const double u = s.side * p.x(), a = -p.y(), z = p.z();
  if (z >= s.apex_z) return z - s.apex_z + 1e-4;
  // Body: superelliptic cross-sections, full size below taper_z, shrinking to the apex as
  // sqrt(1 - t^2) (an elliptic profile: convex costal border, rounded apex). The axis leans
  // medially and posteriorly as t^2, so that it leaves the base without a crease.
  const double t = std::clamp((z - s.taper_z) / (s.apex_z - s.taper_z), 0.0, 1.0);
  const double scale = std::sqrt(std::max(1.0 - t * t, 0.0));
  if (scale < 1e-6) return 1e-4;
  const double cu = s.centre_u0 + (s.centre_u1 - s.centre_u0) * t * t;
  const double ca = s.centre_a0 + (s.centre_a1 - s.centre_a0) * t * t;
  const bool front = a > ca;
  // The exponent changes smoothly from back to front (a step would put a crease wherever a
  // smooth_max below blends across the plane a = ca).
  const double w = std::clamp((a - ca) / 0.02, -1.0, 1.0);
  const double blend = 0.5 + w * (0.75 - 0.25 * w * w);  // smoothstep from -1 to 1
  const double exponent = s.p_back + (s.p_front - s.p_back) * blend;
  const double xu = std::abs(u - cu) / (s.semi_u * scale);
  const double xa = std::abs(a - ca) / ((front ? s.semi_front : s.semi_back) * scale);
  const double level = std::pow(xu, exponent) + std::pow(xa, exponent);
  double f = (level - 1.0) * s.semi_u * scale / exponent;
  // Mediastinal surface.
  f = smooth_max(f, s.medial_u - u, 0.015);
  // Diaphragmatic base: a dome under the lung, the base rising towards the front.
  const double du = (u - s.dome_u) / s.dome_width_u, da = (a - s.dome_a) / s.dome_width_a;
  const double base =
      s.dome_height * std::exp(-(du * du + da * da)) + s.base_rise * (a + s.semi_back) / (s.semi_back + s.semi_front);
  f = smooth_max(f, base - z, 0.015);
  // Heart: cardiac impression (both lungs), cardiac notch (left lung's anterior border).
  const Eigen::Vector3d q((p.x() - kHeart.centre.x()) / kHeart.semi_axes.x(),
                          (a - kHeart.centre.y()) / kHeart.semi_axes.y(),
                          (z - kHeart.centre.z()) / kHeart.semi_axes.z());
  f = smooth_max(f, (1.0 - q.norm()) * kHeart.semi_axes.minCoeff(), 0.03);
  return f;
}

// In the shapes' own frame (before lowering by kLowestPoint).
Eigen::Vector3d star_centre(const LungShape& s) {
  return {s.side * s.star_centre.x(), -s.star_centre.y(), s.star_centre.z()};
}

// The distance along the ray c + t d to the surface, by the Illinois variant of regula falsi
// on a bracket [lo, hi] with field(lo) < 0 < field(hi).
double ray_root(const LungShape& s, const Eigen::Vector3d& c, const Eigen::Vector3d& d, double lo, double hi) {
  double flo = lung_field(s, c + lo * d), fhi = lung_field(s, c + hi * d);
  int side = 0;
  for (int i = 0; i < 60 && hi - lo > 1e-10; ++i) {
    const double t = (lo * fhi - hi * flo) / (fhi - flo);
    const double ft = lung_field(s, c + t * d);
    if (ft > 0.0) {
      hi = t, fhi = ft;
      if (side == -1) flo *= 0.5;
      side = -1;
    } else {
      lo = t, flo = ft;
      if (side == +1) fhi *= 0.5;
      side = +1;
    }
    if (ft == 0.0) return t;
  }
  return 0.5 * (lo + hi);
}

constexpr double kFarOutside = 0.35;  // farther than any point of the lung from its centre

// Around a previous distance t0: widen a bracket until it holds the surface, then solve.
double ray_root_near(const LungShape& s, const Eigen::Vector3d& c, const Eigen::Vector3d& d, double t0) {
  double step = 1e-3;
  double lo = t0, hi = t0;
  if (lung_field(s, c + t0 * d) < 0.0) {
    do hi = std::min(hi + step, kFarOutside), step *= 2.0;
    while (hi < kFarOutside && lung_field(s, c + hi * d) < 0.0);
  } else {
    do lo = std::max(lo - step, 0.0), step *= 2.0;
    while (lo > 0.0 && lung_field(s, c + lo * d) >= 0.0);
  }
  return ray_root(s, c, d, lo, hi);
}

// Class I geodesic sphere of frequency n: each icosahedron face split into n^2 triangles,
// vertices shared along edges and corners; unit vectors.
TriangleMesh geodesic_sphere(int n) {
  const TriangleMesh ico = make_icosphere(1.0, 0);
  const std::size_t nn = static_cast<std::size_t>(n);
  TriangleMesh m;
  m.vertices = ico.vertices;  // the 12 corners
  // Edges of the icosahedron, numbered in sorted order; points k = 1..n-1 from the lower corner.
  const auto edges = unique_edges(ico.triangles);
  auto edge_point = [&](std::uint32_t from, std::uint32_t to, std::size_t k) -> std::uint32_t {
    const std::array<std::uint32_t, 2> key{std::min(from, to), std::max(from, to)};
    const auto e = static_cast<std::size_t>(std::lower_bound(edges.begin(), edges.end(), key) - edges.begin());
    const std::size_t along = from < to ? k : nn - k;
    return static_cast<std::uint32_t>(12 + e * (nn - 1) + along - 1);
  };
  m.vertices.resize(12 + edges.size() * (nn - 1));
  for (std::size_t e = 0; e < edges.size(); ++e) {
    const Eigen::Vector3d& p = ico.vertices[edges[e][0]];
    const Eigen::Vector3d& q = ico.vertices[edges[e][1]];
    for (std::size_t k = 1; k < nn; ++k) {
      m.vertices[12 + e * (nn - 1) + k - 1] = (p + (q - p) * static_cast<double>(k) / n).normalized();
    }
  }
  std::vector<std::uint32_t> grid((nn + 1) * (nn + 1));
  auto at = [&](std::size_t i, std::size_t j) -> std::uint32_t& { return grid[i * (nn + 1) + j]; };
  m.triangles.reserve(20 * nn * nn);
  for (const Triangle& f : ico.triangles) {
    const Eigen::Vector3d &A = ico.vertices[f[0]], &B = ico.vertices[f[1]], &C = ico.vertices[f[2]];
    for (std::size_t i = 0; i <= nn; ++i) {
      for (std::size_t j = 0; i + j <= nn; ++j) {
        std::uint32_t v;
        if (i == 0 && j == 0) v = f[0];
        else if (i == nn) v = f[1];
        else if (j == nn) v = f[2];
        else if (j == 0) v = edge_point(f[0], f[1], i);
        else if (i == 0) v = edge_point(f[0], f[2], j);
        else if (i + j == nn) v = edge_point(f[1], f[2], j);
        else {
          v = static_cast<std::uint32_t>(m.vertices.size());
          m.vertices.push_back(
              (A + (B - A) * static_cast<double>(i) / n + (C - A) * static_cast<double>(j) / n).normalized());
        }
        at(i, j) = v;
      }
    }
    for (std::size_t i = 0; i < nn; ++i) {
      for (std::size_t j = 0; i + j < nn; ++j) {
        m.triangles.push_back({at(i, j), at(i + 1, j), at(i, j + 1)});
        if (i + j + 1 < nn) m.triangles.push_back({at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)});
      }
    }
  }
  return m;
}

TriangleMesh sample_lung(const LungShape& s, int n, int passes) {
  TriangleMesh m = geodesic_sphere(n);
  const Eigen::Vector3d c = star_centre(s);
  // Each vertex's root depends only on its own ray (and, in a pass, on the previous pass's
  // positions), so the vertices are solved on every thread, each writing its own slot: the same
  // bits at any thread count.
  auto each_vertex = [&](const auto& body) {
    const tsan::Region region;  // TBB's own synchronisation, told to ThreadSanitizer (core/tsan.h)
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, m.vertex_count(), 2048),
                      region.wrap([&](const tbb::blocked_range<std::size_t>& range) {
                        for (std::size_t v = range.begin(); v < range.end(); ++v) body(v);
                      }));
    region.join();
  };
  each_vertex(
      [&](std::size_t v) { m.vertices[v] = c + ray_root(s, c, m.vertices[v], 0.0, kFarOutside) * m.vertices[v]; });
  if (passes <= 0) return m;
  const VertexNeighbours around(m);  // rows ascending: a deterministic order
  std::vector<Eigen::Vector3d> next(m.vertex_count());
  for (int pass = 0; pass < passes; ++pass) {
    each_vertex([&](std::size_t v) {
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (const std::uint32_t w : around(v)) mean += m.vertices[w];
      mean /= static_cast<double>(around(v).size());
      const Eigen::Vector3d moved = m.vertices[v] + 0.5 * (mean - m.vertices[v]);
      const Eigen::Vector3d d = (moved - c).normalized();
      next[v] = c + ray_root_near(s, c, d, (moved - c).norm()) * d;
    });
    std::swap(m.vertices, next);
  }
  return m;
}

std::vector<const LungShape*> shapes(std::optional<Lung> lung) {
  if (!lung) return {&kRight, &kLeft};
  return {*lung == Lung::right ? &kRight : &kLeft};
}

// The lung's area, from a fixed, coarse sampling (frequency 48, within 0.5% of the limit).
double reference_area(const LungShape& s) { return surface_area(sample_lung(s, 48, 0)); }

void check_edge(double h) {
  if (!(h > 0.0) || !std::isfinite(h)) throw ValueError("phantom: the target edge length must be positive");
}

int frequency_for(const LungShape& s, double h) {
  const double n = std::sqrt(reference_area(s) / (5.0 * std::sqrt(3.0) * h * h));
  if (n > 10000.0) throw ValueError("phantom: the target edge length is too small (over 2^31 triangles)");
  return std::max(4, static_cast<int>(std::lround(n)));
}

}  // namespace

int phantom_frequency(Lung lung, double edge_length_m) {
  check_edge(edge_length_m);
  return frequency_for(*shapes(lung)[0], edge_length_m);
}

Eigen::Vector3d phantom_centre(Lung lung) {
  return star_centre(*shapes(lung)[0]) - Eigen::Vector3d(0.0, 0.0, kLowestPoint);
}

double predicted_phantom_triangles(std::optional<Lung> lung, double edge_length_m) {
  check_edge(edge_length_m);
  double total = 0.0;
  for (const LungShape* s : shapes(lung))
    total += 4.0 * reference_area(*s) / (std::sqrt(3.0) * edge_length_m * edge_length_m);
  return total;
}

TriangleMesh make_lung_phantom(const PhantomOptions& options) {
  check_edge(options.edge_length_m);
  TriangleMesh out;
  for (const LungShape* s : shapes(options.lung)) {
    TriangleMesh one = sample_lung(*s, frequency_for(*s, options.edge_length_m), options.relaxation_passes);
    const auto offset = static_cast<std::uint32_t>(out.vertices.size());
    out.vertices.insert(out.vertices.end(), one.vertices.begin(), one.vertices.end());
    for (Triangle t : one.triangles) out.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  }
  for (auto& v : out.vertices) v.z() -= kLowestPoint;
  renumber_vertices_by_first_use(out);  // the numbering read_mesh() gives back
  return out;
}

}  // namespace pneuma::mesh
