// Scenario YAML: every key, unit and choice of runner::load_scenario (every output's key too).
#include "fuzz_input.h"
#include "pneuma/core/error.h"
#include "pneuma/runner/output_registry.h"
#include "pneuma/scenario/scenario.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    (void)pneuma::runner::load_scenario(pneuma::fuzz::write_input(data, size, ".yaml"));
  } catch (const pneuma::Error&) {
  }
  return 0;
}
