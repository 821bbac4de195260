// pneuma cohort --slurm against a real one-node Slurm (slurmctld, slurmd and munge from Debian)
// that scripts/start-slurm starts on localhost. Skipped, with the reason, where Slurm or munge is
// not installed or the test does not run as root (the daemons need it). The oracle: every job
// went through sbatch (Snakemake's Slurm log per job) and the results are the same bytes as the
// same cohort run locally.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>

#include "cohort_fixture.h"

namespace {

using namespace pneuma::test;
namespace fs = std::filesystem;

// Stops the test's Slurm (scripts/stop-slurm: by the pid files of what start-slurm started).
struct SlurmGuard {
  fs::path state;
  ~SlurmGuard() {
    ::setenv("PNEUMA_SLURM_DIR", state.c_str(), 1);
    run_program("/bin/bash", {(source_dir() / "scripts/stop-slurm").string()});
  }
};

TEST(CohortSlurm, RunsEveryJobThroughSlurmWithTheLocalResults) {
  for (const char* program : {"sbatch", "slurmctld", "slurmd", "munged", "snakemake"}) {
    if (find_program({program}).empty() && !fs::exists(fs::path("/usr/sbin") / program))
      GTEST_SKIP() << program << " is not installed (Debian: slurm-wlm munge snakemake; scripts/install-deps)";
  }
  if (::geteuid() != 0) GTEST_SKIP() << "not root: scripts/start-slurm runs slurmctld and slurmd as root";
  TempDir dir;
  // A state folder and ports of the test's own, so that it does not meet another Slurm here.
  const fs::path state = dir / "slurm";
  ::setenv("PNEUMA_SLURM_DIR", state.c_str(), 1);
  ::setenv("PNEUMA_SLURM_PORT", "6917", 1);
  SlurmGuard guard{state};
  const auto started = run_program("/bin/bash", {(source_dir() / "scripts/start-slurm").string()});
  ASSERT_EQ(started.exit_code, 0) << started.err;
  ASSERT_EQ(started.out, "export SLURM_CONF=" + (state / "slurm.conf").string() + "\n");
  ::setenv("SLURM_CONF", (state / "slurm.conf").c_str(), 1);
  // Started again: nothing changes (the same daemons, the same answer).
  const auto again = run_program("/bin/bash", {(source_dir() / "scripts/start-slurm").string()});
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(again.out, started.out);

  write_scenarios(dir);
  // Both phantom lungs (the CT path is the local tests'): the Slurm path in well under a minute.
  const std::vector<std::pair<std::string, std::string>> subjects = {{"right", kPhantom},
                                                                     {"left", "{mesh: {phantom: left}}"}};
  const fs::path cohort = write_cohort(dir, "slurm", subjects);
  const auto slurm = run_pneuma({"cohort", cohort.string(), "-o", (dir / "slurm-out").string(), "--slurm", "--jobs",
                                 "4", "--", "--max-status-checks-per-second", "1"});
  ASSERT_EQ(slurm.exit_code, 0) << slurm.out << slurm.err;
  const std::size_t runs = subjects.size() * 2;
  EXPECT_EQ(jobs_of_rule(slurm.out + slurm.err, "run"), static_cast<int>(runs));

  // Every field and run job went through sbatch: Snakemake's log of each Slurm job.
  std::size_t slurm_logs = 0;
  for (const char* rule : {"rule_field", "rule_run"}) {
    const fs::path logs = dir / "slurm-out/.snakemake/slurm_logs" / rule;
    if (fs::exists(logs)) slurm_logs += static_cast<std::size_t>(std::distance(fs::directory_iterator(logs), {}));
  }
  EXPECT_EQ(slurm_logs, subjects.size() + runs);

  const auto local = run_pneuma({"cohort", cohort.string(), "-o", (dir / "local-out").string(), "--jobs", "2"});
  ASSERT_EQ(local.exit_code, 0) << local.err;
  const auto rows = read_csv(dir / "slurm-out/cohort.csv");
  ASSERT_EQ(rows.size(), runs);
  for (const auto& row : rows) {
    EXPECT_EQ(row.at("status"), "ok") << row.at("subject") << "/" << row.at("scenario") << ": " << row.at("error");
    const fs::path run = fs::path("runs") / row.at("subject") / row.at("scenario");
    EXPECT_EQ(output_digests(dir / "slurm-out" / run), output_digests(dir / "local-out" / run)) << run;
  }
}

}  // namespace
