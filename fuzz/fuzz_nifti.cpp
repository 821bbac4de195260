// NIfTI label maps (.nii; the header read by pneuma, the voxels by ITK): image::read_label_map.
#include "fuzz_input.h"
#include "pneuma/core/error.h"
#include "pneuma/mesh/labels/labels.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    (void)pneuma::image::read_label_map(pneuma::fuzz::write_input(data, size, ".nii"));
  } catch (const pneuma::Error&) {
  }
  return 0;
}
