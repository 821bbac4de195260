// A writer thread with a queue (write_queue.h).
#include "pneuma/voxels/write_queue.h"

#include <tbb/global_control.h>

namespace pneuma::voxels {

WriteQueue::~WriteQueue() {
  {
    const std::lock_guard lock(mutex_);
    queue_.clear();  // the one being written finishes; an unwinding run needs no more files
    stop_ = true;
  }
  changed_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void WriteQueue::add(std::function<void()> write) {
  if (tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism) <= 1) {
    wait();  // an earlier error first
    write();
    return;
  }
  {
    const std::lock_guard lock(mutex_);
    if (error_) return;  // wait() reports it; nothing after it is written
    queue_.push_back(std::move(write));
    if (!thread_.joinable()) thread_ = std::thread([this] { work(); });
  }
  changed_.notify_all();
}

void WriteQueue::wait() {
  std::unique_lock lock(mutex_);
  changed_.wait(lock, [this] { return queue_.empty() && !busy_; });
  if (error_) {
    const std::exception_ptr error = error_;
    error_ = nullptr;
    std::rethrow_exception(error);
  }
}

void WriteQueue::work() {
  std::unique_lock lock(mutex_);
  while (true) {
    changed_.wait(lock, [this] { return stop_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stopped, nothing left
    std::function<void()> write = std::move(queue_.front());
    queue_.pop_front();
    busy_ = true;
    lock.unlock();
    std::exception_ptr error;
    try {
      write();
    } catch (...) {
      error = std::current_exception();
    }
    lock.lock();
    busy_ = false;
    if (error) {
      error_ = error;
      queue_.clear();
    }
    changed_.notify_all();
  }
}

}  // namespace pneuma::voxels
