// The lungs' normal surface motion extended smoothly into the body, faded with the distance from
// them (body_motion.h).
#include "pneuma/model/body_motion.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <utility>

#include "pneuma/core/error.h"
#include "pneuma/core/keyed_file.h"
#include "pneuma/core/parallel.h"
#include "pneuma/core/sha256.h"
#include "pneuma/core/tsan.h"
#include "pneuma/image/label_map.h"
#include "pneuma/model/model.h"

namespace pneuma::model {
namespace {

// A frame's key for the Cursors that keep its values: unique per frame made in this process.
std::uint64_t next_frame_id() {
  static std::atomic<std::uint64_t> next{1};
  return next.fetch_add(1, std::memory_order_relaxed);
}

// The cell of one axis holding `f` (in cells from the first node) among `n` nodes, and the fraction
// within it; false outside the lattice (Lattice::cell, one axis).
bool axis_cell(double f, std::size_t n, std::size_t& base, double& t) {
  if (!(f >= 0.0) || !(f <= static_cast<double>(n - 1))) return false;
  base = std::min(static_cast<std::size_t>(f), n - 2);
  t = f - static_cast<double>(base);
  return true;
}

bool same_bits(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }

// A regular axis-aligned grid of nodes (LPS), i fastest.
struct Lattice {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  double h = 1.0;
  std::array<std::size_t, 3> n{0, 0, 0};

  Lattice(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double spacing) : origin(lo), h(spacing) {
    for (int a = 0; a < 3; ++a)
      n[static_cast<std::size_t>(a)] = static_cast<std::size_t>(std::ceil((hi[a] - lo[a]) / h)) + 1;
  }
  Lattice(const Eigen::Vector3d& first, double spacing, const std::array<std::size_t, 3>& nodes)
      : origin(first), h(spacing), n(nodes) {}
  std::size_t count() const { return n[0] * n[1] * n[2]; }
  std::size_t at(std::size_t i, std::size_t j, std::size_t k) const { return i + n[0] * (j + n[1] * k); }
  Eigen::Vector3d node(std::size_t i, std::size_t j, std::size_t k) const {
    return origin + h * Eigen::Vector3d(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k));
  }
  // The cell holding `x` and the fractions within it; false outside the lattice.
  bool cell(const Eigen::Vector3d& x, std::array<std::size_t, 3>& base, Eigen::Vector3d& t) const {
    const Eigen::Vector3d f = (x - origin) / h;
    for (std::size_t a = 0; a < 3; ++a) {
      const double fa = f[static_cast<Eigen::Index>(a)];
      if (!(fa >= 0.0) || !(fa <= static_cast<double>(n[a] - 1))) return false;
      base[a] = std::min(static_cast<std::size_t>(fa), n[a] - 2);
      t[static_cast<Eigen::Index>(a)] = fa - static_cast<double>(base[a]);
    }
    return true;
  }
  // Calls visit(node index, trilinear weight) for the 8 nodes around `x` (none outside).
  template <typename Visit>
  void corners(const Eigen::Vector3d& x, Visit visit) const {
    std::array<std::size_t, 3> b{};
    Eigen::Vector3d t;
    if (!cell(x, b, t)) return;
    for (std::size_t c = 0; c < 8; ++c) {
      const std::size_t di = c & 1u, dj = (c >> 1) & 1u, dk = (c >> 2) & 1u;
      const double w = (di ? t.x() : 1.0 - t.x()) * (dj ? t.y() : 1.0 - t.y()) * (dk ? t.z() : 1.0 - t.z());
      visit(at(b[0] + di, b[1] + dj, b[2] + dk), w);
    }
  }
};

// An unnormalised Gaussian blur (peak 1, truncated at 3 sigma) of a lattice's values, along each
// axis in turn: every node gets the sum of its neighbours' values times exp(-r^2 / 2 sigma^2).
void blur(std::vector<double>& v, const Lattice& g, double sigma_cells) {
  const auto radius = static_cast<std::ptrdiff_t>(std::ceil(3.0 * sigma_cells));
  std::vector<double> kernel;
  for (std::ptrdiff_t r = -radius; r <= radius; ++r)
    kernel.push_back(std::exp(-0.5 * static_cast<double>(r * r) / (sigma_cells * sigma_cells)));
  std::vector<double> line;
  for (std::size_t axis = 0; axis < 3; ++axis) {
    const std::size_t stride = axis == 0 ? 1 : axis == 1 ? g.n[0] : g.n[0] * g.n[1];
    const auto length = static_cast<std::ptrdiff_t>(g.n[axis]);
    line.resize(g.n[axis]);
    for (std::size_t start = 0; start < v.size(); ++start) {
      // One line per node whose coordinate along `axis` is 0.
      if ((start / stride) % g.n[axis] != 0) continue;
      for (std::ptrdiff_t i = 0; i < length; ++i)
        line[static_cast<std::size_t>(i)] = v[start + static_cast<std::size_t>(i) * stride];
      for (std::ptrdiff_t i = 0; i < length; ++i) {
        double sum = 0.0;
        for (std::ptrdiff_t r = std::max(-radius, -i); r <= radius && i + r < length; ++r)
          sum += kernel[static_cast<std::size_t>(r + radius)] * line[static_cast<std::size_t>(i + r)];
        v[start + static_cast<std::size_t>(i) * stride] = sum;
      }
    }
  }
}

// The squared Euclidean distance transform of f (Felzenszwalb and Huttenlocher): per node, the
// least |p - q|^2 + f(q) over nodes q, in squared lattice units; f is infinite where no seed is.
void distance_transform(std::vector<double>& f, const Lattice& g) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::vector<double> line, out, z;
  std::vector<std::ptrdiff_t> root;  // the parabolas of the lower envelope, left to right
  for (std::size_t axis = 0; axis < 3; ++axis) {
    const std::size_t stride = axis == 0 ? 1 : axis == 1 ? g.n[0] : g.n[0] * g.n[1];
    const std::size_t length = g.n[axis];
    line.resize(length);
    out.resize(length);
    z.resize(length + 1);
    root.resize(length);
    for (std::size_t start = 0; start < f.size(); ++start) {
      if ((start / stride) % length != 0) continue;  // one line per node at coordinate 0 along `axis`
      for (std::size_t i = 0; i < length; ++i) line[i] = f[start + i * stride];
      std::ptrdiff_t k = -1;
      for (std::size_t q = 0; q < length; ++q) {
        if (line[q] == kInf) continue;
        const auto qd = static_cast<double>(q);
        double s = -kInf;
        while (k >= 0) {
          const auto p = root[static_cast<std::size_t>(k)];
          const auto pd = static_cast<double>(p);
          s = ((line[q] + qd * qd) - (line[static_cast<std::size_t>(p)] + pd * pd)) / (2.0 * qd - 2.0 * pd);
          if (s > z[static_cast<std::size_t>(k)]) break;
          --k;
        }
        ++k;
        root[static_cast<std::size_t>(k)] = static_cast<std::ptrdiff_t>(q);
        z[static_cast<std::size_t>(k)] = k == 0 ? -kInf : s;
        z[static_cast<std::size_t>(k) + 1] = kInf;
      }
      if (k < 0) continue;  // no seed on this line
      std::size_t at = 0;
      for (std::size_t q = 0; q < length; ++q) {
        while (z[at + 1] < static_cast<double>(q)) ++at;
        const double d = static_cast<double>(q) - static_cast<double>(root[at]);
        out[q] = d * d + line[static_cast<std::size_t>(root[at])];
      }
      for (std::size_t i = 0; i < length; ++i) f[start + i * stride] = out[i];
    }
  }
}

double smoothstep(double x) {
  const double t = std::clamp(x, 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

// A surface vertex as the body sees it: where it is, its area, the motion the tissue beside it
// follows (per unit scale), how much of it is diaphragm, and its lung.
struct Sample {
  Eigen::Vector3d at, normal, normal_motion;
  double area = 0.0, diaphragm = 0.0;
  double off_lobes = 0.0;  // the share of the surface here that is not pleura (off_lobes())
  std::size_t lung = 0;
};

// Per vertex of a lung from a label map, how far its surface lies off the lung's labels (0 to 1;
// body_motion.h, "Off the lobes"): the depth along the inward normal at which the label map first
// shows this lung within a voxel (the 3 x 3 x 3 voxels around the point, so that a fissure's or a
// small vessel's gap does not count), 0 up to kOnLobes, 1 from kOffLobes, a smooth step between.
// Empty for a lung without a label map.
constexpr double kOnLobes = 1.5e-3, kOffLobes = 3e-3, kDepthStep = 0.5e-3;
std::vector<double> off_lobes(const Model& model, const LungModel& lung) {
  if (model.label_map == nullptr || lung.label_values.empty()) return {};
  const image::LabelMap& map = *model.label_map;
  const Eigen::Matrix4d to_ijk = map.ijk_to_lps.inverse();
  const auto is_lung = [&](std::int64_t i, std::int64_t j, std::int64_t k) {
    if (i < 0 || j < 0 || k < 0 || i >= static_cast<std::int64_t>(map.size[0]) ||
        j >= static_cast<std::int64_t>(map.size[1]) || k >= static_cast<std::int64_t>(map.size[2]))
      return false;
    const auto at = static_cast<std::size_t>(i) +
                    map.size[0] * (static_cast<std::size_t>(j) + map.size[1] * static_cast<std::size_t>(k));
    return std::find(lung.label_values.begin(), lung.label_values.end(), map.labels[at]) != lung.label_values.end();
  };
  const auto lung_near = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d f = (to_ijk * p.homogeneous()).head<3>();
    const auto i = static_cast<std::int64_t>(std::lround(f.x())), j = static_cast<std::int64_t>(std::lround(f.y())),
               k = static_cast<std::int64_t>(std::lround(f.z()));
    for (std::int64_t c = -1; c <= 1; ++c)
      for (std::int64_t b = -1; b <= 1; ++b)
        for (std::int64_t a = -1; a <= 1; ++a)
          if (is_lung(i + a, j + b, k + c)) return true;
    return false;
  };
  std::vector<double> off(lung.rest.vertices.size(), 0.0);
  for (std::size_t v = 0; v < off.size(); ++v) {
    const Eigen::Vector3d inward = -lung.normals[v].normalized();
    double depth = 0.0;
    while (depth < kOffLobes && !lung_near(lung.rest.vertices[v] + depth * inward)) depth += kDepthStep;
    off[v] = smoothstep((depth - kOnLobes) / (kOffLobes - kOnLobes));
  }
  return off;
}

std::vector<Sample> surface_samples(const Model& model, const Eigen::Vector3d& up) {
  std::vector<Sample> samples;
  for (std::size_t l = 0; l < model.lungs.size(); ++l) {
    const LungModel& lung = model.lungs[l];
    const std::vector<double> area = mesh::vertex_areas(lung.rest);
    const std::vector<double> off = off_lobes(model, lung);
    for (std::size_t v = 0; v < lung.rest.vertices.size(); ++v) {
      const Eigen::Vector3d n = lung.normals[v].normalized();
      const double on_diaphragm = lung.regions.weight.size() == lung.rest.vertices.size()
                                      ? lung.regions.weight[v][static_cast<std::size_t>(mesh::Region::diaphragmatic)]
                                      : std::clamp(-n.dot(up), 0.0, 1.0);
      // Beside the chest wall and the mediastinum the tissue follows the pleura across it (the
      // lung slides along); under the diaphragm it follows the diaphragm (the liver in its dome),
      // and where the surface lies off the lobes (the root at the hilum, filled to close the
      // surface) there is no pleura to slide along: the tissue follows the whole motion too.
      const double whole = off.empty() ? on_diaphragm : std::max(on_diaphragm, off[v]);
      const Eigen::Vector3d& u = lung.unit_displacement[v];
      const Eigen::Vector3d followed = whole * u + (1.0 - whole) * n.dot(u) * n;
      samples.push_back({lung.rest.vertices[v], n, followed, area[v], on_diaphragm, off.empty() ? 0.0 : off[v], l});
    }
  }
  return samples;
}

// K's normalised convolution on the nodes of `fine` (body_motion.h), one Gaussian at a time on a
// lattice of half its sigma, sampled back onto the fine nodes: per lung, the sum over its samples
// of K A_v value_v (`values`, one per sample); and, where `weight` is given, the sums of K A_v and
// of K A_v times the diaphragm's share over all samples.
std::vector<Eigen::Vector3d> convolve(std::size_t lungs, const std::vector<Sample>& samples,
                                      const std::vector<Eigen::Vector3d>& values, const Lattice& fine,
                                      const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double smallest_sigma,
                                      std::vector<double>* weight, std::vector<double>* diaphragm) {
  const std::size_t nodes = fine.count();
  std::vector<Eigen::Vector3d> numerator(lungs * nodes, Eigen::Vector3d::Zero());
  const std::size_t sums = weight != nullptr ? 2 : 0;
  for (int scale = 0; scale < 4; ++scale) {
    const double sigma = smallest_sigma * std::ldexp(1.0, scale);
    const double factor = std::pow(smallest_sigma / sigma, 5.0);
    const Lattice g(lo, hi, 0.5 * sigma);
    std::vector<std::vector<double>> arrays(3 * lungs + sums, std::vector<double>(g.count(), 0.0));
    for (std::size_t v = 0; v < samples.size(); ++v) {
      const Sample& s = samples[v];
      g.corners(s.at, [&](std::size_t node, double w) {
        for (std::size_t c = 0; c < 3; ++c)
          arrays[3 * s.lung + c][node] += w * s.area * values[v][static_cast<Eigen::Index>(c)];
        if (sums == 0) return;
        arrays[3 * lungs][node] += w * s.area;
        arrays[3 * lungs + 1][node] += w * s.area * s.diaphragm;
      });
    }
    core::for_each_index(
        arrays.size(), [&](std::size_t a) { blur(arrays[a], g, 2.0); }, 1);  // each its own
    const tsan::Region region;
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, fine.n[2]), region.wrap([&](const tbb::blocked_range<std::size_t>& r) {
          for (std::size_t k = r.begin(); k != r.end(); ++k)
            for (std::size_t j = 0; j < fine.n[1]; ++j)
              for (std::size_t i = 0; i < fine.n[0]; ++i) {
                const std::size_t node = fine.at(i, j, k);
                // The fine node's 8 corners on this scale's lattice, found once for
                // every array.
                std::array<std::size_t, 8> corner{};
                std::array<double, 8> w{};
                std::size_t n = 0;
                g.corners(fine.node(i, j, k), [&](std::size_t at, double weight_at) {
                  corner[n] = at;
                  w[n++] = weight_at;
                });
                const auto sample = [&](const std::vector<double>& a) {
                  double sum = 0.0;
                  for (std::size_t q = 0; q < n; ++q) sum += w[q] * a[corner[q]];
                  return sum;
                };
                for (std::size_t l = 0; l < lungs; ++l)
                  for (std::size_t c = 0; c < 3; ++c)
                    numerator[l * nodes + node][static_cast<Eigen::Index>(c)] += factor * sample(arrays[3 * l + c]);
                if (sums == 0) continue;
                (*weight)[node] += factor * sample(arrays[3 * lungs]);
                (*diaphragm)[node] += factor * sample(arrays[3 * lungs + 1]);
              }
        }));
    region.join();
  }
  return numerator;
}

// Each lung's field at s = 1 on the nodes of `fine` for K's narrowest Gaussian `sigma` (body_motion.h).
std::vector<std::vector<Eigen::Vector3d>> unit_fields(std::size_t lungs, const std::vector<Sample>& samples,
                                                      const std::vector<double>& distance, const Lattice& fine,
                                                      const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                                                      const BodyMotionOptions& options, double smallest_sigma) {
  const std::size_t nodes = fine.count();
  // E and the diaphragm's share at every fine node.
  std::vector<Eigen::Vector3d> followed(samples.size());
  for (std::size_t v = 0; v < samples.size(); ++v) followed[v] = samples[v].normal_motion;
  std::vector<double> weight(nodes, 0.0), diaphragm(nodes, 0.0);
  const std::vector<Eigen::Vector3d> numerator =
      convolve(lungs, samples, followed, fine, lo, hi, smallest_sigma, &weight, &diaphragm);

  std::vector<std::vector<Eigen::Vector3d>> unit(lungs, std::vector<Eigen::Vector3d>(nodes, Eigen::Vector3d::Zero()));
  std::vector<double> fade(nodes, 0.0);
  const double tiny = 1e-12 * weight[0] + std::numeric_limits<double>::min();
  for (std::size_t k = 0; k < fine.n[2]; ++k) {
    for (std::size_t j = 0; j < fine.n[1]; ++j) {
      for (std::size_t i = 0; i < fine.n[0]; ++i) {
        const std::size_t node = fine.at(i, j, k);
        if (!(weight[node] > tiny)) continue;
        // A node within half a cell of the surface counts as on it (the distance's kink at the
        // pleura is between nodes; trilinear sampling would otherwise fade the pleura itself).
        const double d = std::max(0.0, std::sqrt(distance[node]) * fine.h - 0.5 * fine.h);
        const double share = diaphragm[node] / weight[node];
        const double decay = options.wall_decay_m + (options.abdomen_decay_m - options.wall_decay_m) * share;
        double taper = 1.0;
        const std::array<std::size_t, 3> ijk{i, j, k};
        for (std::size_t a = 0; a < 3; ++a) {
          const double from_face = static_cast<double>(std::min(ijk[a], fine.n[a] - 1 - ijk[a])) * fine.h;
          taper *= smoothstep(from_face / options.taper_m);
        }
        fade[node] = std::exp(-d / decay) * taper / weight[node];
        for (std::size_t l = 0; l < lungs; ++l) unit[l][node] = numerator[l * nodes + node] * fade[node];
      }
    }
  }
  // The body at the pleura moves across it as the lung does (body_motion.h, "At the pleura"):
  // each vertex's shortfall along its normal, blurred by the same K and added, faded as E is.
  for (int round = 0; round < options.pleura_corrections; ++round) {
    std::vector<Eigen::Vector3d> shortfall(samples.size());
    for (std::size_t v = 0; v < samples.size(); ++v) {
      Eigen::Vector3d at = Eigen::Vector3d::Zero();
      fine.corners(samples[v].at, [&](std::size_t node, double w) { at += w * unit[samples[v].lung][node]; });
      const Eigen::Vector3d& n = samples[v].normal;
      const Eigen::Vector3d missing = samples[v].normal_motion - at;
      shortfall[v] = n.dot(missing) * n;
      // Off the lobes the whole of it (no pleura to slide along): w missing + (1 - w) its normal part.
      if (const double w = samples[v].off_lobes; w > 0.0) shortfall[v] += w * (missing - shortfall[v]);
    }
    const std::vector<Eigen::Vector3d> correction =
        convolve(lungs, samples, shortfall, fine, lo, hi, smallest_sigma, nullptr, nullptr);
    for (std::size_t l = 0; l < lungs; ++l)
      for (std::size_t node = 0; node < nodes; ++node) unit[l][node] += correction[l * nodes + node] * fade[node];
  }
  return unit;
}

// 1 at the nodes of `g` outside every lung's rest surface: along each column of nodes (the third
// axis) the surface's crossings, counted with the sign of their normal, give the winding number
// below each node. The column is shifted by a tiny odd fraction of a cell so that it passes
// through no vertex or edge.
std::vector<char> outside_lungs(const Model& model, const Lattice& g) {
  std::vector<std::vector<std::pair<double, int>>> crossings(g.n[0] * g.n[1]);
  const Eigen::Vector2d shift = g.h * Eigen::Vector2d(3.1e-7, 1.7e-7);
  for (const LungModel& lung : model.lungs) {
    for (const mesh::Triangle& t : lung.rest.triangles) {
      const Eigen::Vector3d& a = lung.rest.vertices[t[0]];
      const Eigen::Vector3d& b = lung.rest.vertices[t[1]];
      const Eigen::Vector3d& c = lung.rest.vertices[t[2]];
      const double area2 = (b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y());
      if (area2 == 0.0) continue;  // edge-on to the columns: no column crosses it
      const auto first = [&](int axis) {
        const double least = std::min({a[axis], b[axis], c[axis]}) - g.origin[axis];
        return static_cast<std::ptrdiff_t>(std::ceil(least / g.h));
      };
      const auto last = [&](int axis) {
        const double most = std::max({a[axis], b[axis], c[axis]}) - g.origin[axis];
        return static_cast<std::ptrdiff_t>(std::floor(most / g.h));
      };
      for (std::ptrdiff_t j = std::max<std::ptrdiff_t>(0, first(1) - 1);
           j <= std::min<std::ptrdiff_t>(static_cast<std::ptrdiff_t>(g.n[1]) - 1, last(1) + 1); ++j) {
        for (std::ptrdiff_t i = std::max<std::ptrdiff_t>(0, first(0) - 1);
             i <= std::min<std::ptrdiff_t>(static_cast<std::ptrdiff_t>(g.n[0]) - 1, last(0) + 1); ++i) {
          const Eigen::Vector2d p =
              g.origin.head<2>() + g.h * Eigen::Vector2d(static_cast<double>(i), static_cast<double>(j)) + shift;
          // Barycentric coordinates of the column in the triangle's projection.
          const double wa = ((b.x() - p.x()) * (c.y() - p.y()) - (c.x() - p.x()) * (b.y() - p.y())) / area2;
          const double wb = ((c.x() - p.x()) * (a.y() - p.y()) - (a.x() - p.x()) * (c.y() - p.y())) / area2;
          const double wc = 1.0 - wa - wb;
          if (wa < 0.0 || wb < 0.0 || wc < 0.0) continue;
          // Outward normals: a face seen from below (its normal's third component < 0) is entered.
          crossings[static_cast<std::size_t>(i) + g.n[0] * static_cast<std::size_t>(j)].emplace_back(
              wa * a.z() + wb * b.z() + wc * c.z(), area2 > 0.0 ? -1 : 1);
        }
      }
    }
  }
  std::vector<char> outside(g.count(), 1);
  for (std::size_t column = 0; column < crossings.size(); ++column) {
    auto& list = crossings[column];
    std::sort(list.begin(), list.end());
    std::size_t next = 0;
    int winding = 0;
    for (std::size_t k = 0; k < g.n[2]; ++k) {
      const double z = g.origin.z() + g.h * static_cast<double>(k);
      while (next < list.size() && list[next].first < z) winding += list[next++].second;
      if (winding != 0) outside[column + g.n[0] * g.n[1] * k] = 0;
    }
  }
  return outside;
}

// The largest spectral norm of the trilinear field's gradient at the corners of every cell whose
// corners are all `judged` (the gradient at a corner: the differences along the cell's edges there).
double steepest_gradient(const std::vector<Eigen::Vector3d>& u, const Lattice& g, const std::vector<char>& judged) {
  if (u.empty()) return 0.0;
  // The steepest of one cell's eight corners, or `most` if none is steeper; `most` for a cell
  // not wholly judged. A corner whose Frobenius norm (at least the spectral norm) stays clearly
  // below `most` cannot raise it: its eigenvalues are not computed (#50; the same maximum, since
  // the skipped corners' norms lie below it by far more than the solver's rounding).
  const auto cell_steepest = [&](std::size_t i, std::size_t j, std::size_t k, double most) {
    for (std::size_t c = 0; c < 8; ++c)
      if (!judged[g.at(i + (c & 1u), j + ((c >> 1) & 1u), k + ((c >> 2) & 1u))]) return most;
    for (std::size_t c = 0; c < 8; ++c) {
      const std::size_t di = c & 1u, dj = (c >> 1) & 1u, dk = (c >> 2) & 1u;
      Eigen::Matrix3d grad;
      grad.col(0) = (u[g.at(i + 1, j + dj, k + dk)] - u[g.at(i, j + dj, k + dk)]) / g.h;
      grad.col(1) = (u[g.at(i + di, j + 1, k + dk)] - u[g.at(i + di, j, k + dk)]) / g.h;
      grad.col(2) = (u[g.at(i + di, j + dj, k + 1)] - u[g.at(i + di, j + dj, k)]) / g.h;
      if (grad.squaredNorm() < (1.0 - 1e-6) * most * most) continue;
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen;
      eigen.computeDirect(grad.transpose() * grad, Eigen::EigenvaluesOnly);
      most = std::max(most, std::sqrt(std::max(0.0, eigen.eigenvalues()[2])));
    }
    return most;
  };
  std::vector<double> per_slab(g.n[2] - 1, 0.0);  // one per k-slab: the same maximum at any thread count
  const tsan::Region region;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, g.n[2] - 1),
                    region.wrap([&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t k = r.begin(); k != r.end(); ++k)
                        for (std::size_t j = 0; j + 1 < g.n[1]; ++j)
                          for (std::size_t i = 0; i + 1 < g.n[0]; ++i)
                            per_slab[k] = cell_steepest(i, j, k, per_slab[k]);
                    }));
  region.join();
  return *std::max_element(per_slab.begin(), per_slab.end());
}

}  // namespace

BodyMotion::BodyMotion(const Model& model, const BodyMotionOptions& options) : options_(options) {
  if (model.lungs.empty()) return;
  const mesh::BodyAxes& axes = model.lungs.front().regions.axes;
  const Eigen::Vector3d up = axes.up.normalized();
  // The box: the lungs with a margin, and further below them (the abdomen).
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const LungModel& lung : model.lungs) {
    for (const auto& v : lung.rest.vertices) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
  }
  lo -= Eigen::Vector3d::Constant(options.margin_m);
  hi += Eigen::Vector3d::Constant(options.margin_m);
  lo = lo.cwiseMin(lo - options.below_m * up);
  hi = hi.cwiseMax(hi - options.below_m * up);
  const Lattice fine(lo, hi, options.cell_m);
  origin_ = fine.origin;
  size_ = fine.n;
  const std::size_t nodes = fine.count();

  const std::vector<Sample> samples = surface_samples(model, up);

  // The distance to the nearest surface vertex: exact at the nodes around each vertex, then the
  // distance transform (in lattice units) carries it everywhere.
  std::vector<double> distance(nodes, std::numeric_limits<double>::infinity());
  for (const Sample& s : samples) {
    fine.corners(s.at, [&](std::size_t node, double) {
      const std::size_t i = node % fine.n[0], j = (node / fine.n[0]) % fine.n[1], k = node / (fine.n[0] * fine.n[1]);
      distance[node] = std::min(distance[node], (fine.node(i, j, k) - s.at).squaredNorm() / (fine.h * fine.h));
    });
  }
  distance_transform(distance, fine);

  if (options.scale_range.empty() || options.sigma_ladder_m.empty()) {
    unit_ = unit_fields(model.lungs.size(), samples, distance, fine, lo, hi, options, options.smallest_sigma_m);
    return;
  }
  // The narrowest blur (body_motion.h): the least of the ladder whose field is a contraction with
  // room to spare at the breath's ends, judged on the nodes outside the lungs beyond a cell from
  // the pleura (nearer, a node's cells reach into the lung, whose own field moves it there); the
  // widest when none is (steepest() then says by how much it is not).
  std::vector<char> judged = outside_lungs(model, fine);
  for (std::size_t node = 0; node < nodes; ++node)
    judged[node] = static_cast<char>(judged[node] && distance[node] >= 1.0);
  std::array<std::vector<double>, 2> ends;  // the lungs' scales at each end, times the margin
  for (std::size_t l = 0; l < model.lungs.size(); ++l) {
    const std::array<double, 2> range = l < options.scale_range.size() ? options.scale_range[l] : std::array{0.0, 0.0};
    for (std::size_t e = 0; e < 2; ++e) ends[e].push_back(options.margin * range[e]);
  }
  for (const double sigma : options.sigma_ladder_m) {
    unit_ = unit_fields(model.lungs.size(), samples, distance, fine, lo, hi, options, sigma);
    options_.smallest_sigma_m = sigma;
    steepest_ = 0.0;
    for (const std::vector<double>& scales : ends)
      steepest_ = std::max(steepest_, steepest_gradient(frame(scales).u_, fine, judged));
    if (steepest_ <= options.steepest_allowed) break;
  }
}

Eigen::Vector3d BodyMotion::displacement(const Eigen::Vector3d& x, std::span<const double> scales) const {
  Eigen::Vector3d u = Eigen::Vector3d::Zero();
  if (unit_.empty()) return u;
  const Lattice fine(origin_, options_.cell_m, size_);
  fine.corners(x, [&](std::size_t node, double w) {
    for (std::size_t l = 0; l < unit_.size() && l < scales.size(); ++l) u += (w * scales[l]) * unit_[l][node];
  });
  return u;
}

BodyMotion::Frame BodyMotion::frame(std::span<const double> scales) const {
  Frame out;
  if (unit_.empty()) return out;
  out.id_ = next_frame_id();
  out.origin_ = origin_;
  out.h_ = options_.cell_m;
  out.inverse_h_ = 1.0 / out.h_;
  out.size_ = size_;
  // Each node's sum over the lungs in lung order, the nodes on every core (#50: the voxel outputs
  // and each of the report's slices ask for a frame; 0.4-0.9 M nodes).
  out.u_.resize(unit_.front().size());
  const std::size_t lungs = std::min(unit_.size(), scales.size());
  core::for_each_index(out.u_.size(), [&](std::size_t node) {
    Eigen::Vector3d u = Eigen::Vector3d::Zero();
    for (std::size_t l = 0; l < lungs; ++l) u += scales[l] * unit_[l][node];
    out.u_[node] = u;
  });
  return out;
}

Eigen::Vector3d BodyMotion::Frame::column_blend(const Eigen::Vector3d* p, double ty, double tz) const {
  const std::size_t row = size_[0], slab = size_[0] * size_[1];
  const Eigen::Vector3d near = (1.0 - ty) * p[0] + ty * p[row];
  const Eigen::Vector3d far = (1.0 - ty) * p[slab] + ty * p[slab + row];
  return (1.0 - tz) * near + tz * far;
}

Eigen::Vector3d BodyMotion::Frame::displacement(const Eigen::Vector3d& x) const {
  if (u_.empty()) return Eigen::Vector3d::Zero();
  // The voxel outputs call this (or a Cursor) twice per voxel (#50): the corners are blended as
  // two y-z blends and one along x, not walked one by one.
  std::size_t bx = 0, by = 0, bz = 0;
  double tx = 0.0, ty = 0.0, tz = 0.0;
  if (!axis_cell((x.x() - origin_.x()) * inverse_h_, size_[0], bx, tx) ||
      !axis_cell((x.y() - origin_.y()) * inverse_h_, size_[1], by, ty) ||
      !axis_cell((x.z() - origin_.z()) * inverse_h_, size_[2], bz, tz)) {
    return Eigen::Vector3d::Zero();
  }
  const Eigen::Vector3d* column = u_.data() + size_[0] * (by + size_[1] * bz);
  return (1.0 - tx) * column_blend(column + bx, ty, tz) + tx * column_blend(column + bx + 1, ty, tz);
}

Eigen::Vector3d BodyMotion::Frame::Cursor::displacement(const Frame& frame, const Eigen::Vector3d& x) {
  if (frame.u_.empty()) return Eigen::Vector3d::Zero();
  if (frame_id_ != frame.id_ || !same_bits(x.y(), y_) || !same_bits(x.z(), z_)) {
    // Another row (or frame): its y-z cell and fractions as displacement() finds them.
    frame_id_ = frame.id_;
    y_ = x.y();
    z_ = x.z();
    bx_ = kNoCell;
    std::size_t by = 0, bz = 0;
    inside_ = axis_cell((y_ - frame.origin_.y()) * frame.inverse_h_, frame.size_[1], by, ty_) &&
              axis_cell((z_ - frame.origin_.z()) * frame.inverse_h_, frame.size_[2], bz, tz_);
    column_ = inside_ ? frame.u_.data() + frame.size_[0] * (by + frame.size_[1] * bz) : nullptr;
  }
  std::size_t bx = 0;
  double tx = 0.0;
  if (!inside_ || !axis_cell((x.x() - frame.origin_.x()) * frame.inverse_h_, frame.size_[0], bx, tx)) {
    return Eigen::Vector3d::Zero();
  }
  if (bx != bx_) {
    // The next cell along the row shares a node with the last one (either way along x).
    const bool next = bx_ != kNoCell && bx == bx_ + 1, previous = bx_ != kNoCell && bx + 1 == bx_;
    const Eigen::Vector3d left = next ? right_ : frame.column_blend(column_ + bx, ty_, tz_);
    const Eigen::Vector3d right = previous ? left_ : frame.column_blend(column_ + bx + 1, ty_, tz_);
    left_ = left;
    right_ = right;
    bx_ = bx;
  }
  return (1.0 - tx) * left_ + tx * right_;
}

Eigen::Vector3d BodyMotion::Frame::inverse(const Eigen::Vector3d& x, const Eigen::Vector3d& guess) const {
  if (u_.empty()) return Eigen::Vector3d::Zero();
  constexpr double kTolerance_m = 1e-9;
  constexpr int kFixedPointSteps = 12, kNewtonSteps = 50;
  const Lattice fine(origin_, h_, size_);
  // The fixed-point iteration first: one lookup per step, and from a row neighbour's guess it
  // converges in a few wherever |du/dx| is well below 1, nearly everywhere.
  Eigen::Vector3d v = guess;
  for (int step = 0; step < kFixedPointSteps; ++step) {
    const Eigen::Vector3d next = -displacement(x + v);
    const double change = (next - v).norm();
    v = next;
    if (change < kTolerance_m) return v;
  }
  // Newton's method where it has not converged (|du/dz| near or above 1 under the diaphragm).
  for (int step = 0; step < kNewtonSteps; ++step) {
    // u and its gradient at x + v: the trilinear interpolation in its cell (0 outside the lattice).
    Eigen::Vector3d u = Eigen::Vector3d::Zero();
    Eigen::Matrix3d du = Eigen::Matrix3d::Zero();  // du(r, a) = d u_r / d x_a
    std::array<std::size_t, 3> b{};
    Eigen::Vector3d t;
    if (fine.cell(x + v, b, t)) {
      for (std::size_t c = 0; c < 8; ++c) {
        const std::size_t di = c & 1u, dj = (c >> 1) & 1u, dk = (c >> 2) & 1u;
        const double wx = di ? t.x() : 1.0 - t.x(), wy = dj ? t.y() : 1.0 - t.y(), wz = dk ? t.z() : 1.0 - t.z();
        const double sx = di ? 1.0 : -1.0, sy = dj ? 1.0 : -1.0, sz = dk ? 1.0 : -1.0;
        const Eigen::Vector3d& node = u_[fine.at(b[0] + di, b[1] + dj, b[2] + dk)];
        u += (wx * wy * wz) * node;
        du.col(0) += (sx * wy * wz / h_) * node;
        du.col(1) += (wx * sy * wz / h_) * node;
        du.col(2) += (wx * wy * sz / h_) * node;
      }
    }
    const Eigen::Vector3d residual = v + u;  // 0 at the pull-back
    const Eigen::Matrix3d jacobian = Eigen::Matrix3d::Identity() + du;
    const Eigen::Vector3d change =
        jacobian.determinant() > 0.1 ? Eigen::Vector3d(jacobian.inverse() * residual) : residual;
    v -= change;
    if (change.norm() < kTolerance_m) break;
  }
  return v;
}

BodyMotion::Frame BodyMotion::Frame::inverse_field(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                                                   std::size_t refine) const {
  Frame out;
  if (u_.empty() || refine == 0) return out;
  out.h_ = h_ / static_cast<double>(refine);
  out.inverse_h_ = 1.0 / out.h_;
  // The fine lattice's node range per axis: from the last node at or below lo to the first at or
  // above hi, within u's lattice (beyond it u is 0 and so is v), and at least two nodes (a cell).
  std::array<std::size_t, 3> first{};
  for (std::size_t a = 0; a < 3; ++a) {
    const auto e = static_cast<Eigen::Index>(a);
    const std::size_t last = (size_[a] - 1) * refine;
    const double top = static_cast<double>(last);
    const double from = std::floor((lo[e] - origin_[e]) / out.h_), to = std::ceil((hi[e] - origin_[e]) / out.h_);
    if (!(from <= top) || !(to >= 0.0)) return Frame{};  // the box misses u's lattice: v = 0
    std::size_t begin = static_cast<std::size_t>(std::max(from, 0.0)),
                end = static_cast<std::size_t>(std::min(to, top));
    if (end == begin) {
      if (end < last) {
        ++end;
      } else {
        --begin;
      }
    }
    first[a] = begin;
    out.size_[a] = end - begin + 1;
  }
  out.origin_ = origin_ + out.h_ * Eigen::Vector3d(static_cast<double>(first[0]), static_cast<double>(first[1]),
                                                   static_cast<double>(first[2]));
  const Lattice lattice(out.origin_, out.h_, out.size_);
  out.id_ = next_frame_id();
  out.u_.resize(lattice.count());
  // Each row in order by one task, each node started from the line through the two before it (a
  // smooth field's next value to second order): the same nodes' values at any thread count.
  const tsan::Region region;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, out.size_[1] * out.size_[2]),
                    region.wrap([&](const tbb::blocked_range<std::size_t>& rows) {
                      for (std::size_t row = rows.begin(); row != rows.end(); ++row) {
                        const std::size_t j = row % out.size_[1], k = row / out.size_[1];
                        for (std::size_t i = 0; i < out.size_[0]; ++i) {
                          const Eigen::Vector3d x = lattice.node(i, j, k);
                          const std::size_t at = lattice.at(i, j, k);
                          const Eigen::Vector3d guess = i >= 2 ? Eigen::Vector3d(2.0 * out.u_[at - 1] - out.u_[at - 2])
                                                        : i == 1 ? out.u_[at - 1]
                                                                 : Eigen::Vector3d(-displacement(x));
                          out.u_[at] = inverse(x, guess);
                        }
                      }
                    }));
  region.join();
  return out;
}

}  // namespace pneuma::model

namespace pneuma::model {
namespace {

constexpr std::string_view kBodyKind = "pneuma-body-field 2";
constexpr std::uint32_t kByteOrder = 0x01020304;  // written natively: a file of the other order is refused

template <typename T>
void put(std::string& out, const T& value) {
  out.append(reinterpret_cast<const char*>(&value), sizeof value);
}
template <typename T>
T take(std::string_view bytes, std::size_t& at) {
  if (bytes.size() - at < sizeof(T)) throw ValueError("body field: its bytes end early");
  T value;
  std::memcpy(&value, bytes.data() + at, sizeof value);
  at += sizeof value;
  return value;
}

}  // namespace

std::string BodyMotion::to_bytes() const {
  std::string out;
  put(out, kByteOrder);
  put(out, options_.smallest_sigma_m);
  put(out, steepest_);
  for (int a = 0; a < 3; ++a) put(out, origin_[a]);
  for (const std::size_t n : size_) put(out, static_cast<std::uint64_t>(n));
  put(out, static_cast<std::uint64_t>(unit_.size()));
  for (const std::vector<Eigen::Vector3d>& u : unit_) {
    put(out, static_cast<std::uint64_t>(u.size()));
    out.append(reinterpret_cast<const char*>(u.data()), u.size() * sizeof(Eigen::Vector3d));
  }
  return out;
}

BodyMotion BodyMotion::from_bytes(std::string_view bytes, const BodyMotionOptions& options) {
  BodyMotion body;
  body.options_ = options;
  std::size_t at = 0;
  if (take<std::uint32_t>(bytes, at) != kByteOrder) throw ValueError("body field: another byte order");
  body.options_.smallest_sigma_m = take<double>(bytes, at);
  body.steepest_ = take<double>(bytes, at);
  for (int a = 0; a < 3; ++a) body.origin_[a] = take<double>(bytes, at);
  std::uint64_t nodes = 1;
  for (std::size_t& n : body.size_) {
    const auto count = take<std::uint64_t>(bytes, at);
    if (count == 0 || count > (std::uint64_t{1} << 20)) throw ValueError("body field: a lattice side out of range");
    n = static_cast<std::size_t>(count);
    nodes *= count;
  }
  const auto lungs = take<std::uint64_t>(bytes, at);
  if (lungs > 255) throw ValueError("body field: more than 255 lungs");
  for (std::uint64_t l = 0; l < lungs; ++l) {
    const auto count = take<std::uint64_t>(bytes, at);
    if (count != nodes || (bytes.size() - at) / sizeof(Eigen::Vector3d) < count)
      throw ValueError("body field: a lung's field does not fill the lattice");
    std::vector<Eigen::Vector3d>& u = body.unit_.emplace_back(count);
    std::memcpy(static_cast<void*>(u.data()), bytes.data() + at, count * sizeof(Eigen::Vector3d));
    at += count * sizeof(Eigen::Vector3d);
  }
  if (at != bytes.size()) throw ValueError("body field: bytes beyond its lattice");
  return body;
}

std::string body_motion_key(const Model& model, const BodyMotionOptions& o) {
  core::Sha256 h;
  const auto bytes = [&h](const void* data, std::size_t n) {
    const auto size = static_cast<std::uint64_t>(n);
    h.update(&size, sizeof size).update(data, n);
  };
  const auto number = [&h](double x) { h.update(&x, sizeof x); };
  bytes(kBodyKind.data(), kBodyKind.size());
  for (const double x : {o.wall_decay_m, o.abdomen_decay_m, o.smallest_sigma_m, o.margin, o.steepest_allowed,
                         o.margin_m, o.below_m, o.taper_m, o.cell_m, static_cast<double>(o.pleura_corrections)})
    number(x);
  bytes(o.scale_range.data(), o.scale_range.size() * sizeof(o.scale_range[0]));
  bytes(o.sigma_ladder_m.data(), o.sigma_ladder_m.size() * sizeof(double));
  number(static_cast<double>(model.lungs.size()));
  for (const LungModel& lung : model.lungs) {
    bytes(lung.rest.vertices.data(), lung.rest.vertices.size() * sizeof(Eigen::Vector3d));
    bytes(lung.rest.triangles.data(), lung.rest.triangles.size() * sizeof(mesh::Triangle));
    bytes(lung.normals.data(), lung.normals.size() * sizeof(Eigen::Vector3d));
    bytes(lung.regions.weight.data(), lung.regions.weight.size() * sizeof(lung.regions.weight[0]));
    bytes(lung.regions.axes.up.data(), sizeof(Eigen::Vector3d));
    bytes(lung.unit_displacement.data(), lung.unit_displacement.size() * sizeof(Eigen::Vector3d));
    const std::vector<double> off = off_lobes(model, lung);  // what the label map adds
    bytes(off.data(), off.size() * sizeof(double));
  }
  return core::to_hex(h.finish());
}

std::shared_ptr<const BodyMotion> body_motion_cached(const Model& model, const BodyMotionOptions& options,
                                                     const std::filesystem::path& lookup,
                                                     const std::filesystem::path& save_to) {
  if (lookup.empty() && save_to.empty()) return std::make_shared<const BodyMotion>(model, options);
  const std::string key = body_motion_key(model, options);
  std::string discarded;  // a damaged file is computed again and replaced
  if (!lookup.empty()) {
    if (const std::optional<std::string> kept = core::load_keyed_file(lookup, kBodyKind, key, discarded)) {
      try {
        auto body = std::make_shared<const BodyMotion>(BodyMotion::from_bytes(*kept, options));
        if (!save_to.empty() && save_to != lookup) {  // the file as it is (its tens of MB not hashed again)
          std::error_code ec;
          std::filesystem::copy_file(lookup, save_to, std::filesystem::copy_options::overwrite_existing, ec);
          if (ec) throw IoError(save_to.string() + ": cannot write: " + ec.message());
        }
        return body;
      } catch (const ValueError&) {
        // sealed but not a field of this layout: computed again below
      }
    }
  }
  auto body = std::make_shared<const BodyMotion>(model, options);
  if (!save_to.empty()) core::save_keyed_file(save_to, kBodyKind, key, body->to_bytes());
  return body;
}

}  // namespace pneuma::model
