#pragma once
// Ctrl-C and SIGTERM. The handler removes whatever is in flight (the temporaries of
// atomic_file.h and the stages of staged_output.h) and exits with 128 + signal, the status a
// shell reports. Inside a DeferInterruptions scope (a stage being moved into place) the exit
// waits for the scope to end, so an output is never left half old, half new.
namespace pneuma {

// Installs the handler for SIGINT and SIGTERM (the CLI calls it once, first thing).
void install_interrupt_handlers();

class DeferInterruptions {
 public:
  DeferInterruptions();
  ~DeferInterruptions();  // a signal that arrived meanwhile takes effect here
  DeferInterruptions(const DeferInterruptions&) = delete;
  DeferInterruptions& operator=(const DeferInterruptions&) = delete;
};

}  // namespace pneuma
