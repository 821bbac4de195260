// One mesh reader (the extension, PNEUMA_FUZZ_EXTENSION, picks it: assimp's STL/PLY/OBJ or
// pneuma's VTK/VTP), then the surface checks every loaded mesh goes through.
#include "fuzz_input.h"
#include "pneuma/core/error.h"
#include "pneuma/mesh/geometry/validate.h"
#include "pneuma/mesh/io/mesh_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const pneuma::mesh::TriangleMesh mesh =
        pneuma::mesh::read_mesh(pneuma::fuzz::write_input(data, size, PNEUMA_FUZZ_EXTENSION));
    (void)pneuma::mesh::validate(mesh);
  } catch (const pneuma::Error&) {
  }
  return 0;
}
