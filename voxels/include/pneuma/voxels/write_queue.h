#pragma once
// Files written on a thread of their own, one after another in the order given, while the caller
// computes the next thing (#50: a native time point's compression overlapped with computing its
// next field; BENCHMARKS.md, "Voxel outputs"). Each file's bytes are what the same writer makes
// on the caller's thread: only when it runs changes. Under a TBB limit of one thread
// (`--threads 1`) each write runs at once on the caller's thread, so that one thread means one.
#include <condition_variable>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>

namespace pneuma::voxels {

class WriteQueue {
 public:
  WriteQueue() = default;
  WriteQueue(const WriteQueue&) = delete;
  WriteQueue& operator=(const WriteQueue&) = delete;
  // Waits for the write under way and drops those queued after it (a queue destroyed before
  // wait() is being unwound by another error: its files are not wanted), and their errors.
  ~WriteQueue();

  // Queues `write`; what it reads must not change until wait() returns. Under one thread it runs
  // here and now, and its error comes from add().
  void add(std::function<void()> write);
  // Returns when every write queued has run; rethrows the first one's error (the later ones are
  // not run after an error).
  void wait();

 private:
  void work();
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<std::function<void()>> queue_;
  bool busy_ = false, stop_ = false;
  std::exception_ptr error_;
  std::thread thread_;  // started by the first add() that does not run at once
};

}  // namespace pneuma::voxels
