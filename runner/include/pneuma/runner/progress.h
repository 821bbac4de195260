#pragma once
// Progress of a long run on stderr: a bar redrawn in place on a terminal, a plain line every
// 10% otherwise (logs, CI), nothing when quiet.
#include <chrono>
#include <cstddef>
#include <string>

namespace pneuma::runner {

class Progress {
 public:
  Progress(std::string label, std::size_t total, bool quiet);
  ~Progress();
  void update(std::size_t done);
  void finish();

 private:
  std::string label_;
  std::size_t total_;
  bool quiet_;
  bool terminal_;
  bool finished_ = false;
  int last_tenth_ = -1;
  int last_percent_ = -1;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace pneuma::runner
