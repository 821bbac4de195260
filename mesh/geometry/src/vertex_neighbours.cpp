#include "pneuma/mesh/geometry/vertex_neighbours.h"

#include <algorithm>
#include <string>

#include "pneuma/core/error.h"

namespace pneuma::mesh {

VertexNeighbours::VertexNeighbours(std::size_t vertex_count, const std::vector<Triangle>& triangles) {
  // Every corner's two other corners, bucketed per vertex (a closed surface's edge is met from
  // both its faces), then each short row sorted and its repeats dropped in place.
  std::vector<std::uint32_t> slots(vertex_count + 1, 0);
  for (std::size_t f = 0; f < triangles.size(); ++f) {
    for (const std::uint32_t v : triangles[f]) {
      if (v >= vertex_count)
        throw ValueError("VertexNeighbours: triangle " + std::to_string(f) + " has corner " + std::to_string(v) +
                         ", expected a vertex below " + std::to_string(vertex_count));
      slots[v + 1] += 2;
    }
  }
  for (std::size_t v = 0; v < vertex_count; ++v) slots[v + 1] += slots[v];
  std::vector<std::uint32_t> all(slots.back());
  std::vector<std::uint32_t> fill(slots.begin(), slots.end() - 1);
  for (const Triangle& t : triangles) {
    for (std::size_t k = 0; k < 3; ++k) {
      all[fill[t[k]]++] = t[(k + 1) % 3];
      all[fill[t[k]]++] = t[(k + 2) % 3];
    }
  }
  start_.assign(vertex_count + 1, 0);
  list_.clear();
  list_.reserve(all.size() / 2 + 1);
  for (std::size_t v = 0; v < vertex_count; ++v) {
    const auto first = all.begin() + slots[v], last = all.begin() + slots[v + 1];
    std::sort(first, last);
    const auto kept = std::unique(first, last);
    for (auto it = first; it != kept; ++it) {
      if (*it != v) list_.push_back(*it);  // a degenerate face's repeated corner is no edge
    }
    start_[v + 1] = static_cast<std::uint32_t>(list_.size());
  }
}

}  // namespace pneuma::mesh
