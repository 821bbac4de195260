// NIfTI label maps as .nii.gz (#50: pneuma inflates the file once, checks it and converts the
// voxels from those bytes; ITK reads only the header): image::read_label_map. The harness
// compresses the input itself (nifti_gz_input.h), so mutations reach the header and the voxels.
#include <fstream>

#include "fuzz_input.h"
#include "nifti_gz_input.h"
#include "pneuma/core/error.h"
#include "pneuma/mesh/labels/labels.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string gz = pneuma::fuzz::nifti_gz_bytes(data, size);
  try {
    (void)pneuma::image::read_label_map(
        pneuma::fuzz::write_input(reinterpret_cast<const std::uint8_t*>(gz.data()), gz.size(), ".nii.gz"));
  } catch (const pneuma::Error&) {
  }
  return 0;
}
