#pragma once
// Private to pneuma_mesh: the PLY reader (io_ply.cpp) for read_mesh(). pneuma reads PLY itself:
// assimp 5.2's reader trusts the file, and fuzzing found it looping forever, corrupting its heap
// and reading past its buffer on damaged files.
#include <string>

#include "io_vtk.h"  // VtkSoup: points in file units and triangles

namespace pneuma::mesh::detail {

// `bytes`: the whole file. ASCII and binary (little and big endian); the `vertex` element's
// x, y, z and the `face` element's `vertex_indices` (or `vertex_index`) lists, polygons split
// into fans; every other element and property skipped. Throws InputError "<name>: ...".
VtkSoup read_ply(const std::string& name, const std::string& bytes);

}  // namespace pneuma::mesh::detail
