#pragma once
// Isotropic remeshing to a target edge length (CGAL Polygon_mesh_processing::
// isotropic_remeshing: split long edges, collapse short ones, flip to even valences, tangential
// relaxation, and projection of every vertex back onto the input surface, which keeps the
// result within a small distance of the input).
#include <cstddef>

#include "pneuma/core/error.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"
#include "pneuma/mesh/geometry/validate.h"

namespace pneuma::mesh {

struct RemeshOptions {
  double target_edge_length_m = 3e-3;
  unsigned iterations = 3;
  // Measure how far the result strays from the input (an AABB tree over the input; the
  // distance of every output vertex and triangle centroid to it). Costs about one remeshing
  // iteration.
  bool measure_deviation = true;
};

struct RemeshResult {
  TriangleMesh mesh;  // vertices numbered by first use
  MeshQuality before, after;
  double max_deviation_m = 0.0;  // 0 when not measured
};

// The input must be a valid surface (validate(mesh).valid()); throws ValueError
// otherwise, and for a target edge that is not positive and finite.
RemeshResult remesh_isotropic(const TriangleMesh& mesh, const RemeshOptions& options = {});

}  // namespace pneuma::mesh
