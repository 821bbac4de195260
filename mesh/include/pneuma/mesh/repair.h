#pragma once
// Repair of what can be repaired safely, and a clear refusal of the rest.
//
// Repaired: vertices at identical positions (merged), faces with a repeated vertex or three
// collinear vertices (removed / collapsed), duplicated faces (the first is kept), faces
// oriented against their neighbours (flipped), borders that coincide (stitched), holes of at
// most `max_hole_edges` boundary edges (CGAL triangulate_refine_and_fair_hole), closed
// components that enclose a negative volume (reversed), unused vertices (dropped).
// Refused (InputError "<name>: cannot repair: <problem and where>"): non-manifold edges and
// vertices, non-orientable surfaces, self-intersections, larger holes; the indices refer to
// the input mesh.
#include <cstddef>
#include <string>
#include <vector>

#include "pneuma/mesh/triangle_mesh.h"

namespace pneuma::mesh {

struct RepairOptions {
  std::size_t max_hole_edges = 64;
};

struct RepairReport {
  std::size_t merged_vertices = 0;
  std::size_t removed_degenerate_faces = 0;
  std::size_t removed_duplicated_faces = 0;
  std::size_t flipped_faces = 0;
  std::size_t stitched_edges = 0;
  std::size_t filled_holes = 0;
  std::size_t added_faces = 0;
  std::size_t reversed_components = 0;
  std::size_t dropped_vertices = 0;
  // One line per action taken ("flipped 1 face to match its neighbours"); empty: nothing to do.
  std::vector<std::string> actions() const;
};

struct RepairResult {
  TriangleMesh mesh;  // closed, manifold, outward oriented, vertices numbered by first use
  RepairReport report;
};

// `name` (usually the file name) starts every error message.
RepairResult repair(const TriangleMesh& mesh, const std::string& name, const RepairOptions& options = {});

// The repaired mesh alone (the runner's entry point); throws as repair() does.
inline TriangleMesh repair_or_throw(const TriangleMesh& mesh, const std::string& name, const RepairOptions& options = {}) {
  return repair(mesh, name, options).mesh;
}

}  // namespace pneuma::mesh
