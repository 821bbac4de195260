// surface_from_labels(): the voxel work in plain C++ (mask, islands, closing by exact Euclidean
// distances within the ball, cavities, Gaussian smoothing) on the crop of the map around the
// labels; the meshing of the level set is in labels_cgal.cpp. Deterministic: every pass gives
// the serial result at any thread count (each voxel written by one task; floods in voxel order).
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <span>
#include <stdexcept>

#include "pneuma/core/error.h"
#include "pneuma/core/parallel.h"
#include "pneuma/core/tsan.h"
#include "pneuma/mesh/geometry/validate.h"
#include "pneuma/mesh/labels/labels.h"

namespace pneuma::mesh {
namespace {

using Size3 = std::array<std::size_t, 3>;

struct Grid {
  Size3 n{0, 0, 0};
  std::size_t count() const { return n[0] * n[1] * n[2]; }
  std::size_t index(std::size_t i, std::size_t j, std::size_t k) const { return i + n[0] * (j + n[1] * k); }
  std::size_t stride(int axis) const { return axis == 0 ? 1 : axis == 1 ? n[0] : n[0] * n[1]; }
};

// The first voxel of line l of the lines along `axis` (count() / n[axis] of them): for axis 0,
// l indexes (j, k); for axis 1, (i, k); for axis 2, (i, j).
std::size_t line_start(const Grid& g, int axis, std::size_t l) {
  if (axis == 0) return l * g.n[0];
  if (axis == 1) return (l % g.n[0]) + (l / g.n[0]) * g.n[0] * g.n[1];
  return l;
}

// body(first voxel, scratch) for every line along `axis`, lines in parallel: each line is read and
// written by one body only, so the result is the serial loop's at any thread count. `Scratch` is
// one body's working memory, made once per block of lines.
template <class Scratch, class Body>
void for_each_line(const Grid& g, int axis, const Body& body) {
  const std::size_t lines = g.count() / g.n[static_cast<std::size_t>(axis)];
  const tsan::Region region;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, lines, 64),
                    region.wrap([&](const tbb::blocked_range<std::size_t>& range) {
                      Scratch scratch;
                      for (std::size_t l = range.begin(); l < range.end(); ++l) body(line_start(g, axis, l), scratch);
                    }));
  region.join();
}

// Whether a label is one of a few wanted ones, remembering the last label asked about: a label
// map is long runs of one label, so most voxels cost one comparison.
class LabelTest {
 public:
  explicit LabelTest(const std::vector<int>& wanted) : wanted_(wanted) {}
  bool operator()(std::int32_t label) {
    if (label != last_) last_ = label, last_in_ = std::find(wanted_.begin(), wanted_.end(), label) != wanted_.end();
    return last_in_;
  }

 private:
  const std::vector<int>& wanted_;
  std::int32_t last_ = 0;
  bool last_in_ = std::find(wanted_.begin(), wanted_.end(), 0) != wanted_.end();
};

// A run of voxels along x: row j + n[1] k, voxels [a, b].
struct Span {
  std::uint32_t row, a, b;
};

// Floods from voxel (i, row) the voxels of value `from` connected to it, row by row (a span along
// x at a time, rather than voxel by voxel: #50), setting them to `to` (!= from); appends the spans
// to `spans` and returns the voxels set. Neighbouring rows are those at (dj, dk) in `rows`; a span
// reaches along x by `diagonal` voxels beyond its ends (1: 26-connected, 0: 6-connected).
std::size_t flood_spans(const Grid& g, std::vector<std::uint8_t>& mask, std::size_t i, std::size_t row,
                        std::uint8_t from, std::uint8_t to, std::span<const std::array<int, 2>> rows,
                        std::size_t diagonal, std::vector<Span>& stack, std::vector<Span>* spans) {
  const std::size_t nx = g.n[0], ny = g.n[1], nz = g.n[2];
  std::size_t voxels = 0;
  stack.clear();
  stack.push_back({static_cast<std::uint32_t>(row), static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(i)});
  while (!stack.empty()) {
    const Span seed = stack.back();
    stack.pop_back();
    std::uint8_t* line = mask.data() + static_cast<std::size_t>(seed.row) * nx;
    std::size_t a = seed.a;
    if (line[a] != from) continue;  // reached from another seed since it was pushed
    std::size_t b = a;
    while (a > 0 && line[a - 1] == from) --a;
    while (b + 1 < nx && line[b + 1] == from) ++b;
    std::fill(line + a, line + b + 1, to);
    voxels += b - a + 1;
    if (spans) spans->push_back({seed.row, static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(b)});
    const std::size_t j = seed.row % ny, k = seed.row / ny;
    const std::size_t lo = a >= diagonal ? a - diagonal : 0, hi = std::min(nx - 1, b + diagonal);
    for (const auto& [dj, dk] : rows) {
      if ((j == 0 && dj < 0) || (j + 1 == ny && dj > 0) || (k == 0 && dk < 0) || (k + 1 == nz && dk > 0)) continue;
      const std::size_t next = (j + static_cast<std::size_t>(dj)) + ny * (k + static_cast<std::size_t>(dk));
      const std::uint8_t* other = mask.data() + next * nx;
      // One seed per run of `from` in [lo, hi].
      for (std::size_t x = lo; x <= hi; ++x) {
        if (other[x] == from && (x == lo || other[x - 1] != from))
          stack.push_back(
              {static_cast<std::uint32_t>(next), static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(x)});
      }
    }
  }
  return voxels;
}

constexpr std::array<std::array<int, 2>, 8> kRows26{
    {{-1, -1}, {0, -1}, {1, -1}, {-1, 0}, {1, 0}, {-1, 1}, {0, 1}, {1, 1}}};
constexpr std::array<std::array<int, 2>, 4> kRows6{{{0, -1}, {-1, 0}, {1, 0}, {0, 1}}};

// Largest 26-connected component of `mask` (1 = inside); the others are cleared.
// Returns {components dropped, voxels dropped}.
std::pair<std::size_t, std::size_t> keep_largest_component(const Grid& g, std::vector<std::uint8_t>& mask) {
  // Components in the order of their first voxel; each one's spans, contiguous in `spans`.
  std::vector<std::size_t> sizes, first_span;
  std::vector<Span> spans, stack;
  for (std::size_t seed = 0; seed < g.count(); ++seed) {
    if (mask[seed] != 1) continue;
    first_span.push_back(spans.size());
    sizes.push_back(flood_spans(g, mask, seed % g.n[0], seed / g.n[0], 1, 2, kRows26, 1, stack, &spans));
  }
  first_span.push_back(spans.size());
  // The largest; on a tie, the first found (lowest voxel index).
  const std::size_t keep =
      sizes.empty() ? 0 : static_cast<std::size_t>(std::max_element(sizes.begin(), sizes.end()) - sizes.begin());
  std::size_t dropped_voxels = 0;
  for (std::size_t c = 0; c < sizes.size(); ++c) {
    const std::uint8_t value = c == keep ? 1 : 0;
    for (std::size_t s = first_span[c]; s < first_span[c + 1]; ++s) {
      std::uint8_t* line = mask.data() + static_cast<std::size_t>(spans[s].row) * g.n[0];
      std::fill(line + spans[s].a, line + spans[s].b + 1, value);
    }
    if (c != keep) dropped_voxels += sizes[c];
  }
  if (sizes.size() <= 1) return {0, 0};
  return {sizes.size() - 1, dropped_voxels};
}

// Squared distance (metres^2) from each voxel centre to the nearest voxel where `target` is 1,
// where it is at most `bound`; elsewhere infinity. Separable, as an exact Euclidean distance
// transform: along x the row's nearest target; then along y and along z the least of
// w b^2 + d over the offsets b with w b^2 <= bound (w the axis' spacing squared), in the
// arithmetic of Felzenszwalb and Huttenlocher's envelope of parabolas (w dq dq + f in double,
// stored as float), which it replaces: a closing's ball is a few voxels wide, and these short
// windows run along whole rows of x at once (#50: a third of the transform's time).
std::vector<float> squared_distance_within(const Grid& g, const std::vector<std::uint8_t>& target,
                                           const Eigen::Vector3d& spacing, double bound) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  std::vector<float> d(g.count());
  {
    const std::size_t n = g.n[0];
    const double w = spacing[0] * spacing[0];
    for_each_line<std::vector<std::size_t>>(g, 0, [&](std::size_t start, std::vector<std::size_t>& last) {
      // last[q]: the nearest target at or before q (n: none), then the nearer of it and the next.
      last.resize(n);
      std::size_t seen = n;
      for (std::size_t q = 0; q < n; ++q) last[q] = seen = target[start + q] ? q : seen;
      std::size_t next = n;
      for (std::size_t q = n; q-- > 0;) {
        if (target[start + q]) next = q;
        const std::size_t before = last[q];
        if (before == n && next == n) {
          d[start + q] = inf;
          continue;
        }
        const std::size_t dq = std::min(before == n ? n : q - before, next == n ? n : next - q);
        const auto dqd = static_cast<double>(dq);
        const auto value = static_cast<float>(w * dqd * dqd);
        if (static_cast<double>(value) <= bound) {
          d[start + q] = value;
        } else {
          d[start + q] = inf;
        }
      }
    });
  }
  std::vector<float> across(g.count());
  for (int axis = 1; axis < 3; ++axis) {
    const double w = spacing[axis] * spacing[axis];
    const auto reach = static_cast<std::size_t>(std::floor(std::sqrt(bound / w)));
    // The window's terms w b^2, in the transform's order of operations.
    std::vector<double> term(reach + 1);
    for (std::size_t b = 0; b <= reach; ++b) term[b] = w * static_cast<double>(b) * static_cast<double>(b);
    const std::size_t n = g.n[static_cast<std::size_t>(axis)], stride = g.stride(axis), nx = g.n[0];
    const int other = axis == 1 ? 2 : 1;
    const std::size_t rows = g.n[static_cast<std::size_t>(other)], row_step = g.stride(other);
    const tsan::Region region;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rows),
                      region.wrap([&](const tbb::blocked_range<std::size_t>& r) {
                        for (std::size_t o = r.begin(); o < r.end(); ++o) {
                          for (std::size_t q = 0; q < n; ++q) {
                            float* out = across.data() + o * row_step + q * stride;
                            std::fill(out, out + nx, inf);
                            const std::size_t lo = q >= reach ? q - reach : 0, hi = std::min(n - 1, q + reach);
                            for (std::size_t t = lo; t <= hi; ++t) {
                              const double c = term[t > q ? t - q : q - t];
                              const float* in = d.data() + o * row_step + t * stride;
                              for (std::size_t i = 0; i < nx; ++i)
                                out[i] = std::min(out[i], static_cast<float>(c + static_cast<double>(in[i])));
                            }
                            for (std::size_t i = 0; i < nx; ++i)
                              if (!(static_cast<double>(out[i]) <= bound)) out[i] = inf;
                          }
                        }
                      }));
    region.join();
    std::swap(d, across);
  }
  return d;
}

// Morphological closing with a ball of radius r: dilation (distance to the mask <= r), then
// erosion (distance to the outside of the dilation > r). Returns the voxels added.
std::size_t close_mask(const Grid& g, std::vector<std::uint8_t>& mask, const Eigen::Vector3d& spacing, double r) {
  if (r <= 0.0) return 0;
  const double r2 = r * r * (1.0 + 1e-9);
  std::vector<float> d = squared_distance_within(g, mask, spacing, r2);
  std::vector<std::uint8_t> outside(g.count());
  for (std::size_t v = 0; v < g.count(); ++v) outside[v] = !(static_cast<double>(d[v]) <= r2);
  d = squared_distance_within(g, outside, spacing, r2);
  std::size_t added = 0;
  for (std::size_t v = 0; v < g.count(); ++v) {
    const bool in = static_cast<double>(d[v]) > r2;
    if (in && !mask[v]) ++added;
    mask[v] = mask[v] || in;  // closing is extensive; keep the rare voxel a float rounding would lose
  }
  return added;
}

// Background not 6-connected to the border of the crop becomes inside. Returns {cavities, voxels}.
std::pair<std::size_t, std::size_t> fill_cavities(const Grid& g, std::vector<std::uint8_t>& mask) {
  // 0: background not yet reached, 1: inside, 2: outside (reached from the border), 3: cavity.
  std::vector<Span> stack;
  const std::size_t nx = g.n[0], ny = g.n[1], nz = g.n[2];
  auto from_border = [&](std::size_t i, std::size_t j, std::size_t k) {
    if (mask[g.index(i, j, k)] == 0) flood_spans(g, mask, i, j + ny * k, 0, 2, kRows6, 0, stack, nullptr);
  };
  for (std::size_t k = 0; k < nz; ++k) {
    for (std::size_t j = 0; j < ny; ++j) {
      if (k == 0 || j == 0 || k + 1 == nz || j + 1 == ny) {
        for (std::size_t i = 0; i < nx; ++i) from_border(i, j, k);
      } else {
        from_border(0, j, k);
        from_border(nx - 1, j, k);
      }
    }
  }
  std::size_t cavities = 0, voxels = 0;
  for (std::size_t v = 0; v < g.count(); ++v) {
    if (mask[v] != 0) continue;
    ++cavities;
    voxels += flood_spans(g, mask, v % nx, v / nx, 0, 3, kRows6, 0, stack, nullptr);
  }
  for (std::uint8_t& m : mask) m = m == 1 || m == 3 ? 1 : 0;
  return {cavities, voxels};
}

// Which image axis runs most nearly along LPS z (superior), and which way: the feet lie towards
// lower indices when `index_up`.
struct VerticalAxis {
  int axis = 2;
  bool index_up = true;
  // A dent spanning fewer slices is filled: set from the smoothing (surface_from_labels).
  std::size_t min_dent_slices = 1;
};

VerticalAxis vertical_axis(const Eigen::Matrix4d& ijk_to_lps) {
  VerticalAxis v;
  double best = -1.0;
  for (int a = 0; a < 3; ++a) {
    const double z = ijk_to_lps.block<3, 1>(0, a).normalized().z();
    if (std::abs(z) > best) best = std::abs(z), v.axis = a, v.index_up = z > 0.0;
  }
  return v;
}

struct SliceHoles {
  std::size_t filled_voxels = 0;
  std::size_t dents = 0, dent_voxels = 0;  // left to the body (not filled)
};

// The holes of the slices across the vertical axis (marked 2 in `mask`) as 3D regions, 6-connected
// across slices. A region open towards the feet and closed above is a dent from below: the
// underside of the diaphragm's dome, whose top is a hole in the axial slices around it. It is not
// a tunnel (a tunnel opens at both ends, a cavity at neither), and filling it would put a flat lid
// under the lung that the body below cannot follow (docs/voxels.md, "The body's pairs at 2 mm
// voxels"), so it is left to the body; every other region is filled, and so is a dent shallower
// than `min_dent_slices`: the blur all but closes it (case008's left lung: a dent 1 mm deep moved
// the surface by 1.0 mm), so leaving it open changes nothing the body sees and only Mesh_3's
// sampling of the whole lung. Regions are found in voxel order, so the result does not depend on
// the thread count.
void fill_vertical_holes_but_dents(const Grid& g, std::vector<std::uint8_t>& mask, VerticalAxis vertical,
                                   SliceHoles& out) {
  constexpr std::uint8_t kHole = 2, kSeen = 3;
  const auto axis = static_cast<std::size_t>(vertical.axis);
  const std::size_t step = g.stride(vertical.axis);
  std::vector<Span> region, stack;
  for (std::size_t seed = 0; seed < g.count(); ++seed) {
    if (mask[seed] != kHole) continue;
    region.clear();
    const std::size_t voxels =
        flood_spans(g, mask, seed % g.n[0], seed / g.n[0], kHole, kSeen, kRows6, 0, stack, &region);
    // Within a slice a hole meets only the mask and its own region; across slices, the background
    // of the next slice (or the crop's edge) is an opening.
    bool open_down = false, open_up = false;
    std::size_t lowest = g.n[axis], highest = 0;  // slices spanned
    for (const Span& span : region) {
      for (std::size_t i = span.a; i <= span.b; ++i) {
        const std::size_t v = i + g.n[0] * span.row;
        const std::size_t at = axis == 0 ? i : axis == 1 ? span.row % g.n[1] : span.row / g.n[1];
        lowest = std::min(lowest, at), highest = std::max(highest, at);
        for (const bool towards_higher : {false, true}) {
          const bool at_edge = towards_higher ? at + 1 == g.n[axis] : at == 0;
          if (!at_edge && mask[towards_higher ? v + step : v - step] != 0) continue;
          (towards_higher == vertical.index_up ? open_up : open_down) = true;
        }
      }
    }
    const bool dent = open_down && !open_up && highest + 1 - lowest >= vertical.min_dent_slices;
    for (const Span& span : region) {
      std::uint8_t* line = mask.data() + static_cast<std::size_t>(span.row) * g.n[0];
      std::fill(line + span.a, line + span.b + 1, dent ? std::uint8_t{0} : std::uint8_t{1});
    }
    if (dent) ++out.dents, out.dent_voxels += voxels;
    else out.filled_voxels += voxels;
  }
}

// Tunnels through the mask: in every slice across each axis, background that the slice's
// border cannot reach (4-connected within the slice) becomes inside. A tunnel shows as such a
// hole in the slices across it; concavities open to the outside do not. With `leave_dents`, the
// holes of the slices across the vertical axis that make a dent from below are left open
// (fill_vertical_holes_but_dents).
SliceHoles fill_slice_holes(const Grid& g, std::vector<std::uint8_t>& mask, VerticalAxis vertical, bool leave_dents) {
  SliceHoles result;
  std::vector<std::uint8_t> reached;
  std::vector<std::size_t> stack;
  for (int axis = 0; axis < 3; ++axis) {
    const bool mark_only = leave_dents && axis == vertical.axis;
    // The slice spans axes u and w; `axis` is fixed at s.
    const int u = (axis + 1) % 3, w = (axis + 2) % 3;
    const std::size_t nu = g.n[static_cast<std::size_t>(u)], nw = g.n[static_cast<std::size_t>(w)];
    const std::size_t su = g.stride(u), sw = g.stride(w), ss = g.stride(axis);
    reached.assign(nu * nw, 0);
    for (std::size_t s = 0; s < g.n[static_cast<std::size_t>(axis)]; ++s) {
      std::fill(reached.begin(), reached.end(), 0);
      const std::size_t base = s * ss;
      auto push = [&](std::size_t a, std::size_t b) {
        const std::size_t local = a + nu * b;
        if (!reached[local] && !mask[base + a * su + b * sw]) reached[local] = 1, stack.push_back(local);
      };
      for (std::size_t a = 0; a < nu; ++a) push(a, 0), push(a, nw - 1);
      for (std::size_t b = 0; b < nw; ++b) push(0, b), push(nu - 1, b);
      while (!stack.empty()) {
        const std::size_t local = stack.back();
        stack.pop_back();
        const std::size_t a = local % nu, b = local / nu;
        if (a > 0) push(a - 1, b);
        if (a + 1 < nu) push(a + 1, b);
        if (b > 0) push(a, b - 1);
        if (b + 1 < nw) push(a, b + 1);
      }
      for (std::size_t b = 0; b < nw; ++b) {
        for (std::size_t a = 0; a < nu; ++a) {
          std::uint8_t& m = mask[base + a * su + b * sw];
          if (m || reached[a + nu * b]) continue;
          if (mark_only) m = 2;
          else m = 1, ++result.filled_voxels;
        }
      }
    }
    if (mark_only) fill_vertical_holes_but_dents(g, mask, vertical, result);
  }
  return result;
}

// Separable Gaussian blur (sigma in metres, truncated at 3 sigma, normalised weights; zero
// outside the grid).
std::vector<float> blur(const Grid& g, const std::vector<std::uint8_t>& mask, const Eigen::Vector3d& spacing,
                        double sigma) {
  std::vector<float> a(mask.begin(), mask.end());
  if (sigma <= 0.0) return a;
  std::vector<float> b(a.size());
  for (int axis = 0; axis < 3; ++axis) {
    const double s = sigma / spacing[axis];
    // Narrower than a twentieth of a voxel, the kernel is the identity (its side weights are
    // below 1e-86), and s * s would underflow to 0 for a tiny sigma.
    if (s < 0.05) continue;
    const auto radius = static_cast<std::ptrdiff_t>(std::ceil(3.0 * s));
    std::vector<float> kernel(static_cast<std::size_t>(2 * radius + 1));
    double sum = 0.0;
    for (std::ptrdiff_t t = -radius; t <= radius; ++t) {
      const double w = std::exp(-0.5 * static_cast<double>(t * t) / (s * s));
      kernel[static_cast<std::size_t>(t + radius)] = static_cast<float>(w);
      sum += w;
    }
    for (float& w : kernel) w = static_cast<float>(w / sum);
    const std::size_t n = g.n[static_cast<std::size_t>(axis)], stride = g.stride(axis);
    const auto nn = static_cast<std::ptrdiff_t>(n);
    const auto window = [&](std::ptrdiff_t q) {
      return std::pair{std::max<std::ptrdiff_t>(0, q - radius), std::min<std::ptrdiff_t>(nn - 1, q + radius)};
    };
    if (axis == 0) {
      // Offset by offset along the whole line (so that it vectorises; #50): each voxel's sum
      // still runs over t = q + offset ascending, the terms inside the line only, so the bits are
      // those of a sum over its window.
      for_each_line<std::vector<float>>(g, axis, [&](std::size_t start, std::vector<float>& acc) {
        acc.assign(n, 0.0f);
        const float* line = a.data() + start;
        for (std::ptrdiff_t offset = -radius; offset <= radius; ++offset) {
          const float k = kernel[static_cast<std::size_t>(offset + radius)];
          const std::ptrdiff_t lo = std::max<std::ptrdiff_t>(0, -offset), hi = std::min(nn, nn - offset);
          for (std::ptrdiff_t q = lo; q < hi; ++q)
            acc[static_cast<std::size_t>(q)] += k * line[static_cast<std::size_t>(q + offset)];
        }
        std::copy(acc.begin(), acc.end(), b.begin() + static_cast<std::ptrdiff_t>(start));
      });
    } else {
      // Across y or z, a whole row of x at once (contiguous, so it vectorises): each voxel's sum
      // still runs over t in the same order as along one line, so the bits are the same.
      const int other = axis == 1 ? 2 : 1;
      const std::size_t rows = g.n[static_cast<std::size_t>(other)], row_step = g.stride(other), nx = g.n[0];
      const tsan::Region region;
      tbb::parallel_for(
          tbb::blocked_range<std::size_t>(0, rows), region.wrap([&](const tbb::blocked_range<std::size_t>& range) {
            std::vector<float> acc(nx);
            for (std::size_t o = range.begin(); o < range.end(); ++o) {
              const std::size_t base = o * row_step;
              for (std::ptrdiff_t q = 0; q < nn; ++q) {
                std::fill(acc.begin(), acc.end(), 0.0f);
                const auto [lo, hi] = window(q);
                for (std::ptrdiff_t t = lo; t <= hi; ++t) {
                  const float k = kernel[static_cast<std::size_t>(t - q + radius)];
                  const float* row = a.data() + base + static_cast<std::size_t>(t) * stride;
                  for (std::size_t i = 0; i < nx; ++i) acc[i] += k * row[i];
                }
                std::copy(acc.begin(), acc.end(),
                          b.begin() + static_cast<std::ptrdiff_t>(base + static_cast<std::size_t>(q) * stride));
              }
            }
          }));
      region.join();
    }
    std::swap(a, b);
  }
  return a;
}

std::string join_labels(const std::vector<int>& labels) {
  std::string s;
  for (int l : labels) {
    if (!s.empty()) s += ',';
    s += std::to_string(l);
  }
  return s;
}

std::string mL(double m3) { return fmt::format("{:.4g} mL", m3 * 1e6); }

// Keeps the component with the largest enclosed |volume|, oriented outward. Returns the count dropped.
std::size_t keep_largest_surface(TriangleMesh& mesh) {
  const std::size_t nf = mesh.triangles.size();
  // Components through shared vertices (a valid surface has manifold vertices).
  std::vector<std::uint32_t> component;
  face_components(mesh, component);
  std::map<std::size_t, double> six_volume;
  for (std::size_t f = 0; f < nf; ++f) {
    const Triangle& t = mesh.triangles[f];
    const auto& p = mesh.vertices;
    six_volume[component[f]] += p[t[0]].dot(p[t[1]].cross(p[t[2]]));
  }
  std::size_t keep = 0;
  double best = -1.0;
  for (const auto& [root, v] : six_volume) {
    if (std::abs(v) > best) best = std::abs(v), keep = root;
  }
  const bool flip = six_volume[keep] < 0.0;
  std::vector<Triangle> kept;
  kept.reserve(nf);
  for (std::size_t f = 0; f < nf; ++f) {
    Triangle t = mesh.triangles[f];
    if (component[f] != keep) continue;
    if (flip) std::swap(t[1], t[2]);
    kept.push_back(t);
  }
  mesh.triangles = std::move(kept);
  renumber_vertices_by_first_use(mesh);
  return six_volume.size() - 1;
}

}  // namespace

std::vector<std::string> LabelSurfaceReport::steps() const {
  std::vector<std::string> s;
  s.push_back(fmt::format("labels {}: {} voxels of {:.3f} x {:.3f} x {:.3f} mm ({}), {} frame from the {}",
                          join_labels(labels), label_voxels, spacing_m.x() * 1e3, spacing_m.y() * 1e3,
                          spacing_m.z() * 1e3, mL(label_volume_m3()), "LPS", transform_source));
  s.push_back(dropped_islands == 0 ? std::string("islands: none (one connected component)")
                                   : fmt::format("islands: dropped {} ({} voxels, {}), kept the largest component",
                                                 dropped_islands, dropped_island_voxels,
                                                 mL(static_cast<double>(dropped_island_voxels) * voxel_volume_m3)));
  s.push_back(closing_radius_m <= 0.0
                  ? std::string("closing: off")
                  : fmt::format("closing: ball of {:.2f} mm added {} voxels ({})", closing_radius_m * 1e3,
                                closing_added_voxels, mL(static_cast<double>(closing_added_voxels) * voxel_volume_m3)));
  if (filled_slice_holes) {
    s.push_back(fmt::format("tunnels: filled holes in slices across x, y and z: {} voxels ({})", slice_hole_voxels,
                            mL(static_cast<double>(slice_hole_voxels) * voxel_volume_m3)));
    if (dents_left > 0) {
      s.push_back(fmt::format("dents from below: left {} to the body (holes of the axial slices open downwards, "
                              "closed above: the diaphragm's dome): {} voxels ({})",
                              dents_left, dent_voxels_left,
                              mL(static_cast<double>(dent_voxels_left) * voxel_volume_m3)));
    }
  }
  s.push_back(filled_cavities == 0
                  ? std::string("cavities: none")
                  : fmt::format("cavities: filled {} ({} voxels, {})", filled_cavities, filled_cavity_voxels,
                                mL(static_cast<double>(filled_cavity_voxels) * voxel_volume_m3)));
  s.push_back(
      fmt::format("surface: Gaussian smoothing sigma {:.2f} mm, CGAL Mesh_3 at {:.2f} mm facets (within {:.3f} mm of "
                  "the level set){}",
                  smoothing_m * 1e3, edge_length_m * 1e3, max_distance_m * 1e3,
                  attempts > 1 ? fmt::format(", {} attempts (handles removed to reach genus 0)", attempts) : ""));
  if (dropped_surface_components > 0) {
    s.push_back(fmt::format("surface components: dropped {} small ones", dropped_surface_components));
  }
  const double ref = label_volume_m3();
  s.push_back(fmt::format("result: genus {}, {} enclosed ({:+.2f} % against the voxel count), {:.5g} cm^2", genus,
                          mL(volume_m3), ref > 0.0 ? 100.0 * (volume_m3 - ref) / ref : 0.0, area_m2 * 1e4));
  return s;
}

std::string LabelSurfaceReport::provenance() const {
  std::string s = "made by: pneuma mesh from-labels\n";
  s += "source: " + source + "\n";
  s += "labels: " + join_labels(labels) + "\n";
  s += fmt::format("grid: {} x {} x {} voxels of {:.4f} x {:.4f} x {:.4f} mm, {} applied, LPS millimetres\n", size[0],
                   size[1], size[2], spacing_m.x() * 1e3, spacing_m.y() * 1e3, spacing_m.z() * 1e3, transform_source);
  for (const auto& line : steps()) s += line + "\n";
  return s;
}

namespace detail {

std::size_t close_mask(const std::array<std::size_t, 3>& size, std::vector<std::uint8_t>& mask,
                       const Eigen::Vector3d& spacing_m, double radius_m) {
  return pneuma::mesh::close_mask(Grid{size}, mask, spacing_m, radius_m);
}

std::pair<std::size_t, std::size_t> keep_largest_component(const std::array<std::size_t, 3>& size,
                                                           std::vector<std::uint8_t>& mask) {
  return pneuma::mesh::keep_largest_component(Grid{size}, mask);
}

std::pair<std::size_t, std::size_t> fill_cavities(const std::array<std::size_t, 3>& size,
                                                  std::vector<std::uint8_t>& mask) {
  return pneuma::mesh::fill_cavities(Grid{size}, mask);
}

}  // namespace detail

double extraction_edge_m(double target_edge_m) {
  // Above 4 mm the 2 mm meshing stays: remeshed to 12 mm, case004's right lung meshed at 4 mm
  // cut into itself at rest (TwoLungs.TheDemoAndTheShippedScenarioRunWithBothLungs).
  constexpr double kDefault = 2e-3, kCoarsest = 4e-3;
  return target_edge_m > 0.0 && target_edge_m <= kCoarsest ? target_edge_m : kDefault;
}

std::filesystem::path provenance_path(const std::filesystem::path& mesh_path) {
  std::filesystem::path p = mesh_path;
  p += ".provenance.txt";
  return p;
}

namespace {

// check_label_surface_size's checks of the options against the map's extent.
void check_label_extent(const image::LabelMap& map, const std::string& name, const LabelSurfaceOptions& options) {
  const Eigen::Vector3d spacing = map.spacing_m();
  double extent_m = 0.0;
  for (std::size_t a = 0; a < 3; ++a)
    extent_m = std::max(extent_m, static_cast<double>(map.size[a]) * spacing[static_cast<Eigen::Index>(a)]);
  const double closing_m = std::max(options.closing_radius_m, options.max_closing_radius_m);
  const auto dims = fmt::format("{} x {} x {} voxels, {:.4g} mm at its widest", map.size[0], map.size[1], map.size[2],
                                extent_m * 1e3);
  if (3.0 * options.smoothing_m > extent_m) {
    throw ValueError(fmt::format("{}: smoothing: a sigma of {:.4g} mm blurs beyond the whole label map ({}); "
                                 "expected at most {:.3g} mm (a third of its widest side)",
                                 name, options.smoothing_m * 1e3, dims, extent_m / 3 * 1e3));
  }
  if (closing_m > extent_m) {
    throw ValueError(fmt::format("{}: closing: a radius of {:.4g} mm is beyond the whole label map ({}); expected at "
                                 "most {:.3g} mm",
                                 name, closing_m * 1e3, dims, extent_m * 1e3));
  }
}

// check_label_surface_size's check of the surface's size, from the count of the labels' voxels.
void check_label_count(const image::LabelMap& map, const std::string& name, std::size_t count,
                       const LabelSurfaceOptions& options) {
  const double volume_m3 = static_cast<double>(count) * map.voxel_volume_m3();
  const double area_m2 = 1.5 * std::cbrt(36.0 * std::numbers::pi * volume_m3 * volume_m3);
  const double vertices = vertex_count_at_edge(area_m2, options.edge_length_m);
  if (!(vertices <= kMaxSurfaceVertices)) {
    throw ValueError(
        fmt::format("{}: edge: {:.4g} mL of labels (about {:.4g} cm2 of surface) at a facet size of {:.4g} "
                    "mm would have about {:.3g} vertices; expected at most {:.0f} (a coarser edge)",
                    name, volume_m3 * 1e6, area_m2 * 1e4, options.edge_length_m * 1e3, vertices, kMaxSurfaceVertices));
  }
}

}  // namespace

void check_label_surface_size(const image::LabelMap& map, const std::string& name, const std::vector<int>& labels,
                              const LabelSurfaceOptions& options) {
  check_label_extent(map, name, options);
  // Counted slice by slice on every core (a whole map of 70 Mvoxels; #50), summed in order.
  std::vector<std::size_t> per_slice(map.size[2], 0);
  const std::size_t slice = map.size[0] * map.size[1];
  core::for_each_index(
      map.size[2],
      [&](std::size_t k) {
        LabelTest wanted(labels);
        const std::int32_t* at = map.labels.data() + k * slice;
        std::size_t n = 0;
        for (std::size_t v = 0; v < slice; ++v) n += wanted(at[v]) ? 1 : 0;
        per_slice[k] = n;
      },
      1);
  std::size_t count = 0;
  for (const std::size_t n : per_slice) count += n;
  check_label_count(map, name, count, options);
}

LabelSurface surface_from_labels(const std::filesystem::path& path, const std::vector<int>& labels,
                                 const LabelSurfaceOptions& options) {
  return surface_from_labels(image::read_label_map(path), path.string(), labels, options);
}

LabelSurface surface_from_labels(const image::LabelMap& map, const std::string& name, const std::vector<int>& labels,
                                 const LabelSurfaceOptions& options) {
  auto positive = [](double x) { return x > 0.0 && std::isfinite(x); };
  auto non_negative = [](double x) { return x >= 0.0 && std::isfinite(x); };
  if (!positive(options.edge_length_m))
    throw std::invalid_argument("surface_from_labels: the edge length must be positive");
  if (!non_negative(options.smoothing_m) || !non_negative(options.closing_radius_m) ||
      !non_negative(options.max_distance_m) || !non_negative(options.max_closing_radius_m)) {
    throw std::invalid_argument("surface_from_labels: smoothing, closing and distance must be >= 0");
  }
  if (labels.empty()) throw std::invalid_argument("surface_from_labels: no labels given");
  if (map.labels.size() != map.voxel_count())
    throw std::invalid_argument("surface_from_labels: label map size mismatch");
  check_label_extent(map, name, options);  // the size of the surface once the labels are counted

  LabelSurface result;
  LabelSurfaceReport& rep = result.report;
  rep.source = name;
  rep.labels = labels;
  std::sort(rep.labels.begin(), rep.labels.end());
  rep.labels.erase(std::unique(rep.labels.begin(), rep.labels.end()), rep.labels.end());
  rep.transform_source = map.transform_source;
  rep.size = map.size;
  rep.spacing_m = map.spacing_m();
  rep.voxel_volume_m3 = map.voxel_volume_m3();
  rep.smoothing_m = options.smoothing_m;
  rep.edge_length_m = options.edge_length_m;
  rep.max_distance_m = options.max_distance_m > 0.0 ? options.max_distance_m : options.edge_length_m / 8.0;

  // 1. The union, its voxel bounds, and a check that every label is there: slice by slice on
  // every core (#50), each slice's counts and bounds merged in order (sums, minima and maxima:
  // the same whatever the split).
  struct SliceScan {
    std::map<int, std::size_t> counts;
    Size3 lo{std::numeric_limits<std::size_t>::max(), std::numeric_limits<std::size_t>::max(), 0};
    Size3 hi{0, 0, 0};
    bool any = false;
  };
  std::vector<SliceScan> slices(map.size[2]);
  core::for_each_index(
      map.size[2],
      [&](std::size_t k) {
        SliceScan& scan = slices[k];
        LabelTest wanted(rep.labels);
        // Counted by runs of one label (a map is mostly long runs of background).
        std::size_t v = k * map.size[0] * map.size[1], run = 0;
        std::int32_t run_label = map.labels[v];
        for (std::size_t j = 0; j < map.size[1]; ++j) {
          // The row's first and last wanted voxel; the box grows once per row.
          std::size_t first = map.size[0], last = 0;
          for (std::size_t i = 0; i < map.size[0]; ++i, ++v) {
            const std::int32_t l = map.labels[v];
            if (l != run_label) scan.counts[run_label] += run, run_label = l, run = 0;
            ++run;
            if (!wanted(l)) continue;
            first = std::min(first, i);
            last = i;
          }
          if (first == map.size[0]) continue;
          scan.lo[0] = std::min(scan.lo[0], first), scan.hi[0] = std::max(scan.hi[0], last);
          scan.lo[1] = std::min(scan.lo[1], j), scan.hi[1] = std::max(scan.hi[1], j);
          scan.any = true;
        }
        if (run > 0) scan.counts[run_label] += run;
      },
      1);
  std::map<int, std::size_t> counts;
  Size3 lo{map.size[0], map.size[1], map.size[2]}, hi{0, 0, 0};
  for (std::size_t k = 0; k < slices.size(); ++k) {
    const SliceScan& scan = slices[k];
    for (const auto& [label, n] : scan.counts) counts[label] += n;
    if (!scan.any) continue;
    for (std::size_t a = 0; a < 2; ++a) lo[a] = std::min(lo[a], scan.lo[a]), hi[a] = std::max(hi[a], scan.hi[a]);
    lo[2] = std::min(lo[2], k), hi[2] = std::max(hi[2], k);
  }
  slices.clear();
  std::size_t wanted_voxels = 0;
  for (int l : rep.labels) wanted_voxels += counts.count(l) ? counts[l] : 0;
  check_label_count(map, name, wanted_voxels, options);  // before a missing label, as check_label_surface_size
  for (int l : rep.labels) {
    if (counts.count(l)) continue;
    std::string present;
    std::size_t shown = 0;
    for (const auto& [value, n] : counts) {
      if (shown++ == 20) {
        present += ", ...";
        break;
      }
      if (!present.empty()) present += ", ";
      present += std::to_string(value);
    }
    throw InputError(fmt::format("{}: label {} is not in the file (labels present: {})", name, l, present));
  }
  for (int l : rep.labels) rep.label_voxels += counts[l];

  // The crop: the labels' bounds, padded for the largest closing, the blur and a margin.
  const Eigen::Vector3d spacing = rep.spacing_m;
  const double reach = std::max(options.closing_radius_m, options.max_closing_radius_m) + 3.0 * options.smoothing_m;
  Grid g;
  Size3 origin{};
  for (std::size_t a = 0; a < 3; ++a) {
    const auto pad = static_cast<std::size_t>(std::ceil(reach / spacing[static_cast<Eigen::Index>(a)])) + 2;
    origin[a] = lo[a] >= pad ? lo[a] - pad : 0;  // voxels outside the file are background anyway
    g.n[a] = hi[a] + pad + 1 - origin[a];        // may run past the file: read as background
  }
  std::vector<std::uint8_t> base(g.count(), 0);
  core::for_each_index(
      g.n[2],
      [&](std::size_t k) {
        const std::size_t fk = origin[2] + k;
        if (fk >= map.size[2]) return;
        LabelTest wanted(rep.labels);
        for (std::size_t j = 0; j < g.n[1]; ++j) {
          const std::size_t fj = origin[1] + j;
          if (fj >= map.size[1]) break;
          for (std::size_t i = 0; i < g.n[0]; ++i) {
            const std::size_t fi = origin[0] + i;
            if (fi >= map.size[0]) break;
            base[g.index(i, j, k)] = wanted(map.labels[fi + map.size[0] * (fj + map.size[1] * fk)]) ? 1 : 0;
          }
        }
      },
      1);

  // 2. Islands.
  if (options.keep_largest_component) {
    std::tie(rep.dropped_islands, rep.dropped_island_voxels) = keep_largest_component(g, base);
  }

  detail::ScalarGrid field;
  field.size = g.n;
  Eigen::Matrix4d shift = Eigen::Matrix4d::Identity();
  shift.block<3, 1>(0, 3) << static_cast<double>(origin[0]), static_cast<double>(origin[1]),
      static_cast<double>(origin[2]);
  field.index_to_lps = map.ijk_to_lps * shift;
  field.lps_to_index = field.index_to_lps.inverse();

  // Attempts: the closing radius asked for; then with slice holes filled but the dents from below
  // left open; then, where some were left and the surface still has a handle, with those filled
  // too; then the same at a doubled radius while the genus is above 0 and the radius allows. The
  // closed mask is kept while the radius stays (the later attempts close as the first did).
  VerticalAxis vertical = vertical_axis(map.ijk_to_lps);
  // Deeper than twice the blur's sigma (3 slices of 1 mm at the default 1 mm).
  vertical.min_dent_slices =
      static_cast<std::size_t>(
          std::floor(2.0 * options.smoothing_m / spacing[static_cast<Eigen::Index>(vertical.axis)] * (1.0 + 1e-9))) +
      1;
  double radius = options.closing_radius_m;
  bool slice_holes = false, leave_dents = false;
  std::vector<std::uint8_t> closed;
  double closed_radius = -1.0;
  rep.meshings = 0;
  for (int attempt = 1;; ++attempt) {
    // 3. Closing (and tunnels), 4. cavities.
    if (radius != closed_radius) {
      closed = base;
      rep.closing_added_voxels = close_mask(g, closed, spacing, radius);
      closed_radius = radius;
    }
    std::vector<std::uint8_t> mask = closed;
    rep.closing_radius_m = radius;
    const SliceHoles holes = slice_holes ? fill_slice_holes(g, mask, vertical, leave_dents) : SliceHoles{};
    rep.slice_hole_voxels = holes.filled_voxels;
    rep.dents_left = holes.dents;
    rep.dent_voxels_left = holes.dent_voxels;
    rep.filled_slice_holes = slice_holes;
    rep.filled_cavities = rep.filled_cavity_voxels = 0;
    if (options.fill_cavities) std::tie(rep.filled_cavities, rep.filled_cavity_voxels) = fill_cavities(g, mask);
    rep.mask_voxels = static_cast<std::size_t>(std::count(mask.begin(), mask.end(), std::uint8_t{1}));
    rep.attempts = attempt;
    // 5. Smoothing, 6. meshing.
    field.values = blur(g, mask, spacing, options.smoothing_m);
    mask.clear();
    mask.shrink_to_fit();
    const bool can_grow = radius > 0.0 && 2.0 * radius <= options.max_closing_radius_m * (1.0 + 1e-9);
    const bool dents_to_fill = holes.dents > 0;
    const bool last = !options.remove_handles || (slice_holes && !can_grow && !dents_to_fill);
    // The next attempt after a handle: slice holes; the dents filled too; a doubled radius.
    auto next_attempt = [&] {
      if (!slice_holes) {
        slice_holes = leave_dents = true;
      } else if (dents_to_fill) {
        leave_dents = false;
      } else {
        radius *= 2.0;
        leave_dents = true;
      }
    };
    // Handles on the blurred mask's samples, in both cubical models between which the trilinear
    // level set lies (islands and cavities only raise the characteristic), are handles of the
    // surface Mesh_3 would make: the next attempt, without meshing this one. On the twelve CT
    // lungs this skips exactly the meshings whose surface had a handle (BENCHMARKS.md, #50).
    if (!last) {
      const detail::LevelSetEuler chi = detail::level_set_euler_characteristics(field);
      if (chi.thin < 1 && chi.thick < 1) {
        field.values.clear();
        next_attempt();
        continue;
      }
    }
    TriangleMesh mesh = detail::mesh_level_set(field, rep.edge_length_m, rep.max_distance_m);
    ++rep.meshings;
    field.values.clear();
    if (mesh.triangles.empty()) {
      throw InputError(
          fmt::format("{}: labels {}: no surface found ({} voxels): expected a region at least a few voxels "
                      "thick",
                      name, join_labels(rep.labels), rep.label_voxels));
    }
    rep.dropped_surface_components = keep_largest_surface(mesh);
    // 7. Genus.
    const ValidationReport check = validate(mesh, {.check_self_intersections = false});
    rep.genus = check.genus.value_or(-1);
    const bool done = rep.genus == 0 || last;
    if (done || !check.genus) {
      rep.volume_m3 = enclosed_volume(mesh);
      rep.area_m2 = surface_area(mesh);
      result.mesh = std::move(mesh);
      break;
    }
    next_attempt();
  }
  return result;
}

}  // namespace pneuma::mesh
