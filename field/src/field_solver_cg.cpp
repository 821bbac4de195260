// ConjugateGradient_Schur: the one-hop fixed point as a symmetric positive definite system on
// the mass nodes alone, solved by Jacobi-preconditioned conjugate gradients.
//
// Derivation (METHOD.md 2-3). t(k -> n) = S_n g_kn / Z_k with g_kn = g_nk the distance factor.
// R = f + P^T R reads R_n = f_n + S_n sum_k g_kn R_k / Z_k. With y = R / Z and D = Z / S:
//     D_n y_n - sum_k g_kn y_k = f_n / S_n,      i.e.  (D - G) y = f / S,
// a symmetric Z-matrix; (I - P^T) is a nonsingular M-matrix (P >= 0, rows sum below 1) and
// D - G = S^-1 (I - P^T) Z, so D - G is one too, hence positive definite. A spring node e
// (a, b) has no load, so y_e = g_e (y_a + y_b) / D_e exactly; substituting leaves
//     K_aa = D_a - sum_{e at a} g_e^2 / D_e,   K_ab = -g_e^2 / D_e,   K y_m = f_m / S_m,
// with F_i = Shot_i = S_i y_i. The original residual on a mass node is S_i times K's residual
// (spring rows are satisfied exactly), which is what the stopping test measures.
#include <algorithm>
#include <chrono>
#include <cmath>

#include "fixed_blocks.h"
#include "pneuma/core/error.h"
#include "pneuma/core/stopwatch.h"
#include "pneuma/field/field_solver.h"

namespace pneuma::field {
namespace {

using detail::for_blocks;
using detail::kBlock;

}  // namespace

struct ConjugateGradient_Schur::Impl {
  // K = diag(diagonal) - W over the mesh's vertex adjacency, read through the graph's incidence
  // CSR (no copy): K_ij = -w_e for the edge e = (i, j), w_e = g_e^2 / D_e.
  std::shared_ptr<const FieldGraph> graph;
  std::uint32_t mass_count = 0, node_count = 0;
  std::vector<double> diagonal, inverse_diagonal;  // per vertex
  std::vector<double> edge_weight;                 // w_e per edge

  void multiply(const std::vector<double>& x, std::vector<double>& y, std::vector<double>& partial_dot) const {
    const auto& offset = graph->incident_offset();
    const auto& edge = graph->incident_edges();
    const auto& other = graph->incident_vertices();
    for_blocks(mass_count, [&](std::size_t b, std::size_t lo, std::size_t hi) {
      double dot = 0.0;
      for (std::size_t i = lo; i < hi; ++i) {
        double s = diagonal[i] * x[i];
        for (std::uint32_t j = offset[i]; j < offset[i + 1]; ++j) s -= edge_weight[edge[j]] * x[other[j]];
        y[i] = s;
        dot += s * x[i];
      }
      partial_dot[b] = dot;
    });
  }
};

ConjugateGradient_Schur::ConjugateGradient_Schur(std::shared_ptr<const FieldGraph> graph, const SolveOptions& options)
    : options_(options), impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.graph = std::move(graph);
  const FieldGraph& g = *m.graph;
  const std::uint32_t nv = g.mass_count(), ne = g.spring_count();
  m.mass_count = nv;
  m.node_count = g.node_count();
  const auto& z = g.normaliser();
  const auto& s = g.weight();
  const auto& factor = g.distance_factor();
  m.edge_weight.resize(ne);
  const tsan::Region edges;
  tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, ne, 8192),
                    edges.wrap([&](const tbb::blocked_range<std::uint32_t>& r) {
                      for (std::uint32_t e = r.begin(); e != r.end(); ++e) {
                        m.edge_weight[e] = factor[e] * factor[e] * s[nv + e] / z[nv + e];
                      }
                    }));
  edges.join();
  const auto& offset = g.incident_offset();
  const auto& edge = g.incident_edges();
  m.diagonal.resize(nv);
  m.inverse_diagonal.resize(nv);
  const tsan::Region vertices;
  tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, nv, 8192),
                    vertices.wrap([&](const tbb::blocked_range<std::uint32_t>& r) {
                      for (std::uint32_t i = r.begin(); i != r.end(); ++i) {
                        double diag = z[i] / s[i];
                        for (std::uint32_t j = offset[i]; j < offset[i + 1]; ++j) diag -= m.edge_weight[edge[j]];
                        m.diagonal[i] = diag;
                        m.inverse_diagonal[i] = 1.0 / diag;
                      }
                    }));
  vertices.join();
}

ConjugateGradient_Schur::~ConjugateGradient_Schur() = default;

SolveResult ConjugateGradient_Schur::solve(std::span<const double> load) const {
  const auto start = Clock::now();
  const Impl& m = *impl_;
  const std::vector<double>& weight = m.graph->weight();
  const std::size_t nv = m.mass_count;
  const bool mass_only = load.size() == nv;
  if (!mass_only && load.size() != m.node_count)
    throw ValueError("load: expected " + std::to_string(m.node_count) + " or " + std::to_string(nv) + " values, got " +
                     std::to_string(load.size()));
  double max_f = 0.0;
  for (std::size_t k = 0; k < load.size(); ++k) {
    const double f = load[k];
    if (!(f >= 0.0) || !std::isfinite(f)) throw ValueError("load: expected finite values >= 0");
    if (k >= nv && f != 0.0) throw ValueError("load: the cg solver needs zero load on spring nodes");
    max_f = std::max(max_f, f);
  }
  SolveResult out;
  out.report.method = "cg";
  out.shot.assign(load.size(), 0.0);
  if (max_f == 0.0) return out;
  const double threshold = options_.tolerance * max_f;
  const std::size_t blocks = (nv + kBlock - 1) / kBlock;
  std::vector<double> x(nv, 0.0), r(nv), z(nv), p(nv), q(nv), partial(blocks), partial2(blocks), partial_max(blocks);
  auto sum = [](const std::vector<double>& v) {
    double t = 0.0;
    for (double a : v) t += a;
    return t;
  };
  auto maximum = [](const std::vector<double>& v) { return *std::max_element(v.begin(), v.end()); };

  // r = b - K x (q holds K x); z = M^-1 r; p = z. At the start x = 0 and q = 0.
  double rz = 0.0, max_residual = 0.0;
  auto restart_directions = [&] {
    for_blocks(nv, [&](std::size_t b, std::size_t lo, std::size_t hi) {
      double rz_b = 0.0, worst = 0.0;
      for (std::size_t i = lo; i < hi; ++i) {
        r[i] = load[i] / weight[i] - q[i];
        z[i] = r[i] * m.inverse_diagonal[i];
        p[i] = z[i];
        rz_b += r[i] * z[i];
        worst = std::max(worst, std::abs(weight[i] * r[i]));
      }
      partial[b] = rz_b;
      partial_max[b] = worst;
    });
    rz = sum(partial);
    max_residual = maximum(partial_max);
  };
  restart_directions();
  std::uint64_t iterations = 0;
  bool recomputed = false;
  while (max_residual > threshold || !recomputed) {
    if (max_residual <= threshold) {
      // The recurrence says converged: check the true residual once, and go on if it is not.
      m.multiply(x, q, partial);
      restart_directions();
      recomputed = true;
      continue;
    }
    recomputed = false;
    if (++iterations > 10'000) throw Error(ExitCode::failure, "conjugate gradients did not converge");
    m.multiply(p, q, partial);
    const double alpha = rz / sum(partial);
    for_blocks(nv, [&](std::size_t b, std::size_t lo, std::size_t hi) {
      double rz_b = 0.0, worst = 0.0;
      for (std::size_t i = lo; i < hi; ++i) {
        x[i] += alpha * p[i];
        r[i] -= alpha * q[i];
        z[i] = r[i] * m.inverse_diagonal[i];
        rz_b += r[i] * z[i];
        worst = std::max(worst, std::abs(weight[i] * r[i]));
      }
      partial[b] = rz_b;
      partial_max[b] = worst;
    });
    const double rz_next = sum(partial);
    max_residual = maximum(partial_max);
    const double beta = rz_next / rz;
    rz = rz_next;
    for_blocks(nv, [&](std::size_t, std::size_t lo, std::size_t hi) {
      for (std::size_t i = lo; i < hi; ++i) p[i] = z[i] + beta * p[i];
    });
  }
  for (std::size_t i = 0; i < nv; ++i) out.shot[i] = weight[i] * x[i];  // F = S y
  if (!mass_only) {
    // Spring nodes: y_e = g_e (y_a + y_b) / D_e, Shot_e = S_e y_e.
    const auto& normaliser = m.graph->normaliser();
    const auto& factor = m.graph->distance_factor();
    const auto& edges = m.graph->edges();
    for (std::size_t e = 0; e < edges.size(); ++e) {
      const double y = factor[e] * weight[nv + e] / normaliser[nv + e] * (x[edges[e][0]] + x[edges[e][1]]);
      out.shot[nv + e] = weight[nv + e] * y;
    }
  }
  out.report.iterations = iterations;
  out.report.residual = max_residual / max_f;
  out.report.seconds = seconds_since(start);
  return out;
}

}  // namespace pneuma::field
