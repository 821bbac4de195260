#pragma once
// The paper's evaluation (section 5, figures 2, 6 - 8, Table 1) rebuilt from the comparators:
// each function runs one experiment and returns its data (a CSV table), a plot, and summary
// lines with the numbers that docs/paper-reproduction.md quotes. Everything is deterministic
// (fixed seeds, no timings in the data), so the same options give the same bytes.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/paper/svg_plot.h"

namespace pneuma::paper {

struct ReproductionOptions {
  // Figures 6 - 8: a side x side square lattice (odd, so one vertex sits at the centre), pushed
  // at that vertex with a unit force; figure 8 follows the vertex `probe_offset` columns right.
  std::uint32_t grid_side = 21;
  std::uint32_t probe_offset = 3;
  // Figure 2: lattices of these sides, uniform load (the lung's pressure), each against
  // `seeds` irregular versions with links removed with probability `link_removal`.
  std::vector<std::uint32_t> fig2_sides{5, 9, 17, 33, 65, 129};
  std::uint32_t seeds = 8;
  std::uint64_t seed = 1;
  double link_removal = 0.1;
  // Table 1: lattices of these sides (N = side^2 mass nodes), clique sizes 1 .. max_clique.
  std::vector<std::uint32_t> table1_sides{32, 100, 316, 1000};
  int max_clique = 4;
  double tolerance = 1e-6;  // every iterative method stops at max residual <= tolerance * max load
};
inline const ReproductionOptions default_reproduction_options{};
// Small sizes for tests and a quick look (a few seconds in all).
ReproductionOptions quick_reproduction_options();

struct FigureOutput {
  std::string name;                  // "fig6", ...: the files are <name>.csv and <name>.svg
  std::vector<std::string> columns;  // CSV header
  std::vector<std::vector<std::string>> rows;
  LinePlot plot;
  std::vector<std::string> summary;  // one finding per line, with numbers
};

FigureOutput figure2(const ReproductionOptions& options = default_reproduction_options);
FigureOutput figure6(const ReproductionOptions& options = default_reproduction_options);
FigureOutput figure7(const ReproductionOptions& options = default_reproduction_options);
FigureOutput figure8(const ReproductionOptions& options = default_reproduction_options);
FigureOutput table1(const ReproductionOptions& options = default_reproduction_options);

// "fig2", "fig6", "fig7", "fig8", "table1" (in this order).
const std::vector<std::string>& figure_names();
// Runs the named figure. Throws ValueError for an unknown name.
FigureOutput run_figure(const std::string& name, const ReproductionOptions& options = default_reproduction_options);

// Writes <dir>/<name>.csv and <dir>/<name>.svg atomically; returns their paths.
std::vector<std::filesystem::path> write_figure(const FigureOutput& figure, const std::filesystem::path& dir);

// Least-squares slope of log(y) against log(x) (the exponent of a power law y ~ x^slope).
// Throws ValueError unless there are two or more positive pairs with distinct x.
double log_log_slope(const std::vector<double>& x, const std::vector<double>& y);

}  // namespace pneuma::paper
