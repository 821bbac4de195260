#pragma once
// The Shot/UnShot loop and its pieces, in field::detail: not for general use, published for the
// paper's traced comparator (paper/src/comparators.cpp) and the production solver
// (field_solver.cpp), so both shoot in exactly one order.
#include <cstdint>
#include <limits>
#include <span>
#include <vector>
#include "pneuma/core/error.h"
#include "pneuma/field/field_graph.h"
#include "pneuma/field/field_solver.h"

namespace pneuma::field::detail {

// Checks a load (one finite value >= 0 per node) and returns max f (0 when all zero).
// Throws ValueError naming what is wrong.
double check_load(std::span<const double> load, std::size_t node_count);

// An indexed binary max-heap of nodes keyed by their UnShot: position_[node] says where a node
// sits (or npos), so a key can grow (sift up) or shrink (sift down) in O(log n).
class IndexedMaxHeap {
 public:
  static constexpr std::uint32_t npos = std::numeric_limits<std::uint32_t>::max();
  explicit IndexedMaxHeap(std::uint32_t capacity) : position_(capacity, npos) { items_.reserve(1024); }

  bool empty() const { return items_.empty(); }
  bool contains(std::uint32_t node) const { return position_[node] != npos; }
  std::uint32_t top() const { return items_.front().node; }

  void push(std::uint32_t node, double key) {
    items_.push_back({key, node});
    position_[node] = static_cast<std::uint32_t>(items_.size() - 1);
    sift_up(items_.size() - 1);
  }
  // Changes the key of a node in the heap either way (decrease-key or increase-key).
  void update(std::uint32_t node, double key) {
    const std::size_t i = position_[node];
    const double old = items_[i].key;
    items_[i].key = key;
    if (key > old) sift_up(i);
    else sift_down(i);
  }
  void pop() {
    position_[items_.front().node] = npos;
    if (items_.size() > 1) {
      items_.front() = items_.back();
      position_[items_.front().node] = 0;
      items_.pop_back();
      sift_down(0);
    } else {
      items_.pop_back();
    }
  }

 private:
  struct Item {
    double key;
    std::uint32_t node;
  };
  void place(std::size_t i, const Item& item) {
    items_[i] = item;
    position_[item.node] = static_cast<std::uint32_t>(i);
  }
  void sift_up(std::size_t i) {
    const Item item = items_[i];
    while (i > 0) {
      const std::size_t parent = (i - 1) / 2;
      if (!(items_[parent].key < item.key)) break;
      place(i, items_[parent]);
      i = parent;
    }
    place(i, item);
  }
  void sift_down(std::size_t i) {
    const Item item = items_[i];
    const std::size_t n = items_.size();
    while (true) {
      std::size_t child = 2 * i + 1;
      if (child >= n) break;
      if (child + 1 < n && items_[child].key < items_[child + 1].key) ++child;
      if (!(item.key < items_[child].key)) break;
      place(i, items_[child]);
      i = child;
    }
    place(i, item);
  }
  std::vector<Item> items_;
  std::vector<std::uint32_t> position_;
};

// The Shot/UnShot iteration (eq. 4.5 - 4.7): shoots the node holding the most UnShot until
// none holds more than `threshold`. `unshot` starts as the load; `shot` (zeros, same size)
// receives the result. With Count, every addition and multiplication is counted into
// `counts`. `after_shot(steps, heap, unshot)` runs after each shot (the comparator's trace).
// Throws Error(failure) past `step_limit` shots. Returns the number of shots.
template <bool Count, typename AfterShot>
std::uint64_t shoot_until_below(const TransferOperator& op, std::vector<double>& unshot, std::vector<double>& shot,
                                double threshold, std::uint64_t step_limit, OperationCounts& counts,
                                AfterShot&& after_shot) {
  IndexedMaxHeap heap(op.node_count);
  // Nodes at or below the threshold stay out of the heap until they rise above it, so the
  // heap empties exactly when max UnShot <= threshold.
  for (std::uint32_t k = 0; k < op.node_count; ++k) {
    if (unshot[k] > threshold) heap.push(k, unshot[k]);
  }
  std::uint64_t steps = 0;
  while (!heap.empty()) {
    const std::uint32_t k = heap.top();
    heap.pop();
    const double u = unshot[k];
    unshot[k] = 0.0;                  // eq. 4.7
    shot[k] += u * op.self_share[k];  // eq. 4.6
    if constexpr (Count) {
      ++counts.multiplications;
      ++counts.additions;
    }
    for (std::uint64_t j = op.offset[k]; j < op.offset[k + 1]; ++j) {  // eq. 4.5
      const std::uint32_t n = op.target[j];
      const double value = unshot[n] + u * op.share[j];
      if constexpr (Count) {
        ++counts.multiplications;
        ++counts.additions;
      }
      unshot[n] = value;
      if (heap.contains(n)) heap.update(n, value);
      else if (value > threshold) heap.push(n, value);
    }
    if (++steps > step_limit) throw Error(ExitCode::failure, "Shot/UnShot did not converge");
    after_shot(steps, heap, unshot);
  }
  return steps;
}

}  // namespace pneuma::field::detail
