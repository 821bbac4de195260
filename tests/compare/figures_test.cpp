// The experiments of the paper's evaluation at small sizes: Table 1's operation counts grow
// linearly in N, the figures hold what they claim to hold, and the plots are deterministic.
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "pneuma/core/error.h"
#include "pneuma/paper/paper_figures.h"
#include "pneuma/paper/svg_plot.h"

using namespace pneuma::paper;

namespace {

std::size_t column(const FigureOutput& f, const std::string& name) {
  for (std::size_t i = 0; i < f.columns.size(); ++i) {
    if (f.columns[i] == name) return i;
  }
  ADD_FAILURE() << f.name << ": no column " << name;
  return 0;
}

double cell(const FigureOutput& f, std::size_t row, const std::string& name) {
  return std::stod(f.rows[row][column(f, name)]);
}

}  // namespace

TEST(LogLogSlope, RecoversAnExactPowerLaw) {
  EXPECT_NEAR(
      log_log_slope({1, 10, 100, 1000}, {3, 3 * std::pow(10, 1.5), 3 * std::pow(100, 1.5), 3 * std::pow(1000, 1.5)}),
      1.5, 1e-12);
  EXPECT_NEAR(log_log_slope({2, 4}, {5, 5}), 0.0, 1e-12);
  EXPECT_THROW(log_log_slope({1}, {1}), pneuma::ValueError);
  EXPECT_THROW(log_log_slope({2, 2}, {1, 3}), pneuma::ValueError);
}

TEST(Table1, CountedOperationsGrowLinearlyInN) {
  ReproductionOptions o = quick_reproduction_options();
  o.table1_sides = {16, 32, 64};  // N = 256 .. 4096
  o.max_clique = 3;
  const FigureOutput t = table1(o);
  ASSERT_EQ(t.rows.size(), 9u);
  std::map<int, std::vector<double>> n, add, mul;
  for (std::size_t r = 0; r < t.rows.size(); ++r) {
    const int m = static_cast<int>(cell(t, r, "M"));
    n[m].push_back(cell(t, r, "N"));
    add[m].push_back(cell(t, r, "additions"));
    mul[m].push_back(cell(t, r, "multiplications"));
    // Every shot does one multiplication and one addition per target plus one for itself.
    EXPECT_EQ(cell(t, r, "additions"), cell(t, r, "multiplications"));
    EXPECT_GE(cell(t, r, "additions"), cell(t, r, "shots"));
  }
  for (int m = 1; m <= 3; ++m) {
    EXPECT_NEAR(log_log_slope(n[m], add[m]), 1.0, 0.1) << "M = " << m;
    EXPECT_NEAR(log_log_slope(n[m], mul[m]), 1.0, 0.1) << "M = " << m;
  }
  // Larger cliques cost more per node (the paper: O(N * M) multiplications).
  EXPECT_GT(mul[2].back(), mul[1].back());
  EXPECT_GT(mul[3].back(), mul[2].back());
}

TEST(Figure6, MatchedMassSpringAgreesAndTheFieldIsNormalisedAtThePush) {
  const ReproductionOptions o = quick_reproduction_options();
  const FigureOutput f = figure6(o);
  ASSERT_EQ(f.rows.size(), std::size_t{o.grid_side} * o.grid_side);
  const std::size_t centre = (o.grid_side / 2) * o.grid_side + o.grid_side / 2;
  EXPECT_EQ(cell(f, centre, "proposed"), 1.0);
  EXPECT_EQ(cell(f, centre, "mass_spring_clamped"), 1.0);
  for (std::size_t r = 0; r < f.rows.size(); ++r) {
    EXPECT_NEAR(cell(f, r, "difference_matched"), 0.0, 1e-4);  // two stopped iterations, tolerance 1e-6
    EXPECT_EQ(cell(f, r, "row") * o.grid_side + cell(f, r, "column"), static_cast<double>(r));  // row-wise
  }
}

TEST(Figure7, BothMethodsConvergeAndTracesEndBelowTheTolerance) {
  const ReproductionOptions o = quick_reproduction_options();
  const FigureOutput f = figure7(o);
  std::map<std::string, double> last;
  for (std::size_t r = 0; r < f.rows.size(); ++r) last[f.rows[r][0]] = cell(f, r, "residual");
  ASSERT_EQ(last.size(), 3u);
  for (const auto& [method, residual] : last) EXPECT_LE(residual, o.tolerance) << method;
}

TEST(Figure8, ProbeTracesEndAtTheirFinalValue) {
  const FigureOutput f = figure8(quick_reproduction_options());
  std::map<std::string, double> last;
  for (std::size_t r = 0; r < f.rows.size(); ++r) last[f.rows[r][0]] = cell(f, r, "probe_over_final");
  ASSERT_EQ(last.size(), 3u);
  for (const auto& [method, value] : last) EXPECT_EQ(value, 1.0) << method;
}

TEST(Figure2, SameSeedSameBytesAndVariationIsPositive) {
  ReproductionOptions o = quick_reproduction_options();
  o.fig2_sides = {9, 17};
  const FigureOutput a = figure2(o), b = figure2(o);
  EXPECT_EQ(a.rows, b.rows);
  EXPECT_EQ(render_svg(a.plot), render_svg(b.plot));
  o.seed = 2;
  EXPECT_NE(figure2(o).rows, a.rows);
  for (std::size_t r = 0; r < a.rows.size(); ++r) {
    EXPECT_GT(cell(a, r, "node_rms_variation"), 0.0);
    EXPECT_NEAR(cell(a, r, "links_removed_fraction"), 0.1, 0.05);
  }
}

TEST(SvgPlot, LogAxesSkipNonPositivePointsAndTheDocumentIsComplete) {
  LinePlot p;
  p.title = "a < b & c";
  p.log_x = p.log_y = true;
  p.series.push_back({"s", {0, 1, 10, 100}, {1, 0.1, 0.01, 0.001}, false, false});
  const std::string svg = render_svg(p);
  EXPECT_EQ(svg.rfind("<svg ", 0), 0u);
  EXPECT_EQ(svg.substr(svg.size() - 7), "</svg>\n");
  EXPECT_NE(svg.find("a &lt; b &amp; c"), std::string::npos);
  EXPECT_EQ(svg.find("nan"), std::string::npos);
  EXPECT_EQ(svg.find("inf"), std::string::npos);
  p.series[0].y = {0, 0, 0, 0};
  EXPECT_THROW(render_svg(p), pneuma::ValueError);
}
