#pragma once
// Runs a cohort's plan with Snakemake (7.21, Debian's `snakemake`): writes the plan as the
// workflow's config (DIR/.cohort/plan.yaml) and the Snakefile built into pneuma
// (cohort/workflow/Snakefile, or one given) to DIR/.cohort/, then runs
//   snakemake --snakefile DIR/.cohort/Snakefile --directory DIR --configfile DIR/.cohort/plan.yaml
//             --keep-going --ignore-incomplete --nolock  (--cores N | --slurm --jobs N | --profile P)
// Snakemake decides which jobs are missing (a resumed cohort runs only those); pneuma holds an
// flock(2) on DIR/.cohort/lock instead of Snakemake's lock files, which the kernel releases when
// the holder dies, so a killed cohort never needs `--unlock`.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "pneuma/cohort/cohort.h"

namespace pneuma::cohort {

enum class Executor { local, slurm, profile };

struct WorkflowOptions {
  std::filesystem::path output_dir;
  Executor executor = Executor::local;
  int jobs = 0;                         // at most N jobs at once (local: N cores; 0: every core / 100 on Slurm)
  std::string profile;                  // Executor::profile: a Snakemake profile (folder or name)
  bool dry_run = false;                 // snakemake --dry-run: list the jobs that would run
  std::vector<std::string> extra_args;  // passed to snakemake as they are
  std::optional<std::filesystem::path> snakefile;  // instead of the built-in one
  std::filesystem::path pneuma;                    // the executable the jobs run (absolute)
  std::filesystem::path snakemake = "snakemake";   // looked up on PATH
};

// The Snakefile built into pneuma.
const std::string& builtin_snakefile();

// The plan as Snakemake config (YAML): the executable, the cohort file, resources, every field
// and run job with its inputs and digest (absolute paths).
std::string plan_yaml(const Cohort& cohort, const Plan& plan, const std::filesystem::path& pneuma);

// What the summary needs back from DIR/.cohort/plan.yaml.
struct PlanFile {
  std::string name;  // the cohort's
  std::filesystem::path cohort;
  Plan plan;
};
// Throws IoError when it cannot be read, InputError when it is not a plan.
PlanFile read_plan(const std::filesystem::path& output_dir);

// The snakemake command line (argv, the program first) for `options`.
std::vector<std::string> snakemake_command(const WorkflowOptions& options);

// What a Snakemake run ended with.
struct WorkflowResult {
  int status = 0;  // Snakemake's exit status (0: every job done; 128 + N when it died of signal N)
  // When status != 0: which job failed and why, or why Snakemake stopped before any job, in one
  // line (diagnose_snakemake); empty when it succeeded.
  std::string failure;
};
// Locks DIR, writes the plan and the Snakefile (atomically, only where they changed, so that
// Snakemake's code trigger does not fire for nothing), runs Snakemake with stdout inherited and
// stderr passed through (and kept, to say in one line why it failed). SIGINT and SIGTERM are
// passed on to Snakemake (which stops or cancels its jobs) and waited for. Throws IoError when
// DIR cannot be written or is in use by another cohort, and Error(unsupported) when snakemake
// cannot be started.
WorkflowResult run_workflow(const Cohort& cohort, const Plan& plan, const WorkflowOptions& options);
// Snakemake's stderr (`log`) to one line: the first failed job ("rule run (subject=a, scenario=b):
// " and the last line of its log file under `dir`, where pneuma's job wrote its one-line error),
// else the error Snakemake stopped with ("SyntaxError in file F, line 2: ..."), else its last line.
std::string diagnose_snakemake(const std::string& log, const std::filesystem::path& dir);

}  // namespace pneuma::cohort
