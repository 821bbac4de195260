#pragma once
// Rays from a surface's vertices to the face across (answered by CGAL in surface_queries.cpp,
// kept out of this header).
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh {

// Where a ray from a vertex leaves the surface.
struct SurfaceHit {
  bool found = false;               // false: no face within reach, or the ray met a face from
                                    // outside (it started outside the surface: a concave fold)
  double distance = 0.0;            // metres from the vertex
  std::uint32_t face = 0;           // the face crossed
  std::array<double, 3> weights{};  // barycentric coordinates of the crossing in that face
};

// From vertex i along `direction[i]` (unit), the first face the ray crosses within `reach`
// (metres), the faces around vertex i skipped (the nearest of CGAL's crossings with the faces
// whose boxes a segment of that reach meets, found through a box tree of pneuma's own; every
// vertex on its own thread, the same bits at any count).
// Cast inward across a thin part of a closed surface, it finds the face opposite: the part's
// thickness there and the point of the far face. Throws ValueError for one direction per vertex
// missing or a reach that is not positive.
std::vector<SurfaceHit> first_hits_from_vertices(const TriangleMesh& mesh,
                                                 const std::vector<Eigen::Vector3d>& direction, double reach);

}  // namespace pneuma::mesh
