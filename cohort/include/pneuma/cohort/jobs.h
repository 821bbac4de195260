#pragma once
// The two kinds of cohort job, as the Snakefile runs them (`pneuma cohort-field`, `pneuma
// cohort-run`): each reads the cohort again and builds only its own scenario (cohort.h).
#include <filesystem>
#include <string>

#include "pneuma/cohort/cohort.h"
#include "pneuma/runner/runner.h"

namespace pneuma::cohort {

// The surface and field of `subject` for the field section of `scenario`, written to
// `field_file` (atomically) by the same compile step and cache key that the runs look it up
// with, so each run reuses it. A file already there with that key is kept. Throws the one-line
// pneuma::Error of whatever failed (a bad label map: InputError).
void compute_field(const Cohort& cohort, const std::string& subject, const std::string& scenario,
                   const std::filesystem::path& field_file);

// `pneuma run` of one subject and scenario into `output_dir` (staged: its files appear together,
// manifest.json last), its field read from `field_file`. Throws Error(failure) when the field
// there was not the one the run needs (it is then computed again, and the run would not share
// it): that is a bug, never silently accepted.
runner::RunResult run_job(const Cohort& cohort, const std::string& subject, const std::string& scenario,
                          const std::filesystem::path& field_file, const std::filesystem::path& output_dir);

}  // namespace pneuma::cohort
