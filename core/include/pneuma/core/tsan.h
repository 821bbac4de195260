#pragma once
// ThreadSanitizer and TBB. libtbb is not built with -fsanitize=thread, so ThreadSanitizer does
// not see the synchronisation inside TBB's scheduler: it would report every parallel loop's
// inputs (written before the loop, read in a body) and outputs (written in a body, read after the
// loop) as data races. A Region tells it what TBB guarantees, and nothing more: what the caller
// did before the loop happens before every body, and every body happens before what the caller
// does once the loop has returned. Bodies stay unordered with one another, so a race between two
// bodies is still reported.
//
//   const tsan::Region region;
//   tbb::parallel_for(range, region.wrap([&](const auto& r) { ... }));  // or task_group::run
//   region.join();  // after the loop (or task_group::wait) has returned
//
// In any other build every call is empty and compiles to nothing. tests/tsan.supp holds the
// reports left inside TBB's own code; docs/DEVELOPING.md says how to run the tsan preset.

#include <type_traits>
#include <utility>

#if defined(__SANITIZE_THREAD__)
#define PNEUMA_TSAN 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define PNEUMA_TSAN 1
#endif
#endif

#ifdef PNEUMA_TSAN
extern "C" void __tsan_acquire(void* addr);
extern "C" void __tsan_release(void* addr);
#endif

namespace pneuma::tsan {

#ifdef PNEUMA_TSAN
inline void acquire(const void* address) { __tsan_acquire(const_cast<void*>(address)); }
inline void release(const void* address) { __tsan_release(const_cast<void*>(address)); }
#else
inline void acquire(const void*) {}
inline void release(const void*) {}
#endif

class Region;

// A loop body (or task) made by Region::wrap. Each object is its own synchronisation address, so
// a body reads nothing before it has acquired: the object that made it (the caller's, or the copy
// TBB split it from) released it once written, and every copy acquires its source first.
template <typename F>
class Body {
 public:
  Body(const Region& region, F f);
  Body(const Body& other) : f_((acquire(&other), other.f_)), end_(other.end_) { release(this); }
  Body(Body&& other) noexcept(std::is_nothrow_move_constructible_v<F>)
      : f_((acquire(&other), std::move(other.f_))), end_(other.end_) {
    release(this);
  }
  Body& operator=(const Body&) = delete;
  Body& operator=(Body&&) = delete;
  ~Body() { acquire(this); }  // a cancelled task is destroyed by a thread that never ran it

  // Returns what the body returns (a parallel_reduce body or join gives its partial result).
  template <typename... Args>
  decltype(auto) operator()(Args&&... args) const {
    acquire(this);
    if constexpr (std::is_void_v<std::invoke_result_t<const F&, Args...>>) {
      f_(std::forward<Args>(args)...);
      release(end_);
    } else {
      auto result = f_(std::forward<Args>(args)...);
      release(end_);
      return result;
    }
  }

 private:
  F f_;
  const void* end_;  // the Region's, released after each call
};

// The caller's side of one loop or task group (see the top of this file).
class Region {
 public:
  Region() = default;
  Region(const Region&) = delete;
  Region& operator=(const Region&) = delete;
  ~Region() = default;

  template <typename F>
  Body<F> wrap(F f) const {
    return Body<F>(*this, std::move(f));
  }
  // Every body called so far happens before what follows.
  void join() const { acquire(&end_); }

 private:
  template <typename>
  friend class Body;
  char end_ = 0;
};

template <typename F>
Body<F>::Body(const Region& region, F f) : f_(std::move(f)), end_(&region.end_) {
  release(this);
}

}  // namespace pneuma::tsan
