#pragma once
// Private to pneuma_mesh: the bridge between TriangleMesh and CGAL. Only the CGAL .cpp files
// (validate_cgal.cpp, repair.cpp, remesh.cpp) include <CGAL/...>; this header does not.
#include <cstddef>
#include <utility>
#include <vector>

#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh::detail {

// Faces whose three (distinct) vertices are collinear, by CGAL's exact predicate.
std::vector<std::size_t> collinear_faces(const TriangleMesh& mesh);

// Pairs of faces (indices into mesh.triangles, first < second, sorted) that intersect other
// than along shared edges or vertices. Only `faces` are considered (they must be free of
// repeated vertices and duplicates); non-manifold vertices and edges are allowed (the soup is
// split there first). Stops after `max_pairs` pairs.
std::vector<std::pair<std::size_t, std::size_t>> self_intersecting_pairs(const TriangleMesh& mesh,
                                                                         const std::vector<std::size_t>& faces,
                                                                         std::size_t max_pairs);

}  // namespace pneuma::mesh::detail
