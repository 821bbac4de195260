#pragma once
// Shared by the runner tests (runner_test.cpp, trace_run_test.cpp).
#include <filesystem>

#include "pneuma/mesh/io/mesh_io.h"

namespace pneuma::test {

// Signed-tetrahedron volume of a mesh file in metres, read back with the mesh reader: an oracle
// independent of the engine's volume cubic.
inline double file_volume(const std::filesystem::path& p) {
  const auto m = mesh::read_mesh(p);  // in the unit the file records (frames: mm)
  double six = 0.0;
  for (const auto& t : m.triangles) six += m.vertices[t[0]].dot(m.vertices[t[1]].cross(m.vertices[t[2]]));
  return six / 6.0;
}

}  // namespace pneuma::test
