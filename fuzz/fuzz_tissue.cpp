// Tissue YAML (stiffness models, posture, load): scenario::load_tissue.
#include "fuzz_input.h"
#include "pneuma/core/error.h"
#include "pneuma/scenario/tissue_config.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    (void)pneuma::scenario::load_tissue(pneuma::fuzz::write_input(data, size, ".yaml"));
  } catch (const pneuma::Error&) {
  }
  return 0;
}
