#pragma once
// A cohort: subjects (each a lung surface: the phantom, a mesh file or a label map with its
// labels) times scenarios (scenario YAML files), run as one Snakemake workflow (docs/cohorts.md).
//
//   load_cohort    the cohort YAML read and checked, with every job's scenario (the subject's
//                  mesh in place of the scenario's) read as `pneuma run` would read it, so that
//                  every input error comes before any work, as one line: file:line:col: key: what
//   plan           the jobs: one field per subject and field variant (the tissue and solver
//                  options its scenarios ask for; usually one per subject), shared by the runs of
//                  that subject that ask for it; one run per subject and scenario
//   job_scenario   the scenario a job runs: the subject's mesh, the cohort's and subject's
//                  `field:` and the cohort's `outputs:` over the scenario file, the field cache
//                  set to the job's field file
//
// Nothing here runs Snakemake (workflow.h) or reads results (summary.h).
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "pneuma/scenario/scenario.h"

namespace pneuma::cohort {

// Folders and files inside a cohort's output folder DIR, relative to it (docs/cohorts.md).
inline constexpr const char* kStateDir = ".cohort";            // plan.yaml, Snakefile, lock
inline constexpr const char* kPlanFile = ".cohort/plan.yaml";  // the Snakemake config
inline constexpr const char* kSnakefile = ".cohort/Snakefile";

struct Subject {
  std::string id;                             // [A-Za-z0-9._-]+, unique
  std::vector<std::filesystem::path> inputs;  // the files its surface is made from (absolute)
};

struct ScenarioEntry {
  std::string id;              // [A-Za-z0-9._-]+, unique (the key under `scenarios:`)
  std::filesystem::path file;  // the cohort file's folder / the path given, normalised
};

// Per-job resources (for Slurm; threads also locally).
struct Resources {
  int threads = 1;        // threads of each job (pneuma --threads, Slurm --cpus-per-task)
  long memory_mb = 2048;  // Slurm --mem (a CT label map read takes up to about 700 MiB)
  long runtime_min = 60;  // Slurm -t
};

struct Cohort {
  std::filesystem::path file;  // the cohort YAML (absolute)
  std::string name;
  std::optional<double> edge_m;  // `edge`: every subject's surface at this edge (pneuma run --edge)
  Resources resources;
  std::vector<Subject> subjects;
  std::vector<ScenarioEntry> scenarios;
  std::string text;  // the file's text (the subjects' YAML is read again from it per job)
};

// One field job: the field of `subject` for the field section of `scenario` (the first of the
// subject's scenarios with this variant), shared by every run of the subject in `runs`.
struct FieldJob {
  std::string subject;
  std::string id;                             // the variant: the tissue's name, "-2", "-3", ... where names repeat
  std::string scenario;                       // the scenario whose field section it computes
  std::vector<std::filesystem::path> inputs;  // surface files and the tissue file
  std::string digest;                         // of everything that determines the field (Snakemake params)
  std::filesystem::path file() const { return std::filesystem::path("fields") / subject / (id + ".h5"); }
};

struct RunJob {
  std::string subject;
  std::string scenario;
  std::string field;                          // FieldJob::id
  std::vector<std::filesystem::path> inputs;  // the scenario file
  std::string digest;                         // of everything that determines the run (Snakemake params)
  std::filesystem::path dir() const { return std::filesystem::path("runs") / subject / scenario; }
};

struct Plan {
  std::vector<FieldJob> fields;  // subject by subject, in cohort order
  std::vector<RunJob> runs;      // subject by subject, scenarios in cohort order
};

// Reads and checks `file` (structure, ids, files present). Does not read the scenarios yet.
// Throws InputError / IoError with one line.
Cohort load_cohort(const std::filesystem::path& file);

// Every job's scenario read and checked (the subject's mesh, the cohort's field and outputs),
// and the jobs they make. Throws the first job's one-line error.
Plan plan(const Cohort& cohort);

// The scenario of subject `subject` and scenario `scenario` with its field cached in
// `field_file` (absolute). Throws InputError for an unknown id, and as runner::read_scenario.
scenario::Scenario job_scenario(const Cohort& cohort, const std::string& subject, const std::string& scenario,
                                const std::filesystem::path& field_file);

}  // namespace pneuma::cohort
