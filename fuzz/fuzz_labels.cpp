// One label-map reader through ITK (the extension, PNEUMA_FUZZ_EXTENSION, picks it: .nrrd or
// .mha), then the check a selection goes through: image::read_label_map, image::resolve_labels.
#include "fuzz_input.h"
#include "pneuma/core/error.h"
#include "pneuma/mesh/labels/labels.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const pneuma::image::LabelMap map =
        pneuma::image::read_label_map(pneuma::fuzz::write_input(data, size, PNEUMA_FUZZ_EXTENSION));
    std::vector<std::string> names{"1"};
    for (const pneuma::image::Segment& s : map.segments) names.push_back(s.name);
    (void)pneuma::image::resolve_labels(map, "input", names);
  } catch (const pneuma::Error&) {
  }
  return 0;
}
