#include "pneuma/runner/progress.h"
#include "pneuma/core/stopwatch.h"

#include <unistd.h>

#include <cstdio>

namespace pneuma::runner {

Progress::Progress(std::string label, std::size_t total, bool quiet)
    : label_(std::move(label)),
      total_(total),
      quiet_(quiet),
      terminal_(::isatty(STDERR_FILENO) != 0),
      start_(Clock::now()) {}

Progress::~Progress() {
  if (terminal_ && !quiet_ && !finished_ && last_percent_ >= 0) std::fputc('\n', stderr);  // keep the shell tidy
}

void Progress::update(std::size_t done) {
  if (quiet_ || total_ == 0) return;
  const int percent = static_cast<int>(100 * done / total_);
  const double elapsed = seconds_since(start_);
  if (terminal_) {
    if (percent == last_percent_) return;
    last_percent_ = percent;
    constexpr int kWidth = 30;
    const int filled = percent * kWidth / 100;
    std::fprintf(stderr, "\r%s [%.*s%*s] %3d%% %zu/%zu %.1f s", label_.c_str(), filled,
                 "##############################", kWidth - filled, "", percent, done, total_, elapsed);
    std::fflush(stderr);
  } else {
    const int tenth = percent / 10;
    if (tenth == last_tenth_) return;
    last_tenth_ = tenth;
    std::fprintf(stderr, "%s: %d%% (%zu/%zu) %.1f s\n", label_.c_str(), percent, done, total_, elapsed);
  }
}

void Progress::finish() {
  if (finished_) return;
  update(total_);
  finished_ = true;
  if (terminal_ && !quiet_) std::fputc('\n', stderr);
}

}  // namespace pneuma::runner
