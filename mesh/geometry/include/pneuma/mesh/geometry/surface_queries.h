#pragma once
// Queries the scenario runner makes of a surface, answered by CGAL (kept out of this header).
#include <Eigen/Core>
#include <memory>
#include <vector>

#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh {

// Surface area of a fixed connectivity with moving vertices, by CGAL's
// Polygon_mesh_processing::area. Built once (the CGAL mesh is allocated here); each call
// moves its points in place and allocates nothing.
class AreaMeter {
 public:
  explicit AreaMeter(const TriangleMesh& mesh);
  ~AreaMeter();
  AreaMeter(const AreaMeter&) = delete;
  AreaMeter& operator=(const AreaMeter&) = delete;
  // `positions` has one entry per vertex of the mesh given to the constructor.
  double area(const std::vector<Eigen::Vector3d>& positions);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

enum class Concurrency { serial, parallel };

// True when two faces of the surface intersect other than along shared edges or vertices
// (CGAL::Polygon_mesh_processing::does_self_intersect). parallel: the faces cut into slabs along
// x, each slab tested by CGAL in its own TBB task; the same answer as serial, with less work in
// total (at 1M vertices: 3.0-3.2 s of CPU against 3.9-4.1 s, the calling thread 2.1-2.2 s;
// BENCHMARKS.md, "Frame kernel").
bool self_intersects(const TriangleMesh& mesh, Concurrency concurrency = Concurrency::parallel);

// True when a face of `a` and a face of `b` intersect (closed triangles, CGAL's exact test; two
// surfaces that share no vertex, such as two lungs): what self_intersects() of the two as one
// mesh answers when neither intersects itself, without testing each one's faces against its own
// again (#50: the two lungs' check at half the work). Only the faces whose box meets the other
// surface's box are sorted into CGAL's box intersection.
bool surfaces_intersect(const TriangleMesh& a, const TriangleMesh& b);

// A per-vertex field of `source` carried to `targets`: each target point takes the value
// interpolated (barycentrically) at its closest point on the source surface (CGAL AABB tree).
std::vector<Eigen::Vector3d> transfer_vertex_field(const TriangleMesh& source,
                                                   const std::vector<Eigen::Vector3d>& field,
                                                   const std::vector<Eigen::Vector3d>& targets);

}  // namespace pneuma::mesh
