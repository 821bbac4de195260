#pragma once
// Each vertex's neighbours along the surface's edges, in compressed rows, built from the triangles
// without the global sort of mesh::unique_edges (#50: that sort was 5 % of the realistic field).
#include <cstdint>
#include <span>
#include <vector>

#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh {

// Row v is neighbours(v): the vertices that share an edge with v, each once, ascending (the order
// in which walking mesh::unique_edges meets them, so sums over a row keep their bits).
class VertexNeighbours {
 public:
  // Throws ValueError for a triangle corner that is not a vertex of `vertex_count`.
  VertexNeighbours(std::size_t vertex_count, const std::vector<Triangle>& triangles);
  explicit VertexNeighbours(const TriangleMesh& mesh) : VertexNeighbours(mesh.vertex_count(), mesh.triangles) {}

  std::size_t vertex_count() const { return start_.size() - 1; }
  std::span<const std::uint32_t> operator()(std::size_t v) const {
    return {list_.data() + start_[v], list_.data() + start_[v + 1]};
  }
  // The rows' offsets (vertex_count() + 1) and their concatenation, as compressed rows.
  const std::vector<std::uint32_t>& start() const { return start_; }
  const std::vector<std::uint32_t>& list() const { return list_; }

 private:
  std::vector<std::uint32_t> start_;
  std::vector<std::uint32_t> list_;
};

}  // namespace pneuma::mesh
