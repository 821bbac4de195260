// pneuma compare fig2|fig6|fig7|fig8|table1|all -o DIR: the paper's evaluation (section 5),
// rebuilt from the comparators; one CSV and one SVG per figure (docs/paper-reproduction.md).
#include <fmt/format.h>

#include <string>
#include <vector>

#include "commands.h"
#include "pneuma/core/error.h"
#include "pneuma/paper/paper_figures.h"

namespace pneuma::cli {
namespace {

struct CompareOptions {
  std::string what;
  std::string output = "paper-figures";
  bool quick = false;
  std::uint32_t grid_side = 0;  // 0: the preset's
  std::uint64_t seed = 1;
  bool quiet = false;
};

std::string expected_names() {
  std::string out;
  for (const auto& n : paper::figure_names()) out += n + ", ";
  return out + "or all";
}

void run_compare(const CompareOptions& o) {
  std::vector<std::string> names;
  if (o.what == "all") {
    names = paper::figure_names();
  } else {
    for (const auto& n : paper::figure_names()) {
      if (n == o.what) names.push_back(n);
    }
    if (names.empty())
      throw UsageError("pneuma: compare: unknown figure '" + o.what + "' (expected " + expected_names() + ")");
  }
  paper::ReproductionOptions options = o.quick ? paper::quick_reproduction_options() : paper::ReproductionOptions{};
  options.seed = o.seed;
  if (o.grid_side != 0) {
    if (o.grid_side < 3 || o.grid_side % 2 == 0)
      throw UsageError(fmt::format("pneuma: compare: --grid-side: expected an odd number >= 3, got {}", o.grid_side));
    options.grid_side = o.grid_side;
  }
  for (const auto& name : names) {
    const paper::FigureOutput figure = paper::run_figure(name, options);
    const auto paths = paper::write_figure(figure, o.output);
    if (o.quiet) continue;
    for (const auto& line : figure.summary) fmt::print("{}\n", line);
    fmt::print("wrote {} and {}\n", paths[0].string(), paths[1].string());
  }
}

}  // namespace

void register_compare(CLI::App& app) {
  auto options = std::make_shared<CompareOptions>();
  CLI::App* cmd = app.add_subcommand(
      "compare", "Reproduce the paper's evaluation: mass-spring and exponential comparators, figures 2, 6-8, Table 1");
  cmd->add_option("figure", options->what, "fig2, fig6, fig7, fig8, table1 or all")->required();
  cmd->add_option("-o,--output", options->output, "Folder for <figure>.csv and <figure>.svg")->capture_default_str();
  cmd->add_flag("--quick", options->quick, "Small sizes (seconds): grid 11x11, up to N = 4096 for Table 1");
  cmd->add_option("--grid-side", options->grid_side, "Side of the pushed grid of figures 6-8 (odd; default 21)");
  cmd->add_option("--seed", options->seed, "Seed of the irregular grids of figure 2")->capture_default_str();
  cmd->add_flag("-q,--quiet", options->quiet, "Print nothing on success");
  add_examples(*cmd, {"pneuma compare fig6 -o out/paper", "pneuma compare all --quick -o out/paper-quick"});
  cmd->callback([options] { run_compare(*options); });
}

}  // namespace pneuma::cli
