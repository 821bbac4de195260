#include "pneuma/field/field_graph.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <fmt/format.h>

#include "pneuma/core/error.h"
#include "pneuma/core/parameters.h"
#include "pneuma/core/tsan.h"

namespace pneuma::field {
namespace {

// The undirected edges {a < b}, sorted, each once: a counting sort on a (the smaller end),
// then a tiny sort per bucket. O(T) and the same order as mesh::unique_edges.
std::vector<std::array<std::uint32_t, 2>> sorted_edges(const std::vector<mesh::Triangle>& triangles,
                                                       std::uint32_t vertex_count) {
  std::vector<std::uint32_t> start(static_cast<std::size_t>(vertex_count) + 1, 0);
  for (const mesh::Triangle& t : triangles) {
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = t[k], b = t[(k + 1) % 3];
      if (a != b) ++start[std::min(a, b) + 1];
    }
  }
  for (std::uint32_t v = 0; v < vertex_count; ++v) start[v + 1] += start[v];
  std::vector<std::uint32_t> other(start.back());
  std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
  for (const mesh::Triangle& t : triangles) {
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = t[k], b = t[(k + 1) % 3];
      if (a != b) other[fill[std::min(a, b)]++] = std::max(a, b);
    }
  }
  std::vector<std::array<std::uint32_t, 2>> edges;
  edges.reserve(other.size() / 2 + 1);
  for (std::uint32_t a = 0; a < vertex_count; ++a) {
    auto first = other.begin() + start[a], last = other.begin() + start[a + 1];
    std::sort(first, last);
    last = std::unique(first, last);
    for (auto it = first; it != last; ++it) edges.push_back({a, *it});
  }
  return edges;
}

void check_inputs(const mesh::TriangleMesh& mesh, std::span<const double> mu) {
  if (mesh.vertices.size() >= std::numeric_limits<std::uint32_t>::max() / 4)
    throw InputError("mesh: too many vertices for the field graph (" + std::to_string(mesh.vertices.size()) + ")");
  if (mu.size() != mesh.vertices.size()) {
    throw InputError("shear modulus: expected one value per mesh vertex (" + std::to_string(mesh.vertices.size()) +
                     "), got " + std::to_string(mu.size()));
  }
  for (std::size_t i = 0; i < mu.size(); ++i) {
    if (!(std::isfinite(mu[i]) && mu[i] > 0.0))
      throw InputError("shear modulus: vertex " + std::to_string(i) + ": expected a positive shear modulus");
  }
  const auto n = static_cast<std::uint32_t>(mesh.vertices.size());
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    for (std::uint32_t v : mesh.triangles[t]) {
      if (v >= n)
        throw InputError("mesh: triangle " + std::to_string(t) + " names vertex " + std::to_string(v) +
                         ", but there are " + std::to_string(n));
    }
  }
}

// Sums v[0..n) in fixed blocks, added in block order: the same bits at any thread count.
template <typename Value>
double deterministic_sum(std::size_t n, const Value& value) {
  constexpr std::size_t block = 16384;
  const std::size_t blocks = (n + block - 1) / block;
  std::vector<double> partial(blocks, 0.0);
  const tsan::Region region;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks),
                    region.wrap([&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t b = r.begin(); b != r.end(); ++b) {
                        double sum = 0.0;
                        for (std::size_t i = b * block; i < std::min(n, (b + 1) * block); ++i) sum += value(i);
                        partial[b] = sum;
                      }
                    }));
  region.join();
  double total = 0.0;
  for (double p : partial) total += p;
  return total;
}

template <typename Index, typename Body>
void parallel_for_each(Index n, const Body& body) {
  const tsan::Region region;
  tbb::parallel_for(tbb::blocked_range<Index>(0, n, 8192), region.wrap([&](const tbb::blocked_range<Index>& r) {
    for (Index i = r.begin(); i != r.end(); ++i) body(i);
  }));
  region.join();
}

}  // namespace

FieldGraph::FieldGraph(const mesh::TriangleMesh& mesh, std::span<const double> mu) {
  check_inputs(mesh, mu);
  mass_count_ = static_cast<std::uint32_t>(mesh.vertices.size());
  const std::uint32_t nv = mass_count_;
  edges_ = sorted_edges(mesh.triangles, nv);
  const auto ne = static_cast<std::uint32_t>(edges_.size());
  if (ne == 0) throw InputError("mesh: no edges, so no field can be computed");

  // Incidence (vertex -> its edges, ascending edge id, and their other ends), CSR.
  incident_offset_.assign(static_cast<std::size_t>(nv) + 1, 0);
  for (const auto& e : edges_) {
    ++incident_offset_[e[0] + 1];
    ++incident_offset_[e[1] + 1];
  }
  for (std::uint32_t v = 0; v < nv; ++v) incident_offset_[v + 1] += incident_offset_[v];
  incident_edges_.resize(incident_offset_.back());
  incident_vertices_.resize(incident_offset_.back());
  {
    std::vector<std::uint32_t> fill(incident_offset_.begin(), incident_offset_.end() - 1);
    for (std::uint32_t e = 0; e < ne; ++e) {
      const auto [a, b] = edges_[e];
      incident_edges_[fill[a]] = e;
      incident_vertices_[fill[a]++] = b;
      incident_edges_[fill[b]] = e;
      incident_vertices_[fill[b]++] = a;
    }
  }

  // Relative modulus m = mu / mean(mu) (METHOD.md 1).
  const double mean = deterministic_sum(nv, [&](std::size_t i) { return mu[i]; }) / static_cast<double>(nv);
  relative_modulus_.resize(nv);
  const std::uint32_t n = nv + ne;
  weight_.resize(n);
  parallel_for_each(nv, [&](std::uint32_t i) {
    relative_modulus_[i] = mu[i] / mean;
    weight_[i] = 1.0 / relative_modulus_[i];  // S of a mass node
  });

  // Distances: a spring node sits at its edge's midpoint, so both its links are |ab| / 2 long.
  distance_factor_.resize(ne);
  parallel_for_each(ne, [&](std::uint32_t e) {
    const auto [a, b] = edges_[e];
    weight_[nv + e] = 0.5 * (relative_modulus_[a] + relative_modulus_[b]);     // S of a spring node
    distance_factor_[e] = 0.5 * (mesh.vertices[b] - mesh.vertices[a]).norm();  // half length for now
  });
  reference_distance_ =
      deterministic_sum(ne, [&](std::size_t e) { return distance_factor_[e]; }) / static_cast<double>(ne);
  if (!(reference_distance_ > 0.0) || !std::isfinite(reference_distance_))
    throw InputError("mesh: every edge has zero length, so no field can be computed");
  const double h = reference_distance_;
  normaliser_.resize(n);
  parallel_for_each(ne, [&](std::uint32_t e) {
    distance_factor_[e] = 1.0 / std::max(1.0, distance_factor_[e] / h);
    normaliser_[nv + e] = weight_[nv + e] + weight_[edges_[e][0]] + weight_[edges_[e][1]];
  });
  // Z_k = S_k + sum of the neighbours' S.
  parallel_for_each(nv, [&](std::uint32_t i) {
    double z = weight_[i];
    for (std::uint32_t j = incident_offset_[i]; j < incident_offset_[i + 1]; ++j) z += weight_[nv + incident_edges_[j]];
    normaliser_[i] = z;
  });
}

TransferOperator one_hop_operator(const FieldGraph& g) {
  const std::uint32_t nv = g.mass_count(), ne = g.spring_count(), n = g.node_count();
  const auto& inc_offset = g.incident_offset();
  const auto& inc_edges = g.incident_edges();
  const auto& s = g.weight();
  const auto& z = g.normaliser();
  const auto& factor = g.distance_factor();
  const auto& edges = g.edges();
  TransferOperator op;
  op.clique_hops = 1;
  op.mass_count = nv;
  op.node_count = n;
  op.offset.resize(static_cast<std::size_t>(n) + 1);
  op.offset[0] = 0;
  for (std::uint32_t i = 0; i < nv; ++i) op.offset[i + 1] = inc_offset[i + 1];
  for (std::uint32_t e = 0; e < ne; ++e) op.offset[nv + e + 1] = op.offset[nv + e] + 2;
  op.target.resize(op.offset.back());
  op.share.resize(op.offset.back());
  op.self_share.resize(n);
  parallel_for_each(nv, [&](std::uint32_t i) {
    const double inv_z = 1.0 / z[i];
    for (std::uint32_t j = inc_offset[i]; j < inc_offset[i + 1]; ++j) {
      const std::uint32_t e = inc_edges[j];
      op.target[j] = nv + e;
      op.share[j] = s[nv + e] * inv_z * factor[e];
    }
    op.self_share[i] = s[i] * inv_z;
  });
  parallel_for_each(ne, [&](std::uint32_t e) {
    const std::uint32_t k = nv + e;
    const double inv_z = 1.0 / z[k];
    const std::uint64_t j = op.offset[k];
    for (int end = 0; end < 2; ++end) {
      op.target[j + end] = edges[e][end];
      op.share[j + end] = s[edges[e][end]] * inv_z * factor[e];
    }
    op.self_share[k] = s[k] * inv_z;
  });
  return op;
}

TransferOperator clique_operator(const FieldGraph& graph, int hops, CliquePathRule rule) {
  if (const auto why = parameters::kCliqueHops.check(hops)) throw ValueError("clique_operator: " + *why);
  const TransferOperator one = one_hop_operator(graph);
  TransferOperator op;
  op.clique_hops = hops;
  op.mass_count = one.mass_count;
  op.node_count = one.node_count;
  op.self_share = one.self_share;
  op.offset.assign(static_cast<std::size_t>(one.node_count) + 1, 0);
  OperationCounts& c = op.build_counts;

  // Scratch shared by all rows: the row that last visited a node, its hop count and weight.
  std::vector<std::uint32_t> visited_by(one.node_count, std::numeric_limits<std::uint32_t>::max());
  std::vector<int> level(one.node_count, 0);
  std::vector<double> weight(one.node_count, 0.0);
  std::vector<std::uint32_t> layer, next, row;
  std::vector<std::pair<std::uint32_t, double>> entries;

  for (std::uint32_t k = 0; k < one.node_count; ++k) {
    visited_by[k] = k;
    level[k] = 0;
    weight[k] = 1.0;
    layer.assign(1, k);
    row.clear();
    for (int d = 1; d <= hops && !layer.empty(); ++d) {
      next.clear();
      for (std::uint32_t m : layer) {
        for (std::uint64_t j = one.offset[m]; j < one.offset[m + 1]; ++j) {
          const std::uint32_t n = one.target[j];
          if (visited_by[n] != k) {
            visited_by[n] = k;
            level[n] = d;
            // A one-hop share is its own path product: no multiplication for the first hop.
            if (d == 1) {
              weight[n] = one.share[j];
            } else {
              weight[n] = weight[m] * one.share[j];
              ++c.multiplications;
            }
            next.push_back(n);
          } else if (level[n] == d) {  // another shortest path to n
            const double w = weight[m] * one.share[j];
            ++c.multiplications;
            if (rule == CliquePathRule::sum_of_shortest_paths) {
              weight[n] += w;
              ++c.additions;
            } else {
              weight[n] = std::max(weight[n], w);
            }
          }
        }
      }
      row.insert(row.end(), next.begin(), next.end());
      layer.swap(next);
    }
    // Keep the share leaving k no larger than with M = 1 (METHOD.md 3).
    double leaving_one_hop = 0.0, leaving = 0.0;
    for (std::uint64_t j = one.offset[k]; j < one.offset[k + 1]; ++j) leaving_one_hop += one.share[j];
    for (std::uint32_t n : row) leaving += weight[n];
    c.additions += (one.offset[k + 1] - one.offset[k]) + row.size();
    const double scale = leaving > leaving_one_hop ? leaving_one_hop / leaving : 1.0;
    entries.clear();
    for (std::uint32_t n : row) entries.emplace_back(n, weight[n]);
    std::sort(entries.begin(), entries.end());
    for (const auto& [n, w] : entries) {
      op.target.push_back(n);
      op.share.push_back(scale == 1.0 ? w : w * scale);
    }
    if (scale != 1.0) c.multiplications += entries.size();
    op.offset[k + 1] = op.target.size();
  }
  return op;
}

}  // namespace pneuma::field
