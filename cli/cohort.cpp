// pneuma cohort COHORT.yaml -o DIR: subjects x scenarios through Snakemake, locally or on Slurm;
// and the three steps its workflow runs (cohort-field, cohort-run, cohort-summary). Thin: the
// work is in cohort/ (docs/cohorts.md).
#include <fmt/format.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "commands.h"
#include "pneuma/cohort/cohort.h"
#include "pneuma/cohort/jobs.h"
#include "pneuma/cohort/summary.h"
#include "pneuma/cohort/workflow.h"
#include "pneuma/core/error.h"
#include "pneuma/core/text.h"

namespace pneuma::cli {
namespace {

struct CohortCommandOptions {
  std::string cohort;
  std::string output = "out/cohort";
  int jobs = 0;
  bool slurm = false;
  std::string profile;
  bool dry_run = false;
  std::string snakefile;
  std::vector<std::string> snakemake_args;
};

struct JobOptions {
  std::string cohort, subject, scenario, field, output;
};

// This executable, for the jobs to run (the same build everywhere in the cohort).
std::filesystem::path this_executable() {
  std::array<char, 4096> buffer{};
  const ssize_t n = ::readlink("/proc/self/exe", buffer.data(), buffer.size() - 1);
  if (n <= 0) throw IoError("pneuma: cohort: cannot find this executable (/proc/self/exe)");
  return std::filesystem::path(std::string(buffer.data(), static_cast<std::size_t>(n)));
}

void run_cohort(const CohortCommandOptions& o) {
  if (o.slurm && !o.profile.empty()) throw UsageError("pneuma: cohort: give --slurm or --profile, not both");
  const cohort::Cohort c = cohort::load_cohort(o.cohort);
  const cohort::Plan plan = cohort::plan(c);
  fmt::print("cohort {}: {} subjects x {} scenarios: {} field jobs, {} runs, into {}/\n", c.name, c.subjects.size(),
             c.scenarios.size(), plan.fields.size(), plan.runs.size(), o.output);
  std::fflush(stdout);
  cohort::WorkflowOptions w;
  w.output_dir = o.output;
  w.executor =
      o.slurm ? cohort::Executor::slurm : (o.profile.empty() ? cohort::Executor::local : cohort::Executor::profile);
  w.jobs = o.jobs;
  w.profile = o.profile;
  w.dry_run = o.dry_run;
  w.extra_args = o.snakemake_args;
  if (!o.snakefile.empty()) w.snakefile = o.snakefile;
  w.pneuma = this_executable();
  const cohort::WorkflowResult result = cohort::run_workflow(c, plan, w);
  const int status = result.status;
  if (o.dry_run) {
    if (status != 0)
      throw Error(ExitCode::failure, fmt::format("pneuma: cohort: snakemake --dry-run failed (exit {}): {}", status,
                                                 quote_bytes(result.failure)));
    return;
  }
  // Stopped before any job (a workflow Snakemake refuses): its reason, not a line per run.
  if (status != 0 && status <= 128 && !std::filesystem::exists(std::filesystem::path(o.output) / "logs"))
    throw Error(ExitCode::failure, fmt::format("pneuma: cohort: snakemake stopped before any job (exit {}): {}", status,
                                               quote_bytes(result.failure)));
  const std::vector<cohort::Row> rows = cohort::read_rows(o.output, plan);
  std::size_t done = 0;
  for (const cohort::Row& r : rows) {
    if (r.status == "ok") {
      ++done;
      continue;
    }
    std::fprintf(stderr, "pneuma: cohort: %s/%s: %s%s%s\n", r.subject.c_str(), r.scenario.c_str(), r.status.c_str(),
                 r.exit_code ? fmt::format(" (exit {})", *r.exit_code).c_str() : "",
                 r.error.empty() ? "" : (": " + r.error).c_str());
  }
  fmt::print("{} of {} runs complete; summary: {}/cohort.csv, {}/cohort.html\n", done, rows.size(), o.output, o.output);
  std::fflush(stdout);
  // Stopped by a signal: the status a shell reports (the workflow passed the signal on and waited).
  if (status > 128) std::exit(status);
  if (done != rows.size() || status != 0) {
    throw Error(ExitCode::failure,
                fmt::format("pneuma: cohort: {} of {} runs did not complete (snakemake exit {}{}); run the same "
                            "command again to run only those",
                            rows.size() - done, rows.size(), status,
                            result.failure.empty() ? "" : ": first " + quote_bytes(result.failure)));
  }
}

void add_job_options(CLI::App& cmd, JobOptions& o) {
  cmd.add_option("cohort", o.cohort, "Cohort YAML file")->required();
  cmd.add_option("--subject", o.subject, "Subject id")->required();
  cmd.add_option("--scenario", o.scenario, "Scenario id")->required();
}

}  // namespace

void register_cohort(CLI::App& app) {
  auto options = std::make_shared<CohortCommandOptions>();
  CLI::App* cmd = app.add_subcommand(
      "cohort", "Run every subject x scenario of a cohort through Snakemake, locally or on Slurm (docs/cohorts.md)");
  cmd->add_option("cohort", options->cohort, "Cohort YAML file")->required()->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", options->output, "Output folder")->capture_default_str();
  cmd->add_option("-j,--jobs", options->jobs, "At most N jobs at once (default: every core; 100 with --slurm)")
      ->option_text("N")
      ->check(CLI::Range(1, 100000));
  cmd->add_flag("--slurm", options->slurm, "Submit each job to Slurm (Snakemake's --slurm executor)");
  cmd->add_option("--profile", options->profile, "Run with this Snakemake profile (a folder or a name)");
  cmd->add_flag("-n,--dry-run", options->dry_run, "Check the cohort and list the jobs that would run; run nothing");
  cmd->add_option("--snakefile", options->snakefile, "A Snakefile instead of the one built into pneuma")
      ->check(CLI::ExistingFile);
  cmd->add_option("snakemake_args", options->snakemake_args, "After --: arguments passed to snakemake as they are");
  add_examples(*cmd, {"pneuma cohort cohorts/example.yaml -o out/cohort",
                      "pneuma cohort cohorts/example.yaml -o out/cohort --dry-run",
                      "pneuma cohort cohorts/example.yaml -o out/cohort --slurm --jobs 50 -- --default-resources "
                      "slurm_partition=compute"});
  cmd->callback([options] { run_cohort(*options); });

  auto field = std::make_shared<JobOptions>();
  CLI::App* field_cmd =
      app.add_subcommand("cohort-field", "A cohort's field job: one subject's surface and field (run by the workflow)");
  add_job_options(*field_cmd, *field);
  field_cmd->add_option("-o,--output", field->output, "Field file to write (HDF5)")->required();
  field_cmd->callback([field] {
    cohort::compute_field(cohort::load_cohort(field->cohort), field->subject, field->scenario, field->output);
  });

  auto run = std::make_shared<JobOptions>();
  CLI::App* run_cmd =
      app.add_subcommand("cohort-run", "A cohort's run job: one subject and scenario (run by the workflow)");
  add_job_options(*run_cmd, *run);
  run_cmd->add_option("--field", run->field, "The subject's field file (from cohort-field)")->required();
  run_cmd->add_option("-o,--output", run->output, "Output folder")->required();
  run_cmd->callback([run] {
    cohort::run_job(cohort::load_cohort(run->cohort), run->subject, run->scenario, run->field, run->output);
  });

  auto summary_dir = std::make_shared<std::string>();
  CLI::App* summary_cmd = app.add_subcommand(
      "cohort-summary", "Write a cohort's cohort.csv and cohort.html from what its jobs left (run by the workflow)");
  summary_cmd->add_option("dir", *summary_dir, "The cohort's output folder")->required();
  summary_cmd->callback([summary_dir] {
    const cohort::PlanFile plan = cohort::read_plan(*summary_dir);
    const auto rows = cohort::read_rows(*summary_dir, plan.plan);
    cohort::write_summary(*summary_dir, plan.name, rows);
    std::size_t done = 0;
    for (const auto& r : rows) done += r.status == "ok";
    fmt::print("pneuma cohort-summary: {} of {} runs complete: {}/cohort.csv, {}/cohort.html\n", done, rows.size(),
               *summary_dir, *summary_dir);
  });
  for (CLI::App* step : {field_cmd, run_cmd, summary_cmd})
    step->group("Cohort steps (run by pneuma cohort's workflow)");
}

}  // namespace pneuma::cli
