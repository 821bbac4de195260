#pragma once
// Private to pneuma_mesh: VTK readers (io_vtk.cpp) for read_mesh().
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace pneuma::mesh::detail {

struct VtkSoup {
  std::vector<std::array<double, 3>> points;  // file units
  std::vector<std::array<std::uint32_t, 3>> triangles;
};

// `bytes`: the whole file. Throw InputError "<name>[:<line>]: <what was expected>".
VtkSoup read_vtk_legacy(const std::string& name, std::string bytes);
VtkSoup read_vtk_xml(const std::string& name, std::string bytes);

}  // namespace pneuma::mesh::detail
