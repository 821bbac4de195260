// The field cache (HDF5): model::load_field, which must refuse whatever is not a whole,
// unedited pneuma field file.
#include "fuzz_input.h"
#include "pneuma/core/error.h"
#include "pneuma/model/field_cache.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    (void)pneuma::model::load_field(pneuma::fuzz::write_input(data, size, ".h5"));
  } catch (const pneuma::Error&) {
  }
  return 0;
}
