// The phantom-only build's (PNEUMA_PHANTOM_ONLY, make demo) `compare` and `cohort`: the paper's
// comparators and the cohort workflow are not compiled (cli/CMakeLists.txt), so each command
// only says so (core/not_built.h, exit 5), whatever its arguments.
#include "../commands.h"
#include "pneuma/core/not_built.h"

namespace pneuma::cli {
namespace {

void add_not_built(CLI::App& app, const std::string& name, const std::string& description) {
  CLI::App* cmd = app.add_subcommand(name, description + " (not built into this pneuma)");
  cmd->fallthrough(false);  // any arguments stay here: the answer is the same
  cmd->prefix_command();
  cmd->callback([name] { throw_not_built("pneuma " + name); });
}

}  // namespace

void register_compare(CLI::App& app) { add_not_built(app, "compare", "Reproduce the paper's evaluation"); }

void register_cohort(CLI::App& app) {
  add_not_built(app, "cohort", "Run every subject x scenario of a cohort through Snakemake");
}

}  // namespace pneuma::cli
