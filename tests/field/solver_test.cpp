// The graph and the solvers against independent oracles: METHOD.md's formulas evaluated by
// hand, the shares' conservation bound, and Eigen's sparse LU of the same fixed point.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstring>
#include <map>
#include <string>

#include "field_fixture.h"
#include "pneuma/core/error.h"
#include "pneuma/field/field_graph.h"
#include "pneuma/field/field_solver.h"

using namespace pneuma;
using namespace pneuma::field;

namespace {

struct Case {
  std::string name;
  mesh::TriangleMesh mesh;
  std::vector<double> mu;
};

std::vector<Case> cases() {
  std::vector<Case> out;
  auto add = [&](std::string name, mesh::TriangleMesh m, std::vector<double> mu) {
    out.push_back({std::move(name), std::move(m), std::move(mu)});
  };
  const auto grid = test::regular_grid(12, 9, 0.01);
  const auto sphere = mesh::make_icosphere(0.1, 3);
  const auto ellipsoid = test::ellipsoid(0.12, 0.08, 0.15, 3);
  add("triangle", test::single_triangle(), {1e3, 2e3, 3e3});
  add("grid_uniform", grid, std::vector<double>(grid.vertex_count(), 2e3));
  add("grid_graded", grid, test::graded_modulus(grid, 1e3, 4e3, 1));
  add("sphere_uniform", sphere, std::vector<double>(sphere.vertex_count(), 3e3));
  add("sphere_graded", sphere, test::graded_modulus(sphere, 0.6e3, 2.4e3));
  add("sphere_contrast_100_to_1", sphere, test::contrast_modulus(sphere));
  add("ellipsoid_graded", ellipsoid, test::graded_modulus(ellipsoid, 1e3, 5e3));
  return out;
}

std::shared_ptr<const TransferOperator> one_hop(const FieldGraph& g) {
  return std::make_shared<const TransferOperator>(one_hop_operator(g));
}

std::vector<double> mass_load(const FieldGraph& g, double value = 1.0) {
  std::vector<double> f(g.node_count(), 0.0);
  std::fill(f.begin(), f.begin() + g.mass_count(), value);
  return f;
}

// max_k (T (I - P^T)^-1 1)_k: how far a residual of 1 everywhere can move the shots (every
// entry of (I - P^T)^-1 is >= 0, so this row sum bounds the error of any stopped solver).
double error_amplification(const std::shared_ptr<const TransferOperator>& op) {
  const Direct_Eigen lu(op);
  const std::vector<double> ones(op->node_count, 1.0);
  const SolveResult r = lu.solve(ones);
  return *std::max_element(r.shot.begin(), r.shot.end());
}

}  // namespace

TEST(FieldGraph, SharesFollowMethodFormulasOnASingleTriangle) {
  // Independent evaluation of METHOD.md sections 1-2 for the triangle (0,0),(1,0),(0,2).
  const auto m = test::single_triangle();
  const std::vector<double> mu{1e3, 2e3, 3e3};
  const FieldGraph g(m, mu);
  const TransferOperator one = one_hop_operator(g);
  ASSERT_EQ(g.mass_count(), 3u);
  ASSERT_EQ(g.spring_count(), 3u);
  const double mean = 2e3;
  const double rel[3] = {mu[0] / mean, mu[1] / mean, mu[2] / mean};
  // Edges sorted: (0,1) length 1, (0,2) length 2, (1,2) length sqrt 5.
  const std::array<std::array<int, 2>, 3> edge{{{0, 1}, {0, 2}, {1, 2}}};
  const double length[3] = {1.0, 2.0, std::sqrt(5.0)};
  const double h = (length[0] + length[1] + length[2]) / 6.0;
  std::map<int, double> s;
  for (int i = 0; i < 3; ++i) s[i] = 1.0 / rel[i];
  for (int e = 0; e < 3; ++e) s[3 + e] = 0.5 * (rel[edge[e][0]] + rel[edge[e][1]]);
  auto factor = [&](int e) { return 1.0 / std::max(1.0, length[e] / 2.0 / h); };
  const TransferOperator& op = one;
  EXPECT_DOUBLE_EQ(g.reference_distance(), h);
  for (int i = 0; i < 3; ++i) {
    double z = s[i];
    for (int e = 0; e < 3; ++e) {
      if (edge[e][0] == i || edge[e][1] == i) z += s[3 + e];
    }
    EXPECT_NEAR(op.self_share[i], s[i] / z, 1e-15);
    for (std::uint64_t j = op.offset[i]; j < op.offset[i + 1]; ++j) {
      const int e = static_cast<int>(op.target[j]) - 3;
      EXPECT_NEAR(op.share[j], s[3 + e] / z * factor(e), 1e-15) << "mass " << i << " -> spring " << e;
    }
  }
  for (int e = 0; e < 3; ++e) {
    const double z = s[3 + e] + s[edge[e][0]] + s[edge[e][1]];
    EXPECT_NEAR(op.self_share[3 + e], s[3 + e] / z, 1e-15);
    for (std::uint64_t j = op.offset[3 + e]; j < op.offset[4 + e]; ++j) {
      EXPECT_NEAR(op.share[j], s[op.target[j]] / z * factor(e), 1e-15);
    }
  }
}

TEST(FieldGraph, OneHopSharesOfEveryNodeSumToAtMostOne) {
  for (const Case& c : cases()) {
    const FieldGraph g(c.mesh, c.mu);
    const TransferOperator op = one_hop_operator(g);
    for (std::uint32_t k = 0; k < op.node_count; ++k) {
      double total = op.self_share[k];
      for (std::uint64_t j = op.offset[k]; j < op.offset[k + 1]; ++j) {
        EXPECT_GT(op.share[j], 0.0);
        total += op.share[j];
      }
      EXPECT_GT(op.self_share[k], 0.0);
      EXPECT_LE(total, 1.0 + 1e-14) << c.name << " node " << k;
    }
  }
}

TEST(FieldGraph, RefusesBadModuli) {
  const auto m = test::single_triangle();
  EXPECT_THROW(FieldGraph(m, std::vector<double>{1, 2}), InputError);
  EXPECT_THROW(FieldGraph(m, std::vector<double>{1, -2, 3}), InputError);
}

TEST(Solvers, AllAgreeWithTheDirectSolveToTheTolerance) {
  const double tol = 1e-6;
  for (const Case& c : cases()) {
    const auto graph = std::make_shared<const FieldGraph>(c.mesh, c.mu);
    const FieldGraph& g = *graph;
    const auto op = one_hop(g);
    const std::vector<double> f = mass_load(g);
    const SolveResult exact = Direct_Eigen(op).solve(f);
    EXPECT_LT(exact.report.residual, 1e-12) << c.name;
    const double amplification = error_amplification(op);
    EXPECT_LT(amplification, 50.0) << c.name << ": the bound below would be too loose to test anything";
    const double bound = tol * amplification * (1 + 1e-9) + 1e-13;
    std::vector<std::unique_ptr<FieldSolver>> solvers;
    solvers.push_back(std::make_unique<ShotUnshot_Santhanam>(op, SolveOptions{tol}));
    solvers.push_back(std::make_unique<Sweep_GaussSeidel>(op, SolveOptions{tol}));
    solvers.push_back(std::make_unique<ConjugateGradient_Schur>(graph, SolveOptions{tol}));
    solvers.push_back(std::make_unique<Direct_Eigen>(op, SolveOptions{tol}, 0));  // BiCGSTAB
    for (const auto& solver : solvers) {
      const SolveResult r = solver->solve(f);
      EXPECT_LE(r.report.residual, tol) << c.name << " " << solver->name();
      EXPECT_LE(test::max_abs_difference(r.shot, exact.shot, g.node_count()), bound) << c.name << " " << solver->name();
    }
  }
}

TEST(Solvers, ShotUnshotStopsExactlyAtTheTolerance) {
  // A looser tolerance takes fewer shots and leaves a residual just under it.
  const auto sphere = mesh::make_icosphere(1.0, 3);
  const FieldGraph g(sphere, std::vector<double>(sphere.vertex_count(), 1.0));
  const auto f = mass_load(g);
  std::uint64_t previous = 0;
  for (double tol : {1e-2, 1e-4, 1e-6, 1e-8}) {
    const SolveResult r = ShotUnshot_Santhanam(one_hop(g), SolveOptions{tol}).solve(f);
    EXPECT_LE(r.report.residual, tol);
    EXPECT_GT(r.report.shots, previous);
    previous = r.report.shots;
  }
}

TEST(Solvers, ConjugateGradientIsBitIdenticalAtAnyThreadCount) {
  const auto m = test::ellipsoid(1.0, 0.7, 1.3, 5);  // 10k vertices: several TBB blocks
  const auto graph = std::make_shared<const FieldGraph>(m, test::graded_modulus(m, 1.0, 3.0));
  const auto f = mass_load(*graph);
  std::vector<double> one, two;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = ConjugateGradient_Schur(graph).solve(f).shot;
  }
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    two = ConjugateGradient_Schur(graph).solve(f).shot;
  }
  ASSERT_EQ(one.size(), two.size());
  EXPECT_EQ(0, std::memcmp(one.data(), two.data(), one.size() * sizeof(double)));
}

TEST(Cliques, OneHopCliqueIsTheOneHopOperator) {
  const auto sphere = mesh::make_icosphere(1.0, 2);
  const FieldGraph g(sphere, test::graded_modulus(sphere, 1.0, 2.0));
  const TransferOperator c = clique_operator(g, 1);
  const TransferOperator one = one_hop_operator(g);
  EXPECT_EQ(c.offset, one.offset);
  EXPECT_EQ(c.target, one.target);
  EXPECT_EQ(c.share, one.share);
  EXPECT_EQ(c.self_share, one.self_share);
}

TEST(Cliques, LeavingShareNeverExceedsOneHopAndSolversAgree) {
  const auto sphere = mesh::make_icosphere(1.0, 2);
  const FieldGraph g(sphere, test::contrast_modulus(sphere));
  const TransferOperator one = one_hop_operator(g);
  const auto f = mass_load(g);
  OperationCounts previous;
  for (int hops = 2; hops <= 4; ++hops) {
    for (CliquePathRule rule : {CliquePathRule::sum_of_shortest_paths, CliquePathRule::strongest_path}) {
      auto op = std::make_shared<const TransferOperator>(clique_operator(g, hops, rule));
      for (std::uint32_t k = 0; k < op->node_count; ++k) {
        double leaving = 0.0, leaving_one = 0.0;
        for (std::uint64_t j = op->offset[k]; j < op->offset[k + 1]; ++j) leaving += op->share[j];
        for (std::uint64_t j = one.offset[k]; j < one.offset[k + 1]; ++j) leaving_one += one.share[j];
        EXPECT_LE(leaving, leaving_one * (1 + 1e-14)) << hops << " hops, node " << k;
        EXPECT_EQ(op->self_share[k], one.self_share[k]);
      }
      const SolveResult exact = Direct_Eigen(op).solve(f);
      const double bound = 1e-6 * error_amplification(op) * (1 + 1e-9) + 1e-13;
      const SolveResult shot = ShotUnshot_Santhanam(op, SolveOptions{1e-6}, true).solve(f);
      EXPECT_LE(test::max_abs_difference(shot.shot, exact.shot, g.node_count()), bound) << hops;
      if (rule == CliquePathRule::sum_of_shortest_paths) {
        // Counted, not computed: each shot adds and multiplies once per target plus once for itself.
        EXPECT_EQ(shot.report.counts.additions, shot.report.counts.multiplications);
        EXPECT_GT(op->build_counts.multiplications, previous.multiplications);
        previous = op->build_counts;
      }
    }
  }
}

TEST(Cliques, RefuseOutOfRangeSizes) {
  const auto m = test::single_triangle();
  const FieldGraph g(m, std::vector<double>{1, 1, 1});
  EXPECT_THROW(clique_operator(g, 0), pneuma::ValueError);
  EXPECT_THROW(clique_operator(g, 9), pneuma::ValueError);
}
