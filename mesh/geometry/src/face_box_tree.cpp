#include "face_box_tree.h"

#include <tbb/task_group.h>

#include <algorithm>
#include <bit>
#include <limits>

#include "pneuma/core/error.h"
#include "pneuma/core/parallel.h"
#include "pneuma/core/tsan.h"

namespace pneuma::mesh::detail {
namespace {

// Subtrees of more faces than this are built on two tasks.
constexpr std::size_t kParallelFaces = 8192;
constexpr int kMortonBits = 21;  // per axis: 63 bits in all

// x's low 21 bits spread to every third bit.
std::uint64_t spread_bits(std::uint64_t x) {
  x &= 0x1fffffULL;
  x = (x | x << 32) & 0x1f00000000ffffULL;
  x = (x | x << 16) & 0x1f0000ff0000ffULL;
  x = (x | x << 8) & 0x100f00f00f00f00fULL;
  x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
  x = (x | x << 2) & 0x1249249249249249ULL;
  return x;
}

float rounded_down(double x) {
  const auto f = static_cast<float>(x);
  return static_cast<double>(f) > x ? std::nextafter(f, -std::numeric_limits<float>::infinity()) : f;
}

// The box of triangle (a, b, c), rounded outward to floats.
FloatBox rounded_out_box(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  FloatBox out;
  for (std::size_t k = 0; k < 3; ++k) {
    const auto ik = static_cast<int>(k);
    out.low[k] = rounded_down(std::min({a[ik], b[ik], c[ik]}));
    out.high[k] = rounded_up(std::max({a[ik], b[ik], c[ik]}));
  }
  return out;
}

}  // namespace

FaceBoxTree::FaceBoxTree(const TriangleMesh& mesh) {
  const std::size_t n = mesh.triangle_count();
  if (n == 0) return;
  if (n > std::numeric_limits<std::uint32_t>::max()) throw ValueError("FaceBoxTree: too many faces");
  const auto& p = mesh.vertices;
  const std::array<Eigen::Vector3d, 2> bounds = bounding_box(p);
  const Eigen::Vector3d& low = bounds[0];
  const Eigen::Vector3d extent = (bounds[1] - low).cwiseMax(std::numeric_limits<double>::min());
  constexpr double kCells = static_cast<double>(1U << kMortonBits);
  // Each face's key: its centre's Morton code, then its index, so that the order is total and
  // the sorted order the same whatever the sort's schedule.
  struct Key {
    std::uint64_t code;
    std::uint32_t face;
    bool operator<(const Key& other) const { return code != other.code ? code < other.code : face < other.face; }
  };
  std::vector<Key> keys(n);
  // Each face's box too, here where its corners are read in the file's order (read through the
  // curve's order in build, each leaf's triangle and corners were a scattered gather).
  std::vector<FloatBox> box_of_face(n);
  core::for_each_index(n, [&](std::size_t f) {
    const auto& t = mesh.triangles[f];
    box_of_face[f] = rounded_out_box(p[t[0]], p[t[1]], p[t[2]]);
    const Eigen::Vector3d centre = (p[t[0]] + p[t[1]] + p[t[2]]) / 3.0;
    std::uint64_t code = 0;
    for (int a = 0; a < 3; ++a) {
      const double cell = std::clamp((centre[a] - low[a]) / extent[a] * kCells, 0.0, kCells - 1.0);
      code |= spread_bits(static_cast<std::uint64_t>(cell)) << a;
    }
    keys[f] = {code, static_cast<std::uint32_t>(f)};
  });
  // Each half sorted on its own task, then merged: tbb::parallel_sort's tasks cannot be wrapped in
  // a tsan::Region, so ThreadSanitizer would see its writes race with the reads below.
  {
    const auto middle = keys.begin() + static_cast<std::ptrdiff_t>(n / 2);
    const tsan::Region region;
    tbb::task_group halves;
    halves.run(region.wrap([&] { std::sort(keys.begin(), middle); }));
    halves.run(region.wrap([&] { std::sort(middle, keys.end()); }));
    halves.wait();
    region.join();
    std::inplace_merge(keys.begin(), middle, keys.end());
  }
  face_.resize(n);

  std::vector<std::uint64_t> code(n);
  core::for_each_index(n, [&](std::size_t k) {
    face_[k] = keys[k].face;
    code[k] = keys[k].code;
  });
  keys = {};
  if (n == 1) return;
  node_ = std::make_unique_for_overwrite<Node[]>(n - 1);
  const Built root = build(code, 0, n, box_of_face);
  root_ = root.child;
  root_box_ = root.box;
  for (std::size_t a = 0; a < 3; ++a) {
    scale_ = std::max(
        {scale_, std::abs(static_cast<double>(root_box_.low[a])), std::abs(static_cast<double>(root_box_.high[a]))});
  }
}

FaceBoxTree::Built FaceBoxTree::leaf(std::size_t position, const std::vector<FloatBox>& box_of_face) const {
  return {box_of_face[face_[position]], kFace | static_cast<std::uint32_t>(position)};
}

FaceBoxTree::Built FaceBoxTree::build(const std::vector<std::uint64_t>& code, std::size_t begin, std::size_t end,
                                      const std::vector<FloatBox>& box_of_face) {
  // Split where the highest differing bit flips (the codes are sorted, so it flips once), or in
  // the middle where every code is the same.
  std::size_t split = begin + (end - begin) / 2;
  if (code[begin] != code[end - 1]) {
    const int bit = 63 - std::countl_zero(code[begin] ^ code[end - 1]);
    split = static_cast<std::size_t>(std::partition_point(code.begin() + static_cast<std::ptrdiff_t>(begin),
                                                          code.begin() + static_cast<std::ptrdiff_t>(end),
                                                          [bit](std::uint64_t c) { return ((c >> bit) & 1U) == 0; }) -
                                     code.begin());
  }
  const auto side = [&](std::size_t from, std::size_t to) {
    return to - from == 1 ? leaf(from, box_of_face) : build(code, from, to, box_of_face);
  };
  Built left, right;
  if (end - begin > kParallelFaces) {
    const tsan::Region region;
    tbb::task_group both;
    both.run(region.wrap([&] { left = side(begin, split); }));
    both.run(region.wrap([&] { right = side(split, end); }));
    both.wait();
    region.join();
  } else {
    left = side(begin, split);
    right = side(split, end);
  }
  const auto name = static_cast<std::uint32_t>(split - 1);
  Node& node = node_[name];
  for (std::size_t a = 0; a < 3; ++a) {
    node.low[a] = {left.box.low[a], right.box.low[a]};
    node.high[a] = {left.box.high[a], right.box.high[a]};
  }
  node.child = {left.child, right.child};
  Built out{{}, name};
  for (std::size_t a = 0; a < 3; ++a) {
    out.box.low[a] = std::min(left.box.low[a], right.box.low[a]);
    out.box.high[a] = std::max(left.box.high[a], right.box.high[a]);
  }
  return out;
}

}  // namespace pneuma::mesh::detail
