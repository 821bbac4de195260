// The comparators against independent oracles: dense direct solves of their own linear
// systems, Eigen's sparse LU of the field, the lattice's symmetry group, and the production
// Shot/UnShot.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "compare_fixture.h"
#include "pneuma/core/error.h"
#include "pneuma/field/field_graph.h"
#include "pneuma/field/field_solver.h"
#include "pneuma/paper/comparators.h"

using namespace pneuma;
using namespace pneuma::field;
using namespace pneuma::paper;

namespace {

// Shear modulus rising 1:4 along the rows, so that nothing is uniform by accident.
std::vector<double> graded(const LinkGraph& g) {
  std::vector<double> mu;
  double top = 0.0;
  for (const auto& p : g.positions) top = std::max(top, p.y());
  for (const auto& p : g.positions) mu.push_back(1e3 * (1.0 + 3.0 * p.y() / top));
  return mu;
}

// A deterministic, uneven, positive load.
std::vector<double> uneven_load(std::uint32_t n) {
  std::vector<double> f(n);
  for (std::uint32_t i = 0; i < n; ++i) f[i] = 0.2 + static_cast<double>((i * 37) % 11) / 10.0;
  return f;
}

std::vector<double> field_exact(const FieldGraph& fg, const std::vector<double>& vertex_load) {
  std::vector<double> load(fg.node_count(), 0.0);
  std::copy(vertex_load.begin(), vertex_load.end(), load.begin());
  const SolveResult r = Direct_Eigen(std::make_shared<const TransferOperator>(one_hop_operator(fg))).solve(load);
  return {r.shot.begin(), r.shot.begin() + fg.mass_count()};
}

ComparatorOptions tight(double tolerance = 1e-11) {
  ComparatorOptions o;
  o.tolerance = tolerance;
  return o;
}

}  // namespace

// ---- Test graphs ---------------------------------------------------------------------------------

TEST(LinkGraph, LatticeHasRowWiseNumberingAndFourNeighbours) {
  const LinkGraph g = square_lattice(4);
  ASSERT_EQ(g.vertex_count(), 16u);
  EXPECT_EQ(g.links.size(), 2u * 4u * 3u);
  EXPECT_TRUE(std::is_sorted(g.links.begin(), g.links.end()));
  EXPECT_EQ(g.positions[6], Eigen::Vector3d(2, 1, 0));  // row 1, column 2
  EXPECT_EQ(lattice_border(4).size(), 12u);
  EXPECT_THROW(square_lattice(1), pneuma::ValueError);
}

TEST(LinkGraph, FieldGraphOfTheLinkMeshHasExactlyTheLinks) {
  const LinkGraph g = remove_links(square_lattice(9), 0.1, 7);
  const FieldGraph fg(link_mesh(g), std::vector<double>(g.vertex_count(), 1e3));
  EXPECT_EQ(fg.edges(), g.links);
  EXPECT_EQ(fg.mass_count(), g.vertex_count());
}

TEST(LinkGraph, LinkRemovalIsSeededAndReproducible) {
  const LinkGraph regular = square_lattice(60);
  const LinkGraph a = remove_links(regular, 0.1, 42), b = remove_links(regular, 0.1, 42);
  const LinkGraph c = remove_links(regular, 0.1, 43);
  EXPECT_EQ(a.links, b.links) << "same seed, same graph";
  EXPECT_NE(a.links, c.links) << "different seed, different graph";
  // About 10 % removed (binomial: 7080 links, sd 0.36 %), never isolating a vertex.
  const double removed = 1.0 - static_cast<double>(a.links.size()) / static_cast<double>(regular.links.size());
  EXPECT_NEAR(removed, 0.1, 0.015);
  std::vector<int> degree(a.vertex_count(), 0);
  for (const auto& l : a.links) ++degree[l[0]], ++degree[l[1]];
  EXPECT_GT(*std::min_element(degree.begin(), degree.end()), 0);
  // A removed link is a link of the regular lattice, and no link is added.
  const std::set<std::array<std::uint32_t, 2>> all(regular.links.begin(), regular.links.end());
  for (const auto& l : c.links) EXPECT_TRUE(all.count(l));
  EXPECT_EQ(remove_links(regular, 0.0, 1).links, regular.links);
}

// ---- Witkin's mass-spring ----------------------------------------------------------------------

TEST(MassSpringWitkin, ClampedSteadyStateEqualsTheDirectSolutionOfItsLinearSystem) {
  const LinkGraph g = square_lattice(11);
  const SpringNetwork net = clamped_network(g, graded(g), lattice_border(11));
  const auto load = uneven_load(g.vertex_count());
  const MassSpring_Witkin ms(net);
  const ComparatorResult r = ms.solve(load, tight());
  const std::vector<double> exact = test::direct_equilibrium(net, load);
  EXPECT_LE(r.residual, 1e-11);
  // |u - u*| <= |K^-1| |r| <= (1 / lambda_min) tol max b with unit masses.
  const double bound = 1e-11 * test::max_abs(load) / ms.step_choice().lambda_min;
  EXPECT_LE(test::max_abs_difference(r.displacement, exact), bound);
  EXPECT_GT(test::max_abs(exact), 1.0);  // a real deflection, not a trivially small one
  for (std::uint32_t v : lattice_border(11)) EXPECT_EQ(r.displacement[v], 0.0);
}

TEST(MassSpringWitkin, MatchedNetworkReproducesTheFieldsFixedPoint) {
  const LinkGraph g = remove_links(square_lattice(12), 0.1, 3);
  const auto mu = graded(g);
  const FieldGraph fg(link_mesh(g), mu);
  const SpringNetwork net = matched_network(fg);
  const auto load = uneven_load(g.vertex_count());
  // Its own linear system first, then the field it was derived from (Eigen sparse LU).
  const ComparatorResult r = MassSpring_Witkin(net).solve(load, tight());
  const std::vector<double> direct = test::direct_equilibrium(net, load);
  const std::vector<double> field = field_exact(fg, load);
  const double scale = test::max_abs(field);
  EXPECT_LE(test::max_abs_difference(r.displacement, direct), 1e-9 * scale);
  EXPECT_LE(test::max_abs_difference(direct, field), 1e-12 * scale);
  for (double a : net.anchor) EXPECT_GT(a, 0.0);
}

TEST(MassSpringWitkin, StepChoiceIsStableAndTheBoundsHold) {
  const LinkGraph g = square_lattice(9);
  for (const SpringNetwork& net :
       {clamped_network(g, graded(g), lattice_border(9)), matched_network(FieldGraph(link_mesh(g), graded(g)))}) {
    const MassSpring_Witkin ms(net);
    const EulerStepChoice& c = ms.step_choice();
    EXPECT_TRUE(c.exact_spectrum);
    EXPECT_GT(c.lambda_min, 0.0);
    EXPECT_LE(c.lambda_max, c.gershgorin_max * (1 + 1e-12));
    EXPECT_GT(c.step, 0.0);
    EXPECT_LE(c.step, c.stable_step);
    EXPECT_LE(c.gershgorin_step, c.stable_step * (1 + 1e-12)) << "Gershgorin can only be more cautious";
    EXPECT_LT(c.contraction, 1.0);
    // The predicted number of steps is what the run takes, within the transient's slack.
    const ComparatorResult r = ms.solve(uneven_load(g.vertex_count()), ComparatorOptions{});
    EXPECT_LE(static_cast<double>(r.steps), 1.5 * c.predicted_steps + 10);
  }
}

TEST(MassSpringWitkin, RejectsBadLoadsAndFreeFloatingNetworks) {
  const LinkGraph g = square_lattice(4);
  const MassSpring_Witkin ms(clamped_network(g, std::vector<double>(16, 1.0), lattice_border(4)));
  EXPECT_THROW(ms.solve(std::vector<double>(3, 1.0), ComparatorOptions{}), pneuma::ValueError);
  EXPECT_THROW(ms.solve(std::vector<double>(16, -1.0), ComparatorOptions{}), pneuma::ValueError);
  EXPECT_THROW(MassSpring_Witkin(clamped_network(g, std::vector<double>(16, 1.0), {})), UnsupportedError);
}

// ---- The proposed method -------------------------------------------------------------------------

TEST(ProposedSanthanam, TracedShotUnshotIsTheProductionSolverBitForBit) {
  const LinkGraph g = remove_links(square_lattice(15), 0.1, 9);
  const FieldGraph fg(link_mesh(g), graded(g));
  const auto load = uneven_load(g.vertex_count());
  std::vector<double> node_load(fg.node_count(), 0.0);
  std::copy(load.begin(), load.end(), node_load.begin());
  const SolveResult production =
      ShotUnshot_Santhanam(std::make_shared<const TransferOperator>(one_hop_operator(fg)), SolveOptions{1e-8}, true)
          .solve(node_load);
  ComparatorOptions o = tight(1e-8);
  o.probe_vertex = 5;
  const ComparatorResult traced =
      Proposed_Santhanam(std::make_shared<const TransferOperator>(one_hop_operator(fg))).solve(load, o);
  EXPECT_EQ(traced.steps, production.report.shots);
  EXPECT_EQ(traced.counts.additions, production.report.counts.additions);
  EXPECT_EQ(traced.counts.multiplications, production.report.counts.multiplications);
  for (std::uint32_t v = 0; v < fg.mass_count(); ++v) EXPECT_EQ(traced.displacement[v], production.shot[v]);
  // The trace starts at the load and ends at the result.
  EXPECT_EQ(traced.trace.step.front(), 0u);
  EXPECT_EQ(traced.trace.residual.front(), 1.0);
  EXPECT_EQ(traced.trace.step.back(), traced.steps);
  EXPECT_EQ(traced.trace.residual.back(), traced.residual);
  EXPECT_EQ(traced.trace.probe.back(), traced.displacement[5]);
  EXPECT_TRUE(std::is_sorted(traced.trace.step.begin(), traced.trace.step.end()));
}

TEST(ProposedSanthanam, FieldOnTheRegularGridHasTheGridsSymmetries) {
  constexpr std::uint32_t side = 15;
  const LinkGraph g = square_lattice(side);
  const FieldGraph fg(link_mesh(g), std::vector<double>(g.vertex_count(), 2e3));
  std::vector<double> push(g.vertex_count(), 0.0);
  const std::uint32_t centre = (side / 2) * side + side / 2;
  push[centre] = 1.0;
  const std::vector<double> exact = field_exact(fg, push);
  const ComparatorResult shot =
      Proposed_Santhanam(std::make_shared<const TransferOperator>(one_hop_operator(fg))).solve(push, tight(1e-9));
  const LinkGraph lg = square_lattice(side);
  const ComparatorResult membrane =
      MassSpring_Witkin(clamped_network(lg, std::vector<double>(lg.vertex_count(), 1.0), lattice_border(side)))
          .solve(push, tight(1e-11));
  const double peak = exact[centre];
  for (const auto& map : test::lattice_symmetries(side)) {
    for (std::uint32_t v = 0; v < g.vertex_count(); ++v) {
      ASSERT_NEAR(exact[map[v]], exact[v], 1e-13 * peak) << "direct, vertex " << v;
      // Shot/UnShot stops with max UnShot <= 1e-9: each value is within a few of that.
      ASSERT_NEAR(shot.displacement[map[v]], shot.displacement[v], 1e-8 * peak) << "Shot/UnShot, vertex " << v;
      ASSERT_NEAR(membrane.displacement[map[v]], membrane.displacement[v], 1e-8) << "mass-spring, vertex " << v;
    }
  }
  // And the field decays away from the push along every direction.
  EXPECT_GT(exact[centre], exact[centre + 1]);
  EXPECT_GT(exact[centre + 1], exact[centre + 2]);
}

// ---- Hauth's exponential precomputation -------------------------------------------------------------

TEST(ExponentialHauth, SharesFollowTheExponentialAndConserve) {
  const LinkGraph g = square_lattice(5);
  std::vector<double> mu(g.vertex_count(), 1e3);
  mu[7] = 3e3;  // a stiffer neighbour of vertex 12 (the centre) passes less on to it
  const Exponential_Hauth h(g, mu);
  const TransferOperator& op = *h.transfer();
  const double mean_mu = (24 * 1e3 + 3e3) / 25.0;
  // Centre vertex 12: neighbours 7, 11, 13, 17 at distance 1 (the mean link length).
  double total = 1.0;
  for (std::uint32_t n : {7u, 11u, 13u, 17u}) total += std::exp(-mu[n] / mean_mu);
  for (std::uint64_t j = op.offset[12]; j < op.offset[13]; ++j)
    EXPECT_NEAR(op.share[j], std::exp(-mu[op.target[j]] / mean_mu) / total, 1e-15);
  EXPECT_NEAR(op.self_share[12], 1.0 / total, 1e-15);
  for (std::uint32_t k = 0; k < op.node_count; ++k) {
    double sum = op.self_share[k];
    for (std::uint64_t j = op.offset[k]; j < op.offset[k + 1]; ++j) sum += op.share[j];
    EXPECT_NEAR(sum, 1.0, 1e-14);
  }
}

TEST(ExponentialHauth, SweepsConvergeToTheDirectSolutionOfTheirFixedPoint) {
  const LinkGraph g = remove_links(square_lattice(10), 0.1, 5);
  const Exponential_Hauth h(g, graded(g));
  const auto load = uneven_load(g.vertex_count());
  const ComparatorResult r = h.solve(load, tight(1e-12));
  const SolveResult exact = Direct_Eigen(h.transfer()).solve(load);
  // Error <= max residual * max row sum of T (I - P^T)^-1 = 1e-12 * (1 / min self share) at most.
  EXPECT_LE(test::max_abs_difference(r.displacement, exact.shot), 1e-12 * test::max_abs(load) * 10.0);
  EXPECT_GT(r.steps, 5u);
}
