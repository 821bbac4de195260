// pneuma cohort, locally through Snakemake 7.21: the phantom and two real CT cases (case006 and
// case009 of ../shared/data/ct-lobes, CC BY 4.0) at an 8 mm edge, two short scenarios. Oracles:
// the row count (subjects x scenarios), each row's numbers against the run's own manifest and
// CSVs read here, one field file per subject reused by both its runs, which manifests a rerun
// rewrites (their times) against the jobs Snakemake says it ran, the bytes of a killed and resumed
// cohort against an uninterrupted one, and a bad label map's one-line error against the one
// `pneuma mesh from-labels` gives for the same file.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <thread>

#include "cohort_fixture.h"
#include "pneuma/cohort/cohort.h"
#include "pneuma/cohort/summary.h"
#include "pneuma/cohort/workflow.h"
#include "pneuma/core/markup.h"
#include "pneuma/core/staged_output.h"

namespace {

using namespace pneuma::test;
namespace fs = std::filesystem;

bool have_snakemake() { return !find_program({"snakemake"}).empty(); }

#define SKIP_WITHOUT_SNAKEMAKE()                                                              \
  do {                                                                                        \
    if (!have_snakemake()) {                                                                  \
      GTEST_SKIP() << "snakemake is not installed (Debian: snakemake; scripts/install-deps)"; \
    }                                                                                         \
  } while (false)
#define SKIP_WITHOUT_CT()                                                             \
  do {                                                                                \
    if (!fs::exists(ct_lobes_dir() / "case006_lobes.nii.gz")) {                       \
      GTEST_SKIP() << "no CT lobe maps at " << ct_lobes_dir()                         \
                   << " (set PNEUMA_CT_LOBES to the folder of case00N_lobes.nii.gz)"; \
    }                                                                                 \
  } while (false)

double number(const std::string& text) { return std::stod(text); }
double number(const nlohmann::json& text) { return std::stod(text.get<std::string>()); }

// The mean of a CSV column over the rows `keep` accepts.
double csv_mean(const fs::path& file, const std::string& column,
                const std::function<bool(const std::map<std::string, std::string>&)>& keep = nullptr) {
  double sum = 0.0;
  int n = 0;
  for (const auto& row : read_csv(file)) {
    if (keep && !keep(row)) continue;
    sum += number(row.at(column));
    ++n;
  }
  return n ? sum / n : NAN;
}

// ---- Checks before any work: one line naming the file, the key and what was expected ----

TEST(CohortInput, EveryProblemIsOneLineBeforeAnyWork) {
  TempDir dir;
  write_scenarios(dir);
  struct Case {
    std::string cohort;    // the file's text
    std::string expected;  // the stderr line, "<file>" standing for the cohort file
  };
  const std::string scenarios = "scenarios: {quiet: scenarios/quiet.yaml}\n";
  const Case cases[] = {
      {"edge: 8\nsubjects: {a: {mesh: {phantom: right}}}\n" + scenarios,
       "<file>:1:7: edge: expected a length such as '3 mm', got '8'"},
      {"subjects: {a: {mesh: {labels: missing.nii.gz, values: [3]}}}\n" + scenarios,
       "<file>:1:31: mesh.labels: no such file: <dir>/missing.nii.gz"},
      {"subjects: {a: {mesh: {phantom: right}, tissue: x}}\n" + scenarios,
       "<file>:1:40: subjects.a.tissue: unknown key; expected one of: field, mesh"},
      {"subjects: {a/b: {mesh: {phantom: right}}}\n" + scenarios,
       "<file>:1:17: subjects.a/b: expected a subject id of letters, digits, '.', '_' and '-' (a folder name), got "
       "'a/b'"},
      // Snakemake 7.21 refuses a wildcard ending in one piece repeated 20 times (19 pass, tested below).
      {"subjects: {xaaaaaaaaaaaaaaaaaaaa: {mesh: {phantom: right}}}\n" + scenarios,
       "<file>:1:35: subjects.xaaaaaaaaaaaaaaaaaaaa: expected a subject id that does not end in one piece repeated 20 "
       "times or more (Snakemake stops the cohort for it), got 'xaaaaaaaaaaaaaaaaaaaa'"},
      {"subjects: {a: {mesh: {phantom: right}}}\nscenarios: {q-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab: "
       "scenarios/quiet.yaml}\n",
       "<file>:2:76: scenarios.q-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab: expected a scenario id that "
       "does not end in one piece repeated 20 times or more (Snakemake stops the cohort for it), got "
       "'q-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab-ab'"},
      {"subjects: {a: {mesh: {phantom: right}}}\nscenarios: {quiet: scenarios/none.yaml}\n",
       "<file>:2:20: scenarios.quiet: no such scenario file: <dir>/scenarios/none.yaml"},
      {"subjects: {a: {mesh: {phantom: middle}}}\n" + scenarios,
       "<file>:1:32: mesh.phantom: expected one of: left, right, both; got 'middle'"},
      {"subjects: {a: {mesh: {phantom: right}}}\noutputs: {png: {width: 10 mm}}\n" + scenarios,
       ""},  // any one line naming the cohort file: the png output's own check
  };
  for (const Case& c : cases) {
    const fs::path file = dir.write("bad.yaml", c.cohort);
    const fs::path out = dir / "out";
    const auto r = run_pneuma({"cohort", file.string(), "-o", out.string()});
    EXPECT_EQ(r.exit_code, 3) << c.cohort << r.err;
    std::string expected = c.expected;
    for (const auto& [from, to] : {std::pair<std::string, std::string>{"<file>", file.string()},
                                   std::pair<std::string, std::string>{"<dir>", dir.path().string()}}) {
      for (auto at = expected.find(from); at != std::string::npos; at = expected.find(from))
        expected.replace(at, from.size(), to);
    }
    if (!expected.empty()) {
      EXPECT_EQ(r.err, expected + "\n") << c.cohort;
    }
    EXPECT_EQ(r.err.rfind(file.string() + ":", 0), 0u) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(out)) << "nothing is written for a cohort that does not load: " << c.cohort;
  }
}

// The id rule against Snakemake itself: each id, as a wildcard of a one-rule workflow, passes
// `snakemake --dry-run` exactly when the cohort loader accepts it as a subject id.
TEST(CohortInput, AnIdIsRefusedExactlyWhenSnakemakeWouldStopForIt) {
  SKIP_WITHOUT_SNAKEMAKE();
  TempDir dir;
  write_scenarios(dir);
  dir.write("Snakefile", "rule all:\n    input: f\"out/{config['id']}.txt\"\n"
                         "rule one:\n    output: \"out/{id}.txt\"\n    shell: \"touch {output}\"\n");
  const std::string a19(19, 'a'), a20(20, 'a');
  std::string ab19 = "q", ab20;
  for (int i = 0; i < 19; ++i) ab19 += "-ab";
  ab20 = ab19 + "-ab";
  for (const std::string& id : {"x" + a19, "x" + a20, a20 + "b", a20 + a20, ab19, ab20, std::string("case004")}) {
    const auto snakemake =
        run_program(find_program({"snakemake"}), {"--dry-run", "--quiet", "--snakefile", (dir / "Snakefile").string(),
                                                  "--directory", dir.path().string(), "--config", "id=" + id});
    bool loads = true;
    try {
      pneuma::cohort::load_cohort(dir.write(
          "ids.yaml", "subjects: {" + id + ": {mesh: {phantom: right}}}\nscenarios: {quiet: scenarios/quiet.yaml}\n"));
    } catch (const pneuma::InputError&) {
      loads = false;
    }
    EXPECT_EQ(loads, snakemake.exit_code == 0) << id << ": " << snakemake.err;
  }
}

// cohort.html names every dot: each circle carries a <title> with its subject, scenario and value,
// and a class whose colour the legend gives its subject; the tables scroll in their own box.
// Oracle: the rows handed in (every value of every row is one dot of its metric's plot).
TEST(CohortSummary, EveryDotIsNamedAndTheTableScrollsInItsBox) {
  TempDir dir;
  const std::vector<std::string> subjects = {"case006", "case<9>", "phantom"};
  std::vector<pneuma::cohort::Row> rows;
  const std::size_t columns = pneuma::cohort::summary_columns().size();
  for (std::size_t i = 0; i < subjects.size(); ++i) {
    for (const std::string scenario : {"quiet", "deep"}) {
      pneuma::cohort::Row r{subjects[i], scenario, "ok", 0, "", "", "", {}};
      r.values.reserve(columns);
      for (std::size_t c = 0; c < columns; ++c) r.values.emplace_back(100.0 * static_cast<double>(i) + 1.5);
      rows.push_back(std::move(r));
    }
  }
  pneuma::cohort::write_summary(dir.path(), "dots", rows);
  const std::string html = read_text(dir / "cohort.html");
  const auto count = [&](const std::string& what) {
    std::size_t n = 0;
    for (auto at = html.find(what); at != std::string::npos; at = html.find(what, at + 1)) ++n;
    return n;
  };
  std::size_t plots = count("<svg");
  ASSERT_GE(plots, 8u);
  EXPECT_EQ(count("<circle"), plots * rows.size());
  EXPECT_EQ(count("<title>"), 1 + plots * rows.size());  // the page's own title, then one per dot
  for (std::size_t i = 0; i < subjects.size(); ++i) {
    const std::string name = pneuma::escape_markup(subjects[i]);
    // Its dots in each scenario (every value of a row is the same), in its colour, and its legend entry.
    for (const std::string scenario : {"quiet", "deep"}) {
      EXPECT_NE(html.find(fmt::format("class=\"point s{}\"><title>{} ({}): {}</title>", i, name, scenario,
                                      100.0 * static_cast<double>(i) + 1.5)),
                std::string::npos)
          << name << " " << scenario;
    }
    EXPECT_NE(html.find(fmt::format("<span class=\"dot s{}\"></span>{}</span>", i, name)), std::string::npos) << name;
  }
  EXPECT_NE(html.find("<div class=\"scroll\"><table>"), std::string::npos);
  EXPECT_NE(html.find(".scroll{overflow-x:auto"), std::string::npos);
}

// The plan: one field per subject and tissue, shared by the scenarios that ask for it.
TEST(CohortPlan, OneFieldPerSubjectAndTissueSharedByItsScenarios) {
  TempDir dir;
  write_scenarios(dir);
  dir.write("scenarios/supine.yaml",
            "duration: 4 s\nfield: {tissue: healthy-supine}\nphysiology: {preset: healthy-adult}\n");
  const fs::path file =
      write_cohort(dir, "plan", {{"a", kPhantom}, {"b", "{mesh: {phantom: left}, field: {tissue: healthy-supine}}"}},
                   "{quiet: scenarios/quiet.yaml, deep: scenarios/deep.yaml, supine: scenarios/supine.yaml}");
  const pneuma::cohort::Plan plan = pneuma::cohort::plan(pneuma::cohort::load_cohort(file));
  ASSERT_EQ(plan.runs.size(), 6u);
  // a: quiet and deep share healthy-upright, supine has its own; b: one tissue for all three.
  ASSERT_EQ(plan.fields.size(), 3u);
  EXPECT_EQ(plan.fields[0].subject + "/" + plan.fields[0].id, "a/healthy-upright");
  EXPECT_EQ(plan.fields[1].subject + "/" + plan.fields[1].id, "a/healthy-supine");
  EXPECT_EQ(plan.fields[2].subject + "/" + plan.fields[2].id, "b/healthy-supine");
  const std::vector<std::string> fields = {"healthy-upright", "healthy-upright", "healthy-supine",
                                           "healthy-supine",  "healthy-supine",  "healthy-supine"};
  for (std::size_t i = 0; i < plan.runs.size(); ++i) EXPECT_EQ(plan.runs[i].field, fields[i]) << i;
  // The job's scenario: the subject's mesh in place of the scenario's, the cache the field job's.
  const auto s = pneuma::cohort::job_scenario(pneuma::cohort::load_cohort(file), "b", "quiet", dir / "f.h5");
  EXPECT_EQ(s.mesh.phantom, pneuma::mesh::Lung::left);
  EXPECT_DOUBLE_EQ(s.mesh.share, 0.45);  // the left phantom's default, not the scenario's mesh
  EXPECT_EQ(s.field.tissue.name, "healthy-supine");
  EXPECT_EQ(s.field.cache_file, dir / "f.h5");
}

// ---- The local path, end to end ----

// Runs the cohort in `out` with 2 jobs at once; the result of the command.
CommandResult run_cohort(const fs::path& cohort, const fs::path& out, const std::vector<std::string>& extra = {}) {
  std::vector<std::string> args = {"cohort", cohort.string(), "-o", out.string(), "--jobs", "2"};
  args.insert(args.end(), extra.begin(), extra.end());
  return run_pneuma(args);
}

// The manifests of finished runs. A run writes its manifest into its stage folder first and
// moves it out last, so one found inside a stage belongs to a run still going (or killed).
std::vector<fs::path> manifests(const fs::path& out) {
  std::vector<fs::path> found;
  if (!fs::exists(out / "runs")) return found;
  // Error codes, not exceptions: the cohort may move or remove a stage while this walks.
  std::error_code error;
  for (auto e = fs::recursive_directory_iterator(out / "runs", error);
       !error && e != fs::recursive_directory_iterator(); e.increment(error)) {
    if (e->path().filename().string().rfind(pneuma::kStagePrefix, 0) == 0) {
      e.disable_recursion_pending();
    } else if (e->path().filename() == "manifest.json") {
      found.push_back(e->path());
    }
  }
  std::sort(found.begin(), found.end());
  return found;
}

TEST(CohortLocal, PhantomAndTwoCtCasesRunOnceResumeAndRerunOnlyWhatIsMissing) {
  SKIP_WITHOUT_SNAKEMAKE();
  SKIP_WITHOUT_CT();
  TempDir dir;
  write_scenarios(dir);
  const fs::path cohort = write_cohort(
      dir, "three", {{"phantom", kPhantom}, {"case006", ct_subject("case006")}, {"case009", ct_subject("case009")}});
  const std::vector<std::string> subjects = {"phantom", "case006", "case009"}, scenarios = {"quiet", "deep"};

  // 1. A cohort killed midway (the whole process group, SIGKILL: a crash), then resumed.
  const fs::path resumed = dir / "resumed";
  std::size_t done_before_kill = 0;
  {
    BackgroundCohort background({"cohort", cohort.string(), "-o", resumed.string(), "--jobs", "2"}, dir / "killed.log");
    ASSERT_TRUE(background.started());
    ASSERT_TRUE(wait_until([&] { return manifests(resumed).size() >= 2; }, 300000)) << read_text(dir / "killed.log");
    background.kill_group(SIGKILL);
    done_before_kill = manifests(resumed).size();
  }
  ASSERT_LT(done_before_kill, 6u) << "the cohort ended before it could be killed";
  std::map<fs::path, long long> times_before;
  for (const auto& m : manifests(resumed)) times_before[m] = write_time_ns(m);
  const auto resume = run_cohort(cohort, resumed);
  ASSERT_EQ(resume.exit_code, 0) << resume.out << resume.err;
  EXPECT_EQ(jobs_of_rule(resume.out + resume.err, "run"), static_cast<int>(6 - done_before_kill))
      << resume.out << resume.err;
  for (const auto& [m, t] : times_before) EXPECT_EQ(write_time_ns(m), t) << m << " ran again";
  ASSERT_EQ(manifests(resumed).size(), 6u);

  // 2. The same cohort uninterrupted.
  const fs::path out = dir / "out";
  const auto r = run_cohort(cohort, out);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_EQ(jobs_of_rule(r.out + r.err, "field"), 3) << "one field job per subject";
  EXPECT_EQ(jobs_of_rule(r.out + r.err, "run"), 6);

  // The resumed cohort's results are the same bytes (manifest timings aside).
  for (const auto& subject : subjects) {
    for (const auto& scenario : scenarios) {
      const fs::path run = fs::path("runs") / subject / scenario;
      const auto digests = output_digests(out / run);
      EXPECT_GE(digests.size(), 4u) << run;  // physiology CSVs, motion.csv, report.html
      EXPECT_EQ(output_digests(resumed / run), digests) << run;
    }
  }
  for (const auto& e : fs::recursive_directory_iterator(out / "fields")) {
    if (e.is_regular_file()) {
      EXPECT_EQ(read_text(e.path()), read_text(resumed / fs::relative(e.path(), out))) << e.path();
    }
  }

  // One field file per subject, and both its runs reused it (their surfaces are the same).
  for (const auto& subject : subjects) {
    std::vector<fs::path> fields;
    for (const auto& e : fs::directory_iterator(out / "fields" / subject)) fields.push_back(e.path().filename());
    EXPECT_EQ(fields, std::vector<fs::path>{"healthy-upright.h5"}) << subject;
    for (const auto& scenario : scenarios) {
      const auto facts = read_manifest(out / "runs" / subject / scenario).at("facts");
      EXPECT_EQ(facts.at("field"), "reused from cache") << subject << "/" << scenario;
    }
    EXPECT_EQ(read_manifest(out / "runs" / subject / "quiet").at("facts").at("vertices"),
              read_manifest(out / "runs" / subject / "deep").at("facts").at("vertices"));
  }

  // cohort.csv: one row per subject and scenario, each number the run's own.
  const auto rows = read_csv(out / "cohort.csv");
  ASSERT_EQ(rows.size(), subjects.size() * scenarios.size());
  std::size_t i = 0;
  for (const auto& subject : subjects) {
    for (const auto& scenario : scenarios) {
      const auto& row = rows[i++];
      const fs::path run = out / "runs" / subject / scenario;
      EXPECT_EQ(row.at("subject"), subject);
      EXPECT_EQ(row.at("scenario"), scenario);
      EXPECT_EQ(row.at("status"), "ok");
      EXPECT_EQ(row.at("exit_code"), "0");
      const auto manifest = read_manifest(run);
      const auto& facts = manifest.at("facts");
      EXPECT_NEAR(number(row.at("rest_volume_mL")), number(facts.at("rest_volume_m3")) * 1e6, 1e-6);
      EXPECT_EQ(number(row.at("vertices")), number(facts.at("vertices")));
      EXPECT_EQ(number(row.at("dome_top_caudal_mm")), number(facts.at("motion.dome_top_caudal_mm")));
      EXPECT_EQ(number(row.at("diaphragmatic_caudal_mean_mm")),
                number(facts.at("motion.diaphragmatic.caudal_mean_mm")));
      EXPECT_NEAR(number(row.at("tidal_volume_mL")), csv_mean(run / "physiology-breaths.csv", "tidal_volume_mL"), 1e-6);
      EXPECT_NEAR(number(row.at("mesh_volume_change_mL")),
                  csv_mean(run / "motion.csv", "breath_volume_change_mL",
                           [](const auto& csv_row) { return csv_row.at("region") == "apex"; }),
                  1e-6);
      double compute = 0.0;
      for (const auto& [stage, seconds] : manifest.at("timings_s").items()) compute += seconds.template get<double>();
      EXPECT_NEAR(number(row.at("run_compute_s")), compute, 1e-6 * std::max(1.0, compute));
      EXPECT_GT(number(row.at("run_wall_s")), 0.0);
      EXPECT_GT(number(row.at("field_wall_s")), 0.0);
      EXPECT_EQ(row.at("report"), fmt::format("runs/{}/{}/report.html", subject, scenario));
      EXPECT_TRUE(fs::exists(out / row.at("report")));
    }
  }
  // The deep breath moves the diaphragm more than quiet breathing, on every subject.
  for (std::size_t s = 0; s < subjects.size(); ++s) {
    EXPECT_GT(number(rows[2 * s + 1].at("tidal_volume_mL")), number(rows[2 * s].at("tidal_volume_mL")) + 200);
    EXPECT_GT(number(rows[2 * s + 1].at("diaphragmatic_caudal_mean_mm")),
              number(rows[2 * s].at("diaphragmatic_caudal_mean_mm")));
  }

  // cohort.html: self-contained (nothing fetched), a plot per metric, a link to every report.
  const std::string html = read_text(out / "cohort.html");
  EXPECT_EQ(html.find("src=\"http"), std::string::npos);
  EXPECT_EQ(html.find("<script"), std::string::npos);
  EXPECT_GE(std::count(html.begin(), html.end(), '\n'), 10);
  std::size_t svgs = 0;
  for (auto at = html.find("<svg"); at != std::string::npos; at = html.find("<svg", at + 1)) ++svgs;
  EXPECT_GE(svgs, 8u);
  for (const auto& row : rows) EXPECT_NE(html.find("href=\"" + row.at("report") + "\""), std::string::npos);

  // 3. Nothing missing: nothing runs.
  std::map<fs::path, long long> times;
  for (const auto& m : manifests(out)) times[m] = write_time_ns(m);
  const auto again = run_cohort(cohort, out);
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(jobs_of_rule(again.out + again.err, "run"), 0) << again.out;
  for (const auto& [m, t] : times) EXPECT_EQ(write_time_ns(m), t) << m;

  // 4. One run's output deleted: exactly that run again.
  fs::remove(out / "runs/case009/deep/manifest.json");
  const auto one = run_cohort(cohort, out);
  ASSERT_EQ(one.exit_code, 0) << one.err;
  EXPECT_EQ(jobs_of_rule(one.out + one.err, "run"), 1) << one.out;
  EXPECT_EQ(jobs_of_rule(one.out + one.err, "field"), 0) << one.out;
  for (const auto& [m, t] : times) {
    if (m != out / "runs/case009/deep/manifest.json") {
      EXPECT_EQ(write_time_ns(m), t) << m;
    }
  }
  EXPECT_EQ(output_digests(out / "runs/case009/deep"), output_digests(resumed / "runs/case009/deep"));
}

// A subject whose label map is damaged fails with its one-line error; the others complete.
TEST(CohortLocal, BadLabelMapFailsThatSubjectOnlyWithItsOneLineError) {
  SKIP_WITHOUT_SNAKEMAKE();
  SKIP_WITHOUT_CT();
  TempDir dir;
  write_scenarios(dir);
  // The first 64 kB of a real label map: a truncated .nii.gz.
  const std::string bytes = read_text(ct_lobes_dir() / "case006_lobes.nii.gz");
  const fs::path bad = dir.write("truncated_lobes.nii.gz", bytes.substr(0, 65536));
  const fs::path cohort = write_cohort(
      dir, "bad", {{"phantom", kPhantom}, {"broken", "{mesh: {labels: " + bad.string() + ", values: [3, 4, 5]}}"}},
      "{quiet: scenarios/quiet.yaml}");
  const fs::path out = dir / "out";
  const auto r = run_cohort(cohort, out);
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;

  // The oracle: what pneuma says of that file on its own.
  const auto direct =
      run_pneuma({"mesh", "from-labels", bad.string(), "--labels", "3,4,5", "-o", (dir / "x.stl").string()});
  ASSERT_EQ(direct.exit_code, 3);
  const std::string error_line = direct.err.substr(0, direct.err.find('\n'));
  ASSERT_FALSE(error_line.empty());

  const auto rows = read_csv(out / "cohort.csv");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].at("status"), "ok");
  EXPECT_TRUE(fs::exists(out / "runs/phantom/quiet/report.html"));
  EXPECT_EQ(rows[1].at("subject"), "broken");
  EXPECT_EQ(rows[1].at("status"), "field failed");
  EXPECT_EQ(rows[1].at("exit_code"), "3");
  EXPECT_EQ(rows[1].at("error"), error_line);
  EXPECT_EQ(rows[1].at("log"), "logs/fields/broken/healthy-upright.log");
  EXPECT_FALSE(fs::exists(out / "runs/broken/quiet"));
  EXPECT_NE(r.err.find("pneuma: cohort: broken/quiet: field failed (exit 3): " + error_line + "\n"), std::string::npos)
      << r.err;
  // The last line names the first failed job, its wildcards and why (its log's last line).
  const std::string last = last_line(r.err);
  EXPECT_NE(last.find("rule field (subject=broken"), std::string::npos) << last;
  EXPECT_NE(last.find("failed (exit 3): " + error_line), std::string::npos) << last;
  EXPECT_NE(last.find("(log: logs/fields/broken/healthy-upright.log)"), std::string::npos) << last;
  const std::string html = read_text(out / "cohort.html");
  EXPECT_NE(html.find(pneuma::escape_markup(error_line)), std::string::npos);

  // Rerun: the failed field is tried again, the finished run is not.
  const auto again = run_cohort(cohort, out);
  EXPECT_EQ(again.exit_code, 1);
  EXPECT_EQ(jobs_of_rule(again.out + again.err, "field"), 1) << again.out;
  EXPECT_EQ(jobs_of_rule(again.out + again.err, "run"), 1) << again.out;  // planned; never starts
}

// --dry-run lists the jobs and runs none; the Snakefile in DIR is the one in the source tree.
TEST(CohortLocal, DryRunListsTheJobsAndRunsNone) {
  SKIP_WITHOUT_SNAKEMAKE();
  TempDir dir;
  write_scenarios(dir);
  const fs::path cohort = write_cohort(dir, "dry", {{"a", kPhantom}, {"b", "{mesh: {phantom: left}}"}});
  const auto r = run_cohort(cohort, dir / "out", {"--dry-run"});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_EQ(jobs_of_rule(r.out + r.err, "field"), 2) << r.out;
  EXPECT_EQ(jobs_of_rule(r.out + r.err, "run"), 4) << r.out;
  EXPECT_FALSE(fs::exists(dir / "out/runs"));
  EXPECT_FALSE(fs::exists(dir / "out/fields"));
  EXPECT_FALSE(fs::exists(dir / "out/cohort.csv"));
  EXPECT_EQ(read_text(dir / "out/.cohort/Snakefile"), read_text(PNEUMA_SNAKEFILE_SOURCE));
}

// A workflow Snakemake refuses (here a Snakefile it cannot parse) on a first run: the cohort
// fails and leaves the folder as it found it, absent or holding only what it held.
TEST(CohortLocal, AWorkflowSnakemakeRefusesLeavesTheFolderAsItWas) {
  SKIP_WITHOUT_SNAKEMAKE();
  TempDir dir;
  write_scenarios(dir);
  const fs::path cohort = write_cohort(dir, "refused", {{"a", kPhantom}});
  const fs::path snakefile = dir.write("Broken", "rule all:\n    input: [\n");
  for (const bool dry : {true, false}) {
    std::vector<std::string> extra = {"--snakefile", snakefile.string()};
    if (dry) extra.emplace_back("--dry-run");
    const auto r = run_cohort(cohort, dir / "out", extra);
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_FALSE(fs::exists(dir / "out")) << r.err;
    // One line says why, naming Snakemake's own place of the error: the Snakefile (as pneuma
    // copied it into the folder) and its line.
    const std::string last = last_line(r.err);
    EXPECT_EQ(last.rfind("pneuma: cohort: snakemake ", 0), 0u) << r.err;
    EXPECT_NE(last.find(": SyntaxError in file "), std::string::npos) << last;
    EXPECT_NE(last.find("Snakefile, line 2"), std::string::npos) << last;
    dir.write("kept/notes.txt", "mine");
    EXPECT_EQ(run_cohort(cohort, dir / "kept", extra).exit_code, 1);
    std::vector<std::string> left;
    for (const auto& e : fs::directory_iterator(dir / "kept")) left.push_back(e.path().filename().string());
    EXPECT_EQ(left, std::vector<std::string>{"notes.txt"});
  }
}

// A second cohort into a folder in use stops at once; the first is not disturbed.
TEST(CohortLocal, TheSameFolderTwiceAtOnceIsRefused) {
  SKIP_WITHOUT_SNAKEMAKE();
  TempDir dir;
  write_scenarios(dir);
  const fs::path cohort = write_cohort(dir, "busy", {{"a", kPhantom}}, "{quiet: scenarios/quiet.yaml}");
  BackgroundCohort first({"cohort", cohort.string(), "-o", (dir / "out").string()}, dir / "first.log");
  ASSERT_TRUE(wait_until([&] { return fs::exists(dir / "out/.cohort/Snakefile"); }, 60000));
  const auto second = run_cohort(cohort, dir / "out");
  EXPECT_EQ(second.exit_code, 4) << second.err;
  EXPECT_EQ(second.err, (dir / "out").string() + ": another pneuma cohort is running into this folder (" +
                            (dir / "out/.cohort/lock").string() + " is locked); wait for it to end or stop it\n");
}

}  // namespace
