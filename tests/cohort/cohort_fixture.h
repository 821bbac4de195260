#pragma once
// Shared by the cohort tests: a small cohort (the phantom and CT cases at a coarse edge, two
// short scenarios), running `pneuma cohort`, and reading back what it wrote, independently of
// the summary code (manifests with nlohmann::json, CSVs by hand).
#include <fcntl.h>
#include <fmt/format.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "test_support.h"

extern char** environ;

namespace pneuma::test {

namespace fs = std::filesystem;

// Two short scenarios: quiet breathing and a deep breath, both upright, with a report.
inline void write_scenarios(const TempDir& dir) {
  dir.write("scenarios/quiet.yaml",
            "name: quiet\nduration: 10 s\nframes: {rate: 10 Hz}\nmesh: {phantom: left, edge: 4 mm}\n"
            "field: {tissue: healthy-upright}\nphysiology: {preset: healthy-adult}\n"
            "outputs: {hdf5: false, png: false, gltf: false}\n");
  dir.write("scenarios/deep.yaml",
            "name: deep\nduration: 10 s\nframes: {rate: 10 Hz}\nfield: {tissue: healthy-upright}\n"
            "physiology:\n  preset: healthy-adult\n  driver: {mode: spontaneous, rate: 12 /min, tidal_volume: 900 mL}\n"
            "outputs: {hdf5: false, png: false, gltf: false}\n");
}

// subjects: id -> its YAML (a flow mapping), in order.
inline fs::path write_cohort(
    const TempDir& dir, const std::string& name, const std::vector<std::pair<std::string, std::string>>& subjects,
    const std::string& scenarios = "{quiet: scenarios/quiet.yaml, deep: scenarios/deep.yaml}") {
  std::string text = "name: " + name + "\nedge: 8 mm\nsubjects:\n";
  for (const auto& [id, yaml] : subjects) text += fmt::format("  {}: {}\n", id, yaml);
  text += "scenarios: " + scenarios + "\n";
  return dir.write(name + ".yaml", text);
}

inline std::string ct_subject(const std::string& case_name) {
  return "{mesh: {labels: " + (ct_lobes_dir() / (case_name + "_lobes.nii.gz")).string() +
         ", values: [3, 4, 5], share: 55 %}, field: {tissue: healthy-upright}}";
}

inline const char* kPhantom = "{mesh: {phantom: right}}";

// The rows of a CSV file as column -> text maps.
inline std::vector<std::map<std::string, std::string>> read_csv(const fs::path& file) {
  std::ifstream in(file);
  std::string line;
  std::vector<std::map<std::string, std::string>> rows;
  if (!std::getline(in, line)) return rows;
  auto split = [](const std::string& text) {
    std::vector<std::string> cells;
    std::string cell;
    bool quoted = false;
    for (std::size_t i = 0; i < text.size(); ++i) {
      const char c = text[i];
      if (quoted) {
        if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') cell += c, ++i;
        else if (c == '"') quoted = false;
        else cell += c;
      } else if (c == '"') {
        quoted = true;
      } else if (c == ',') {
        cells.push_back(cell), cell.clear();
      } else {
        cell += c;
      }
    }
    cells.push_back(cell);
    return cells;
  };
  const std::vector<std::string> header = split(line);
  while (std::getline(in, line)) {
    const std::vector<std::string> cells = split(line);
    std::map<std::string, std::string> row;
    for (std::size_t i = 0; i < header.size() && i < cells.size(); ++i) row[header[i]] = cells[i];
    rows.push_back(std::move(row));
  }
  return rows;
}

inline nlohmann::json read_manifest(const fs::path& run_dir) {
  return nlohmann::json::parse(read_text(run_dir / "manifest.json"));
}

// Every output file of a run with its SHA-256, from its manifest: what must be the same bytes
// in two cohorts (the manifest itself holds timings, so it is not among them).
inline std::map<std::string, std::string> output_digests(const fs::path& run_dir) {
  std::map<std::string, std::string> digests;
  const nlohmann::json manifest = read_manifest(run_dir);
  for (const auto& file : manifest.at("files")) {
    digests[file.at("path").get<std::string>()] = file.at("sha256").get<std::string>();
  }
  return digests;
}

// How many jobs of `rule` Snakemake said it would run ("Job stats:" table; 0 when none).
// The last non-empty line of a program's output.
inline std::string last_line(const std::string& text) {
  std::string line, last;
  std::istringstream in(text);
  while (std::getline(in, line))
    if (!line.empty()) last = line;
  return last;
}

inline int jobs_of_rule(const std::string& snakemake_output, const std::string& rule) {
  std::istringstream in(snakemake_output);
  int count = 0;
  for (std::string line; std::getline(in, line);) {
    std::istringstream words(line);
    std::string first;
    int n = 0;
    if (words >> first && first == rule && words >> n) count = n;  // the last table wins
  }
  return count;
}

// The time a file was last written, in nanoseconds (to see that a rerun left it alone).
inline long long write_time_ns(const fs::path& file) {
  return static_cast<long long>(fs::last_write_time(file).time_since_epoch().count());
}

// `pneuma cohort ...` started in a process group of its own (so that the test can kill the whole
// cohort, Snakemake and its jobs included, as a crash or a lost node would), output to files.
class BackgroundCohort {
 public:
  BackgroundCohort(const std::vector<std::string>& args, const fs::path& log) {
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    posix_spawnattr_t attributes;
    posix_spawnattr_init(&attributes);
    posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETPGROUP);
    posix_spawnattr_setpgroup(&attributes, 0);
    std::vector<std::string> storage{PNEUMA_EXE};
    storage.insert(storage.end(), args.begin(), args.end());
    std::vector<char*> argv;
    argv.reserve(storage.size() + 1);
    for (auto& s : storage) argv.push_back(s.data());
    argv.push_back(nullptr);
    if (posix_spawn(&pid_, PNEUMA_EXE, &actions, &attributes, argv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
    posix_spawnattr_destroy(&attributes);
  }
  ~BackgroundCohort() {
    if (pid_ > 0 && !reaped_) kill_group(SIGKILL);
  }
  BackgroundCohort(const BackgroundCohort&) = delete;
  BackgroundCohort& operator=(const BackgroundCohort&) = delete;
  bool started() const { return pid_ > 0; }
  // Sends `signal` to the whole group and reaps the leader.
  void kill_group(int signal) {
    ::kill(-pid_, signal);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    reaped_ = true;
    // The group's other processes (Snakemake's jobs) die of the same signal; wait until none is left.
    wait_until([&] { return ::kill(-pid_, 0) != 0; }, 10000);
  }

 private:
  pid_t pid_ = -1;
  bool reaped_ = false;
};

}  // namespace pneuma::test
