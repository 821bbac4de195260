#include "pneuma/core/interrupt.h"

#include <unistd.h>

#include <atomic>
#include <csignal>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/staged_output.h"

namespace pneuma {
namespace {

std::atomic<int> g_defer_depth{0};
std::atomic<int> g_pending_signal{0};

[[noreturn]] void clean_up_and_exit(int signal) noexcept {
  remove_pending_temporaries();
  remove_pending_stages();
  ::_exit(128 + signal);
}

void on_interrupt(int signal) {
  if (g_defer_depth.load() > 0) {
    g_pending_signal.store(signal);
    return;
  }
  clean_up_and_exit(signal);
}

}  // namespace

void install_interrupt_handlers() {
  struct sigaction action {};
  action.sa_handler = on_interrupt;
  sigemptyset(&action.sa_mask);
  // One handler at a time: a second Ctrl-C while the first cleans up is held back.
  sigaddset(&action.sa_mask, SIGINT);
  sigaddset(&action.sa_mask, SIGTERM);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

DeferInterruptions::DeferInterruptions() { g_defer_depth.fetch_add(1); }

DeferInterruptions::~DeferInterruptions() {
  if (g_defer_depth.fetch_sub(1) == 1) {
    if (const int signal = g_pending_signal.exchange(0); signal != 0) clean_up_and_exit(signal);
  }
}

}  // namespace pneuma
