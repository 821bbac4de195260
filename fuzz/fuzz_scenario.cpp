// Scenario YAML: every key, unit and choice of engine::load_scenario.
#include "fuzz_input.h"
#include "pneuma/core/error.h"
#include "pneuma/engine/scenario.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    (void)pneuma::engine::load_scenario(pneuma::fuzz::write_input(data, size, ".yaml"));
  } catch (const pneuma::Error&) {
  }
  return 0;
}
