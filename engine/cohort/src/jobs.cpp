#include "pneuma/cohort/jobs.h"

#include "pneuma/core/error.h"
#include "pneuma/model/compile.h"

namespace pneuma::cohort {

void compute_field(const Cohort& cohort, const std::string& subject, const std::string& scenario,
                   const std::filesystem::path& field_file) {
  const std::filesystem::path file = std::filesystem::absolute(field_file);
  const scenario::Scenario s = job_scenario(cohort, subject, scenario, file);
  // compile() with no frames does the surface, the field (through the cache at `file`, keyed as
  // every run of this subject will look it up) and the rest-shape checks, and nothing else.
  const physiology::SimulationResult no_frames;
  model::compile(s, no_frames, {file.parent_path(), cohort.edge_m});
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
