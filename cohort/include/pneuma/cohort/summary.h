#pragma once
// The cohort summary (docs/cohorts.md): DIR/cohort.csv, one row per subject and scenario, and
// DIR/cohort.html, the distributions across subjects (inline SVG, nothing fetched) with a link
// to each run's report.html. Read from what the jobs left: each run's manifest.json (facts and
// timings), physiology-breaths.csv and motion.csv, Snakemake's per-job benchmark files, and for
// a job that failed its log (the one-line error and the exit status the Snakefile appends).
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "pneuma/cohort/workflow.h"

namespace pneuma::cohort {

// `ok`: the run's manifest.json is there (its outputs complete); `failed`: the run's job failed;
// `field failed`: the subject's field job failed, so the run never started; `incomplete`: a job
// was started and stopped (killed) before it finished; `not run`: not started yet.
struct Row {
  std::string subject, scenario;
  std::string status;
  std::optional<int> exit_code;  // the job's (0 for ok; none when it did not finish)
  std::string error;             // the failed job's one-line error
  std::string log;               // the failed job's log, relative to DIR
  std::string report;            // runs/<subject>/<scenario>/report.html when written
  // The values, in summary_columns() order (empty when not known).
  std::vector<std::optional<double>> values;
};

// The numeric columns, in order, with their units in their names.
const std::vector<std::string>& summary_columns();

// The rows of every run of the plan in DIR, in plan order.
std::vector<Row> read_rows(const std::filesystem::path& output_dir, const Plan& plan);

// Writes DIR/cohort.csv and DIR/cohort.html, each atomically.
void write_summary(const std::filesystem::path& output_dir, const std::string& cohort_name,
                   const std::vector<Row>& rows);

}  // namespace pneuma::cohort
