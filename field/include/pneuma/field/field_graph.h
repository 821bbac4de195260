#pragma once
// The graph of the elastostatic field (paper section 4.2; METHOD.md sections 1-3), built once
// per mesh and stiffness map and then only read.
//
// Nodes 0 .. V-1 are the mass nodes (mesh vertices); nodes V .. V+E-1 are the spring nodes,
// one per undirected mesh edge, placed at the edge midpoint. The graph is bipartite: a mass
// node is adjacent to the spring nodes of its edges, a spring node to its two ends.
//
//   m_i = mu_i / mean(mu)                   relative modulus (only relative stiffness matters)
//   S_i = 1 / m_i (mass), S_e = (m_a + m_b) / 2 (spring)                         node weights
//   Z_k = S_k + sum_{l in N(k)} S_l
//   t(k -> n) = (S_n / Z_k) / max(1, dist(k, n) / h)       one-hop share, eq. 4.4 with M = 1
//   t(k -> k) = S_k / Z_k                                   share a shot keeps, eq. 4.6
//   h = mean mass-to-spring distance (half the mean edge length): the factors are unit-free.
//
// Every array is a flat vector (CSR for adjacency); nothing here allocates per node.
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::field {

// The largest clique (Table 1 of the paper measures M = 1..4); declared once, for the solvers,
// `pneuma field --clique` and the scenario key field.clique.
inline constexpr int kMaxCliqueHops = 4;

// Additions and multiplications actually executed (counted in the loops that do them), for
// the comparison with the paper's Table 1. Divisions count as multiplications.
struct OperationCounts {
  std::uint64_t additions = 0;
  std::uint64_t multiplications = 0;
  OperationCounts& operator+=(const OperationCounts& o) {
    additions += o.additions;
    multiplications += o.multiplications;
    return *this;
  }
};

// Who receives what when a node shoots: node k sends share[j] of its UnShot to target[j] for
// j in [offset[k], offset[k+1]) and keeps self_share[k]. For every node
// self_share[k] + sum_j share[j] <= 1 (a shot never creates force), so every solver converges.
struct TransferOperator {
  int clique_hops = 1;                // M: targets lie within M hops (METHOD.md section 3)
  std::uint32_t mass_count = 0;       // nodes [0, mass_count) are mass nodes
  std::uint32_t node_count = 0;       // mass + spring nodes
  std::vector<std::uint64_t> offset;  // node_count + 1
  std::vector<std::uint32_t> target;  // offset.back()
  std::vector<double> share;          // offset.back(), t(k -> target)
  std::vector<double> self_share;     // node_count, t(k -> k)
  OperationCounts build_counts;       // work spent building the shares (cliques: path products)

  std::uint64_t entry_count() const { return offset.empty() ? 0 : offset.back(); }
};

class FieldGraph {
 public:
  // Throws InputError when shear_modulus_pa does not hold one positive, finite value per
  // vertex, when a triangle names a missing vertex, or when the mesh has no edge of positive
  // length. The mesh may be in any length unit: only ratios of lengths enter.
  FieldGraph(const mesh::TriangleMesh& mesh, std::span<const double> shear_modulus_pa);

  std::uint32_t mass_count() const { return mass_count_; }
  std::uint32_t spring_count() const { return static_cast<std::uint32_t>(edges_.size()); }
  std::uint32_t node_count() const { return mass_count_ + spring_count(); }

  // Spring node V + e sits on edges()[e] = {a, b}, a < b, sorted (as mesh::unique_edges).
  const std::vector<std::array<std::uint32_t, 2>>& edges() const { return edges_; }
  // Mass node i is an end of the edges incident_edges()[incident_offset()[i] .. [i+1]) (in
  // ascending order), whose other ends are incident_vertices()[same range].
  const std::vector<std::uint32_t>& incident_offset() const { return incident_offset_; }
  const std::vector<std::uint32_t>& incident_edges() const { return incident_edges_; }
  const std::vector<std::uint32_t>& incident_vertices() const { return incident_vertices_; }

  const std::vector<double>& relative_modulus() const { return relative_modulus_; }  // m, per vertex
  const std::vector<double>& weight() const { return weight_; }                      // S, per node
  const std::vector<double>& normaliser() const { return normaliser_; }              // Z, per node
  // 1 / max(1, dist / h) for the two mass-spring links of edge e (both ends are |ab| / 2 away).
  const std::vector<double>& distance_factor() const { return distance_factor_; }
  double reference_distance() const { return reference_distance_; }  // h, in mesh units

 private:
  std::uint32_t mass_count_ = 0;
  std::vector<std::array<std::uint32_t, 2>> edges_;
  std::vector<std::uint32_t> incident_offset_, incident_edges_, incident_vertices_;
  std::vector<double> relative_modulus_, weight_, normaliser_, distance_factor_;
  double reference_distance_ = 0.0;
};

// The one-hop operator (M = 1) in CSR: mass rows first (targets: their spring nodes, ascending),
// then spring rows (targets: a < b). Built on demand: the cg solver does not need it.
TransferOperator one_hop_operator(const FieldGraph& graph);

// How a clique combines the several paths that may join a node to one within M hops.
enum class CliquePathRule {
  // The sum, over every shortest path, of the product of the one-hop shares along it (what
  // the one-hop iteration would deliver along those paths). The default.
  sum_of_shortest_paths,
  // The largest such product over the shortest paths only.
  strongest_path,
};

// The clique operator of M hops (eq. 4.3 - 4.4): node k shoots straight to every node n with
// 1 <= hops(k, n) <= M, with the path products of `rule`; then, if the shares leaving k sum to
// more than with M = 1, they are scaled down to that sum, so a shot keeps the same share and
// the iteration still converges. clique_operator(g, 1) equals one_hop_operator(g). Throws
// ValueError unless 1 <= hops <= kMaxCliqueHops.
TransferOperator clique_operator(const FieldGraph& graph, int hops,
                                 CliquePathRule rule = CliquePathRule::sum_of_shortest_paths);

}  // namespace pneuma::field
