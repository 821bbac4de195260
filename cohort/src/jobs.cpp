#include "pneuma/cohort/jobs.h"

#include "pneuma/core/error.h"
#include "pneuma/model/compile.h"

#include <vector>

namespace pneuma::cohort {

void compute_field(const Cohort& cohort, const std::string& subject, const std::string& scenario,
                   const std::filesystem::path& field_file) {
  const std::filesystem::path file = std::filesystem::absolute(field_file);
  const scenario::Scenario s = job_scenario(cohort, subject, scenario, file);
  // compile() makes the surface and the field (through the cache at `file`, keyed as every run
  // of this subject will look it up); the rest shape is checked as a run checks its frames.
  const model::Model model = model::compile(s, {.edge_override_m = cohort.edge_m});
  model::check_no_fold(model, std::vector<model::LungScales>(model.lungs.size()));
}

runner::RunResult run_job(const Cohort& cohort, const std::string& subject, const std::string& scenario,
                          const std::filesystem::path& field_file, const std::filesystem::path& output_dir) {
  const std::filesystem::path file = std::filesystem::absolute(field_file);
  if (!std::filesystem::exists(file))
    throw IoError(file.string() + ": no field file (the cohort's field job for subject '" + subject +
                  "' makes it first)");
  const scenario::Scenario s = job_scenario(cohort, subject, scenario, file);
  runner::RunOptions options;
  options.output_dir = output_dir;
  options.quiet = true;
  options.edge_override_m = cohort.edge_m;
  runner::RunResult result = runner::run_scenario(s, options);
  if (!result.field_reused) {
    throw Error(ExitCode::failure, file.string() + ": subject '" + subject + "', scenario '" + scenario +
                                       "': the field there was not the one this run needs, so it was computed "
                                       "again (a bug in the cohort's field variants)");
  }
  return result;
}

}  // namespace pneuma::cohort
