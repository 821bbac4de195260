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

  // For the segment from `from` along `along` (t in [0, 1]; `inverse` its componentwise

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

 public:
  // For the segment from `from` along `along` (t in [0, 1]; `inverse` its componentwise
  // inverse, +-inf where it does not move): calls `visit(face)` for every face whose node's box,
  // grown by `margin`, the segment meets before `limit`, nearer nodes first. `visit` returns
  // the new limit (at most the one before): nodes entered after it are skipped. The nodes' boxes
  // are tested in floats on boxes grown further (FloatRay): some faces more are visited, never
  // one fewer.
  template <class Visit>
  void walk(const Eigen::Vector3d& from, const Eigen::Vector3d& inverse, double margin, Visit&& visit) const {
    Walk w(*this, from, inverse, margin);
    while (!w.done()) {
      const std::uint32_t f = w.step();
      if (f != Walk::kNone) w.lower_limit(visit(f));
    }
  }

 private:
  // One segment's walk, a step at a time.
  class Walk {
   public:
    static constexpr std::uint32_t kNone = 0xffffffffU;
    Walk(const FaceBoxTree& tree, const Eigen::Vector3d& from, const Eigen::Vector3d& inverse, double margin)
        : tree_(&tree), ray_(from, inverse, margin, tree.scale_) {
      if (tree.face_.empty()) return;
      if (tree.face_.size() == 1) {
        stack_[top_++] = pending(kFace, 0.0F);
        return;
      }
      const auto [enter, leave] = segment_in_box(tree.root_box_, from, inverse, 1.0, margin);
      if (enter <= leave) stack_[top_++] = pending(tree.root_, 0.0F);
    }
    bool done() const { return top_ == 0; }
    // One step (not done()): the next face, or kNone where the step tested a node or skipped one.
    std::uint32_t step() {
      const std::uint64_t next = stack_[--top_];
      if (std::bit_cast<float>(static_cast<std::uint32_t>(next >> 32)) > limit_) return kNone;
      const auto child = static_cast<std::uint32_t>(next);
      if (child & kFace) return tree_->face_[child & ~kFace];
      // Both children's boxes lie in their parent (one cache line), a face's too: a face whose
      // box the segment misses is not yielded.
      const Node& node = tree_->node_[child];
      std::array<float, 2> in{0.0F, 0.0F}, out{limit_, limit_};
      for (std::size_t k = 0; k < 3; ++k) {
        for (std::size_t c = 0; c < 2; ++c) {
          const float t0 = (node.low[k][c] - ray_.below[k]) * ray_.inverse[k];
          const float t1 = (node.high[k][c] - ray_.above[k]) * ray_.inverse[k];
          in[c] = std::max(in[c], std::min(t0, t1));
          out[c] = std::min(out[c], std::max(t0, t1));
        }
      }
      // The nearer child on top, walked first (ties: the left), without a branch on which.
      const bool left_met = in[0] <= out[0], right_met = in[1] <= out[1];
      const std::uint64_t left = pending(node.child[0], in[0]), right = pending(node.child[1], in[1]);
      const bool left_first = in[0] <= in[1];
      const std::uint64_t near = left_first ? left : right, far = left_first ? right : left;
      stack_[top_] = left_met && right_met ? far : (left_met ? left : right);
      stack_[top_ + 1] = near;
      top_ += static_cast<std::size_t>(left_met) + static_cast<std::size_t>(right_met);
      return kNone;
    }
    void lower_limit(double limit) { limit_ = std::min(limit_, rounded_up(limit)); }

   private:
    // A pending child and the t at which the segment enters its box, in one 8-byte word (written
    // as two 4-byte halves and read back whole, the stack stalled on store forwarding).
    static std::uint64_t pending(std::uint32_t child, float enter) {
      return static_cast<std::uint64_t>(std::bit_cast<std::uint32_t>(enter)) << 32 | child;
    }
    const FaceBoxTree* tree_;
    FloatRay ray_;
    float limit_ = 1.0F;
    std::size_t top_ = 0;
    std::array<std::uint64_t, 130> stack_;  // one pending child per level (depth at most 64), a spare
  };
};

}  // namespace pneuma::mesh::detail
