// Witkin's mass-spring with explicit Euler (MassSpring_Witkin) and the two spring networks of
// the comparison: an independent clamped membrane and the network matched to the field.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "comparators_internal.h"
#include "pneuma/core/error.h"
#include "pneuma/paper/comparators.h"

namespace pneuma::paper {
namespace {

constexpr std::uint32_t dense_spectrum_limit = 4000;  // free vertices; above: power iterations

void check_network(const SpringNetwork& n) {
  const std::size_t v = n.vertex_count;
  if (n.stiffness.size() != n.springs.size() || n.anchor.size() != v || n.mass.size() != v || n.clamped.size() != v ||
      n.load_scale.size() != v || n.output_scale.size() != v)
    throw ValueError("spring network: array sizes do not match");
  for (std::size_t s = 0; s < n.springs.size(); ++s) {
    if (n.springs[s][0] >= v || n.springs[s][1] >= v || n.springs[s][0] == n.springs[s][1])
      throw ValueError("spring network: spring " + std::to_string(s) + " has a bad end");
    if (!(n.stiffness[s] > 0.0 && std::isfinite(n.stiffness[s])))
      throw ValueError("spring network: spring " + std::to_string(s) + " needs a positive stiffness");
  }
  for (std::size_t i = 0; i < v; ++i) {
    if (!(n.mass[i] > 0.0) || !(n.anchor[i] >= 0.0))
      throw ValueError("spring network: vertex " + std::to_string(i) + " needs mass > 0 and anchor >= 0");
  }
}

SpringNetwork empty_network(std::uint32_t vertex_count) {
  SpringNetwork n;
  n.vertex_count = vertex_count;
  n.anchor.assign(vertex_count, 0.0);
  n.mass.assign(vertex_count, 1.0);
  n.clamped.assign(vertex_count, 0);
  n.load_scale.assign(vertex_count, 1.0);
  n.output_scale.assign(vertex_count, 1.0);
  return n;
}

// The free vertices' stiffness in the mass-weighted form A = M^-1/2 K M^-1/2 (dense).
Eigen::MatrixXd dense_weighted_stiffness(const SpringNetwork& n, const std::vector<std::int64_t>& free_index,
                                         std::uint32_t free_count) {
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(free_count, free_count);
  for (std::uint32_t i = 0; i < n.vertex_count; ++i) {
    if (free_index[i] >= 0) a(free_index[i], free_index[i]) += n.anchor[i] / n.mass[i];
  }
  for (std::size_t s = 0; s < n.springs.size(); ++s) {
    const auto [p, q] = n.springs[s];
    const double k = n.stiffness[s];
    const std::int64_t fp = free_index[p], fq = free_index[q];
    if (fp >= 0) a(fp, fp) += k / n.mass[p];
    if (fq >= 0) a(fq, fq) += k / n.mass[q];
    if (fp >= 0 && fq >= 0) {
      const double off = -k / std::sqrt(n.mass[p] * n.mass[q]);
      a(fp, fq) += off;
      a(fq, fp) += off;
    }
  }
  return a;
}

// y = A x for the mass-weighted stiffness, matrix-free (power iterations on large networks).
void apply_weighted_stiffness(const SpringNetwork& n, const Eigen::VectorXd& x, Eigen::VectorXd& y) {
  y.setZero(n.vertex_count);
  for (std::uint32_t i = 0; i < n.vertex_count; ++i) {
    if (!n.clamped[i]) y[i] += n.anchor[i] / n.mass[i] * x[i];
  }
  for (std::size_t s = 0; s < n.springs.size(); ++s) {
    const auto [p, q] = n.springs[s];
    const double k = n.stiffness[s];
    const double xp = n.clamped[p] ? 0.0 : x[p] / std::sqrt(n.mass[p]);
    const double xq = n.clamped[q] ? 0.0 : x[q] / std::sqrt(n.mass[q]);
    if (!n.clamped[p]) y[p] += k * (xp - xq) / std::sqrt(n.mass[p]);
    if (!n.clamped[q]) y[q] += k * (xq - xp) / std::sqrt(n.mass[q]);
  }
}

// Largest eigenvalue of (shift I - A) by power iteration from a fixed start (deterministic).
double power_iteration(const SpringNetwork& n, double shift, int iterations) {
  Eigen::VectorXd x(n.vertex_count), y;
  for (std::uint32_t i = 0; i < n.vertex_count; ++i) x[i] = n.clamped[i] ? 0.0 : 1.0 + 0.001 * (i % 7);
  x.normalize();
  double rayleigh = 0.0;
  for (int it = 0; it < iterations; ++it) {
    apply_weighted_stiffness(n, x, y);
    y = shift * x - y;
    for (std::uint32_t i = 0; i < n.vertex_count; ++i) {
      if (n.clamped[i]) y[i] = 0.0;
    }
    rayleigh = x.dot(y);
    x = y.normalized();
  }
  return rayleigh;
}

// |1 + dt s| over the two roots s of s^2 + gamma s + lambda = 0 (one mode of m u'' + c u' + k u).
double euler_factor(double lambda, double gamma, double dt) {
  const double disc = gamma * gamma - 4.0 * lambda;
  if (disc < 0.0) return std::sqrt(std::max(0.0, 1.0 - dt * gamma + dt * dt * lambda));  // complex pair
  const double root = std::sqrt(disc);
  const double slow = -0.5 * (gamma - root), fast = -0.5 * (gamma + root);
  return std::max(std::abs(1.0 + dt * slow), std::abs(1.0 + dt * fast));
}

// The largest dt with euler_factor(lambda, gamma, dt) <= 1.
double stable_step_limit(double lambda, double gamma) {
  const double disc = gamma * gamma - 4.0 * lambda;
  if (disc < 0.0) return gamma / lambda;
  return 4.0 / (gamma + std::sqrt(disc));
}

EulerStepChoice choose_step(double lambda_min, double lambda_max, double gershgorin, bool exact, double tolerance) {
  EulerStepChoice c;
  c.lambda_min = lambda_min;
  c.lambda_max = lambda_max;
  c.gershgorin_max = gershgorin;
  c.exact_spectrum = exact;
  // Sample the spectrum's interval: the worst factor sits at an end or near critical damping.
  std::vector<double> lambdas;
  constexpr int samples = 64;
  for (int i = 0; i <= samples; ++i)
    lambdas.push_back(lambda_min * std::pow(lambda_max / lambda_min, static_cast<double>(i) / samples));
  const double gamma_low = 0.05 * 2.0 * std::sqrt(lambda_min), gamma_high = 20.0 * 2.0 * std::sqrt(lambda_max);
  constexpr int gamma_steps = 160, dt_steps = 200;
  double best = 2.0;
  for (int gi = 0; gi <= gamma_steps; ++gi) {
    const double gamma = gamma_low * std::pow(gamma_high / gamma_low, static_cast<double>(gi) / gamma_steps);
    double limit = std::numeric_limits<double>::infinity();
    for (double l : lambdas) limit = std::min(limit, stable_step_limit(l, gamma));
    for (double l : {gamma * gamma / 4.0}) {
      if (l > lambda_min && l < lambda_max) limit = std::min(limit, stable_step_limit(l, gamma));
    }
    for (int ai = 1; ai < dt_steps; ++ai) {
      const double dt = limit * ai / dt_steps;
      double rho = 0.0;
      for (double l : lambdas) rho = std::max(rho, euler_factor(l, gamma, dt));
      rho = std::max(rho, euler_factor(std::clamp(gamma * gamma / 4.0, lambda_min, lambda_max), gamma, dt));
      if (rho < best) {
        best = rho;
        c.damping = gamma;
        c.stable_step = limit;
        c.step = dt;
      }
    }
  }
  c.contraction = best;
  // From Gershgorin alone (lambda in (0, bound]): the limit is smallest at lambda -> 0 (2 / gamma)
  // or at the bound.
  c.gershgorin_step = std::min(2.0 / c.damping, stable_step_limit(gershgorin, c.damping));
  c.predicted_steps = std::log(tolerance) / std::log(best);
  return c;
}

}  // namespace

// ---- Networks ----------------------------------------------------------------------------------

SpringNetwork clamped_network(const LinkGraph& graph, std::span<const double> mu,
                              std::span<const std::uint32_t> clamped_vertices) {
  const std::uint32_t v = graph.vertex_count();
  if (mu.size() != v) throw ValueError("clamped network: expected one shear modulus per vertex");
  if (graph.links.empty()) throw ValueError("clamped network: no links");
  double mean_mu = 0.0, mean_length = 0.0;
  for (double m : mu) mean_mu += m;
  mean_mu /= static_cast<double>(v);
  for (const auto& l : graph.links) mean_length += (graph.positions[l[1]] - graph.positions[l[0]]).norm();
  mean_length /= static_cast<double>(graph.links.size());
  SpringNetwork n = empty_network(v);
  for (const auto& l : graph.links) {
    const double length = (graph.positions[l[1]] - graph.positions[l[0]]).norm();
    n.springs.push_back(l);
    n.stiffness.push_back(0.5 * (mu[l[0]] + mu[l[1]]) / mean_mu / (length / mean_length));
  }
  for (std::uint32_t c : clamped_vertices) {
    if (c >= v) throw ValueError("clamped network: clamped vertex out of range");
    n.clamped[c] = 1;
  }
  check_network(n);
  return n;
}

SpringNetwork matched_network(const field::FieldGraph& g) {
  const std::uint32_t v = g.mass_count();
  SpringNetwork n = empty_network(v);
  const auto& s = g.weight();
  const auto& z = g.normaliser();
  std::vector<double> spring_sum(v, 0.0);
  for (std::uint32_t e = 0; e < g.spring_count(); ++e) {
    const double ge = g.distance_factor()[e];
    const double c = ge * ge * s[v + e] / z[v + e];
    n.springs.push_back(g.edges()[e]);
    n.stiffness.push_back(c);
    spring_sum[g.edges()[e][0]] += c;
    spring_sum[g.edges()[e][1]] += c;
  }
  for (std::uint32_t i = 0; i < v; ++i) {
    n.anchor[i] = z[i] / s[i] - 2.0 * spring_sum[i];
    if (n.anchor[i] < -1e-12 * z[i] / s[i])
      throw UnsupportedError("matched network: vertex " + std::to_string(i) + " would need a negative anchor");
    n.anchor[i] = std::max(0.0, n.anchor[i]);
    n.load_scale[i] = 1.0 / s[i];
    n.output_scale[i] = s[i];
  }
  check_network(n);
  return n;
}

// ---- MassSpring_Witkin --------------------------------------------------------------------------

MassSpring_Witkin::MassSpring_Witkin(SpringNetwork network, double tolerance) : network_(std::move(network)) {
  check_network(network_);
  const SpringNetwork& n = network_;
  std::vector<std::int64_t> free_index(n.vertex_count, -1);
  std::uint32_t free_count = 0;
  for (std::uint32_t i = 0; i < n.vertex_count; ++i) {
    if (!n.clamped[i]) free_index[i] = free_count++;
  }
  if (free_count == 0) throw ValueError("spring network: every vertex is clamped");
  // Gershgorin: every eigenvalue of A lies below max_i sum_j |A_ij| (row sums of |M^-1/2 K M^-1/2|).
  std::vector<double> row(n.vertex_count, 0.0);
  for (std::uint32_t i = 0; i < n.vertex_count; ++i) row[i] = n.anchor[i] / n.mass[i];
  for (std::size_t s = 0; s < n.springs.size(); ++s) {
    const auto [p, q] = n.springs[s];
    const double k = n.stiffness[s];
    row[p] += k / n.mass[p];
    row[q] += k / n.mass[q];
    if (!n.clamped[p] && !n.clamped[q]) {
      row[p] += k / std::sqrt(n.mass[p] * n.mass[q]);
      row[q] += k / std::sqrt(n.mass[p] * n.mass[q]);
    }
  }
  double gershgorin = 0.0;
  for (std::uint32_t i = 0; i < n.vertex_count; ++i) {
    if (!n.clamped[i]) gershgorin = std::max(gershgorin, row[i]);
  }
  double lambda_min = 0.0, lambda_max = 0.0;
  const bool exact = free_count <= dense_spectrum_limit;
  if (exact) {
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(dense_weighted_stiffness(n, free_index, free_count),
                                                             Eigen::EigenvaluesOnly);
    lambda_min = eig.eigenvalues().minCoeff();
    lambda_max = eig.eigenvalues().maxCoeff();
  } else {
    // Large networks: lambda_max from Gershgorin (a safe bound), lambda_min from power
    // iterations on (bound I - A) (an estimate; it only tunes the damping, never stability).
    lambda_max = gershgorin;
    lambda_min = gershgorin - power_iteration(n, gershgorin, 3000);
  }
  if (!(lambda_min > 1e-12 * lambda_max))
    throw UnsupportedError("spring network: no steady state (a free part is neither clamped nor anchored)");
  choice_ = choose_step(lambda_min, lambda_max, gershgorin, exact, tolerance);
}

ComparatorResult MassSpring_Witkin::solve(std::span<const double> load, const ComparatorOptions& o) const {
  const auto start = Clock::now();
  const SpringNetwork& n = network_;
  field::detail::check_load(load, n.vertex_count);
  ComparatorResult out;
  out.method = name();
  out.displacement.assign(n.vertex_count, 0.0);
  std::vector<double> b(n.vertex_count, 0.0), inv_mass(n.vertex_count), drag(n.vertex_count);
  double max_b = 0.0;
  std::uint32_t free_count = 0;
  for (std::uint32_t i = 0; i < n.vertex_count; ++i) {
    if (n.clamped[i]) continue;
    ++free_count;
    b[i] = n.load_scale[i] * load[i];
    max_b = std::max(max_b, std::abs(b[i]));
    inv_mass[i] = 1.0 / n.mass[i];
    drag[i] = choice_.damping * n.mass[i];  // c = gamma m
  }
  if (max_b == 0.0) return out;
  const double dt = choice_.step;
  std::vector<double> u(n.vertex_count, 0.0), v(n.vertex_count, 0.0), force(n.vertex_count, 0.0);
  // Counted per loop pass: a spring costs 3 additions (difference, two accumulations) and 1
  // multiplication; a free vertex 4 additions and 5 multiplications (anchor, drag, 1/m, two
  // Euler updates).
  const std::uint64_t step_additions = 3 * n.springs.size() + 4ULL * free_count;
  const std::uint64_t step_multiplications = 1 * n.springs.size() + 5ULL * free_count;
  detail::TraceSampler sampler;
  field::OperationCounts c;
  std::uint64_t steps = 0;
  double residual = 0.0;
  while (true) {
    // Forces at the current state (Witkin: clear, accumulate per spring, per particle).
    for (std::uint32_t i = 0; i < n.vertex_count; ++i) force[i] = n.clamped[i] ? 0.0 : b[i] - n.anchor[i] * u[i];
    for (std::size_t s = 0; s < n.springs.size(); ++s) {
      const auto [p, q] = n.springs[s];
      const double f = n.stiffness[s] * (u[p] - u[q]);
      force[p] -= f;
      force[q] += f;
    }
    residual = 0.0;
    for (std::uint32_t i = 0; i < n.vertex_count; ++i) {
      if (!n.clamped[i]) residual = std::max(residual, std::abs(force[i]));
    }
    residual /= max_b;
    const bool done = residual <= o.tolerance;
    if (done) sampler.force_next();
    if (sampler.due(steps)) {
      const double probe = o.probe_vertex >= 0 ? n.output_scale[static_cast<std::size_t>(o.probe_vertex)] *
                                                     u[static_cast<std::size_t>(o.probe_vertex)]
                                               : 0.0;
      sampler.record(out.trace, steps, c.additions + c.multiplications, residual, probe);
    }
    if (done) break;
    if (steps >= o.step_limit) throw Error(ExitCode::failure, "mass-spring: explicit Euler did not converge");
    // Explicit Euler on (u, v): both updates use the state at the start of the step.
    for (std::uint32_t i = 0; i < n.vertex_count; ++i) {
      if (n.clamped[i]) continue;
      const double acceleration = (force[i] - drag[i] * v[i]) * inv_mass[i];
      u[i] += dt * v[i];
      v[i] += dt * acceleration;
    }
    c.additions += step_additions;
    c.multiplications += step_multiplications;
    ++steps;
  }
  for (std::uint32_t i = 0; i < n.vertex_count; ++i) out.displacement[i] = n.output_scale[i] * u[i];
  out.steps = steps;
  out.counts = c;
  out.residual = residual;
  out.seconds = seconds_since(start);
  return out;
}

}  // namespace pneuma::paper
