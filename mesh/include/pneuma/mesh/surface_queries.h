#pragma once
// Queries the scenario runner makes of a surface, answered by CGAL (kept out of this header).
#include <Eigen/Core>
#include <memory>
#include <vector>

#include "pneuma/mesh/triangle_mesh.h"

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
// (CGAL::Polygon_mesh_processing::does_self_intersect). parallel: CGAL's TBB version, the same
// answer; measured at 1M vertices on the 2-core machine it does ~1.5x the work of serial (it
// shuffles the face boxes, losing their locality) and ran 1.2-2.6x slower (BENCHMARKS.md, "Frame
// kernel"), so serial is the default; parallel pays off only with more free cores.
bool self_intersects(const TriangleMesh& mesh, Concurrency concurrency = Concurrency::serial);

// A per-vertex field of `source` carried to `targets`: each target point takes the value
// interpolated (barycentrically) at its closest point on the source surface (CGAL AABB tree).
std::vector<Eigen::Vector3d> transfer_vertex_field(const TriangleMesh& source,
                                                   const std::vector<Eigen::Vector3d>& field,
                                                   const std::vector<Eigen::Vector3d>& targets);

}  // namespace pneuma::mesh
