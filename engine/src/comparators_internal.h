#pragma once
// Helpers shared by the comparators' .cpp files (not installed).
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "pneuma/engine/comparators.h"

namespace pneuma::engine::detail {

// splitmix64 (Steele, Lea, Flood 2014): tiny, seedable, and the same numbers on every
// platform, unlike the standard library's distributions.
class SplitMix64 {
 public:
  explicit SplitMix64(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }
  // Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }

 private:
  std::uint64_t state_;
};

// Checks a load (size, finite, >= 0) and returns its maximum. Throws std::invalid_argument.
double check_load(std::span<const double> load, std::size_t expected);
double seconds_since(std::chrono::steady_clock::time_point start);

// Records a trace at steps 0, 1, 2, ... growing by about 3 % each time (a few hundred records
// for millions of steps), and wherever force_next() asks.
class TraceSampler {
 public:
  bool due(std::uint64_t step) const { return step >= next_; }
  void force_next() { next_ = 0; }
  void record(ConvergenceTrace& trace, std::uint64_t step, std::uint64_t operations, double residual, double probe) {
    if (!trace.step.empty() && trace.step.back() == step) {  // the final record replaces a same-step one
      trace.step.pop_back();
      trace.operations.pop_back();
      trace.residual.pop_back();
      trace.probe.pop_back();
    }
    trace.step.push_back(step);
    trace.operations.push_back(operations);
    trace.residual.push_back(residual);
    trace.probe.push_back(probe);
    next_ = std::max(step + 1, static_cast<std::uint64_t>(std::ceil(static_cast<double>(step) * 1.03)));
  }

 private:
  std::uint64_t next_ = 0;
};

// The indexed binary max-heap of field_solver.cpp (same push / update / pop logic, so the
// traced Shot/UnShot shoots in exactly the production order).
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

}  // namespace pneuma::engine::detail
