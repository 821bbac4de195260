#pragma once
// A bounding-box hierarchy over a surface's faces for the rays from its vertices
// (first_hits_from_vertices): built on every thread with the same layout at any thread count,
// walked near child first so that a ray that has found its face skips the boxes beyond it.
// CGAL's AABB tree built serially and walked every box a ray's segment met, through the lung to
// the end of its reach: most of the realistic field's ray time (BENCHMARKS.md, #50).
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh::detail {

// The least float >= x.
inline float rounded_up(double x) {
  const auto f = static_cast<float>(x);
  return static_cast<double>(f) < x ? std::nextafter(f, std::numeric_limits<float>::infinity()) : f;
}

// A box in floats, rounded outward from the doubles it bounds, so it holds them.
struct FloatBox {
  std::array<float, 3> low{};
  std::array<float, 3> high{};
};

// The interval [enter, leave] of t in [0, limit] over which from + t along lies in `box` grown
// by `margin` (a slab test in doubles); enter > leave where it misses. With the same arguments
// a larger box gives a wider interval (each step is monotonic), so a box that holds another is
// met wherever the other is.
template <class Box>
inline std::pair<double, double> segment_in_box(const Box& box, const Eigen::Vector3d& from,
                                                const Eigen::Vector3d& inverse, double limit, double margin) {
  double enter = 0.0, leave = limit;
  for (int k = 0; k < 3; ++k) {
    const auto a = static_cast<std::size_t>(k);
    const double low = static_cast<double>(box.low[a]) - margin, high = static_cast<double>(box.high[a]) + margin;
    if (std::isinf(inverse[k])) {  // the segment does not move along this axis
      if (from[k] < low || from[k] > high) return {1.0, 0.0};
      continue;
    }
    double t0 = (low - from[k]) * inverse[k], t1 = (high - from[k]) * inverse[k];
    if (t0 > t1) std::swap(t0, t1);
    enter = std::max(enter, t0);
    leave = std::min(leave, t1);
    if (enter > leave) return {1.0, 0.0};
  }
  return {enter, leave};
}

// Each internal node splits its faces (consecutive along a Morton curve of their centres) where
// the highest bit of the curve's code that differs among them flips (the middle where they share
// one cell), so that each node's faces lie in one cell of an octree-like subdivision and its box
// is tight. A node is named by its split: its faces before position s + 1 go left, so the names
// are the same whatever order the nodes are built in (on every thread).
class FaceBoxTree {
 public:
  explicit FaceBoxTree(const TriangleMesh& mesh);

  // The faces in the tree's order (along the curve): neighbouring faces are near each other, and
  // so are the nodes that hold them.
  const std::vector<std::uint32_t>& faces_along_curve() const { return face_; }

  // Up to kPacket segments walked together: segment r (r < count) runs from from[r] along
  // along[r] (t in [0, 1]; inverse[r] its componentwise inverse, +-inf where it does not move).
  // Calls `visit(r, face)` for every face whose node's box, grown by `margin`, segment r meets
  // before its limit; `visit` returns segment r's new limit (at most the one before), and the
  // nodes it enters after that are skipped. Nodes are walked nearer first (for the first segment
  // that meets both children), so that a segment that has found its face skips the boxes beyond.
  // The boxes are tested in floats on boxes grown further (FloatRay): some faces more are
  // visited, never one fewer. Neighbouring rays meet mostly the same nodes: each node is read
  // and its boxes tested once for the packet, the segments' tests side by side (one ray at a
  // time, the walk's branches on the boxes waited on each other and were mispredicted).
  static constexpr std::size_t kPacket = 4;
  template <class Visit>
  void walk_packet(const std::array<Eigen::Vector3d, kPacket>& from,
                   const std::array<Eigen::Vector3d, kPacket>& inverse, std::size_t count, double margin,
                   Visit&& visit) const {
    if (face_.empty() || count == 0) return;
    // The segments' float rays side by side; a lane without a segment (or whose segment misses
    // the root's box) has a limit below every t, so no box is met in it.
    std::array<std::array<float, kPacket>, 3> below{}, above{}, inv{};
    std::array<float, kPacket> limit{};
    std::uint32_t lanes = 0;
    for (std::size_t r = 0; r < kPacket; ++r) {
      limit[r] = -1.0F;
      if (r >= count) continue;
      const FloatRay ray(from[r], inverse[r], margin, scale_);
      for (std::size_t k = 0; k < 3; ++k) {
        below[k][r] = ray.below[k];
        above[k][r] = ray.above[k];
        inv[k][r] = ray.inverse[k];
      }
      const auto [enter, leave] = segment_in_box(root_box_, from[r], inverse[r], 1.0, margin);
      if (face_.size() > 1 && enter > leave) continue;
      limit[r] = 1.0F;
      lanes |= 1U << r;
    }
    if (lanes == 0) return;
    if (face_.size() == 1) {
      for (std::size_t r = 0; r < count; ++r) visit(r, face_[0]);
      return;
    }
    struct Pending {
      std::array<float, kPacket> enter;
      std::uint32_t child;
      std::uint32_t lanes;
    };
    std::array<Pending, 66> stack;  // one pending child per level: the depth is at most 64
    std::size_t top = 0;
    stack[top++] = Pending{{}, root_, lanes};
    while (top > 0) {
      const Pending next = stack[--top];
      std::uint32_t live = 0;
      for (std::size_t r = 0; r < kPacket; ++r) live |= (next.enter[r] <= limit[r] ? 1U : 0U) << r;
      live &= next.lanes;
      if (live == 0) continue;
      if (next.child & kFace) {
        const std::uint32_t face = face_[next.child & ~kFace];
        for (std::size_t r = 0; r < kPacket; ++r) {
          if (live & (1U << r)) limit[r] = std::min(limit[r], rounded_up(visit(r, face)));
        }
        continue;
      }
      const Node& node = node_[next.child];
      std::array<Pending, 2> child;
      for (std::size_t c = 0; c < 2; ++c) {
        std::array<float, kPacket> in{}, out = limit;
        for (std::size_t k = 0; k < 3; ++k) {
          for (std::size_t r = 0; r < kPacket; ++r) {
            const float t0 = (node.low[k][c] - below[k][r]) * inv[k][r];
            const float t1 = (node.high[k][c] - above[k][r]) * inv[k][r];
            in[r] = std::max(in[r], std::min(t0, t1));
            out[r] = std::min(out[r], std::max(t0, t1));
          }
        }
        std::uint32_t met = 0;
        for (std::size_t r = 0; r < kPacket; ++r) met |= (in[r] <= out[r] ? 1U : 0U) << r;
        child[c] = Pending{in, node.child[c], met & live};
      }
      // The nearer child (for the first segment that meets both) on top, walked first.
      const std::uint32_t both = child[0].lanes & child[1].lanes;
      bool left_first = true;
      if (both != 0) {
        const auto r = static_cast<std::size_t>(std::countr_zero(both));
        left_first = child[0].enter[r] <= child[1].enter[r];
      }
      const Pending& first = left_first ? child[0] : child[1];
      const Pending& second = left_first ? child[1] : child[0];
      if (second.lanes != 0) stack[top++] = second;
      if (first.lanes != 0) stack[top++] = first;
    }
  }

 private:
  static constexpr std::uint32_t kFace = 0x80000000U;  // a child that is a face: its position in face_
  // The children's boxes, [axis][child], and the children, in one cache line.
  // Left uninitialised when allocated (build writes every node once, on the thread that builds
  // it): zeroing 64 bytes a face first cost a serial pass over fresh pages.
  struct alignas(64) Node {
    std::array<std::array<float, 2>, 3> low;
    std::array<std::array<float, 2>, 3> high;
    std::array<std::uint32_t, 2> child;  // node names, or kFace | position
  };
  static constexpr double kPad = 1e-5;
  static constexpr double kLargeInverse = 1e30;
  // A segment for the slab test in floats. The boxes are grown by `pad`, over 20 times the error of
  // the float arithmetic on coordinates up to `scale` and of the t it gives (relative to the
  // segment's length), so that every box the test in doubles meets (grown by `margin`) is met,
  // and entered no later.
  struct FloatRay {
    std::array<float, 3> below{}, above{}, inverse{};  // from + pad, from - pad; 1 / along
    FloatRay(const Eigen::Vector3d& from, const Eigen::Vector3d& inverse_d, double margin, double scale) {
      double length = 0.0, reach = scale;
      for (int k = 0; k < 3; ++k) {
        length = std::max(length, 1.0 / std::abs(inverse_d[k]));
        reach = std::max(reach, std::abs(from[k]));
      }
      const double pad = margin + kPad * (reach + length);
      for (int k = 0; k < 3; ++k) {
        const auto a = static_cast<std::size_t>(k);
        below[a] = static_cast<float>(from[k] + pad);
        above[a] = static_cast<float>(from[k] - pad);
        // An axis it does not move along: a large finite inverse (0 x inf would be NaN).
        inverse[a] = static_cast<float>(std::clamp(inverse_d[k], -kLargeInverse, kLargeInverse));
      }
    }
  };
  struct Built {
    FloatBox box;
    std::uint32_t child;
  };
  // The subtree of the faces at positions [begin, end) (two or more).
  Built build(const std::vector<std::uint64_t>& code, std::size_t begin, std::size_t end,
              const std::vector<FloatBox>& box_of_face);
  Built leaf(std::size_t position, const std::vector<FloatBox>& box_of_face) const;

  std::vector<std::uint32_t> face_;  // the faces along the curve
  std::unique_ptr<Node[]> node_;     // node s splits after position s (n - 1 names)
  std::uint32_t root_ = 0;
  FloatBox root_box_;
  double scale_ = 0.0;  // the largest |coordinate| of the root's box
};

}  // namespace pneuma::mesh::detail
