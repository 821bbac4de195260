#include "pneuma/cohort/workflow.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <poll.h>
#include <pwd.h>
#include <signal.h>
#include <spawn.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <thread>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/core/paths.h"

extern char** environ;

namespace pneuma::cohort {
namespace {

// Snakemake's process while it runs, for the signal handler (one workflow at a time).
std::atomic<pid_t> g_snakemake{0};
std::atomic<int> g_signal{0};

// A signal sent by a process (kill, Slurm, a test) is passed on to Snakemake; one from the
// terminal (Ctrl-C) reached Snakemake already, as the whole foreground group gets it, and a
// second one would cut Snakemake's own clean-up short.
void forward_signal(int signal, siginfo_t* info, void*) {
  g_signal.store(signal);
  const pid_t child = g_snakemake.load();
  if (child > 0 && info && (info->si_code == SI_USER || info->si_code == SI_QUEUE)) ::kill(child, signal);
}

// Writes `text` to `path` unless the file already holds it (an unchanged file keeps its time).
void write_if_changed(const std::filesystem::path& path, const std::string& text) {
  if (path_exists(path)) {
    try {
      if (read_file_bytes(path) == text) return;
    } catch (const IoError&) {
      // unreadable: written again below
    }
  }
  write_stream_atomically(path, true, [&](std::ostream& out) { out << text; });
}

// flock(2) on DIR/.cohort/lock, held until the process (and Snakemake, which inherits the
// descriptor) ends: the kernel drops it when they die, however they die.
class DirectoryLock {
 public:
  explicit DirectoryLock(const std::filesystem::path& dir) {
    const std::filesystem::path file = dir / kStateDir / "lock";
    fd_ = ::open(file.c_str(), O_RDWR | O_CREAT, 0644);
    if (fd_ < 0) throw IoError(file.string() + ": cannot open the cohort's lock file: " + std::strerror(errno));
    if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      ::close(fd_);
      throw IoError(dir.string() + ": another pneuma cohort is running into this folder (" + file.string() +
                    " is locked); wait for it to end or stop it");
    }
  }
  ~DirectoryLock() { ::close(fd_); }
  DirectoryLock(const DirectoryLock&) = delete;
  DirectoryLock& operator=(const DirectoryLock&) = delete;

 private:
  int fd_ = -1;
};

void emit_paths(YAML::Emitter& out, const char* key, const std::vector<std::filesystem::path>& paths) {
  out << YAML::Key << key << YAML::Value << YAML::Flow << YAML::BeginSeq;
  for (const auto& p : paths) out << std::filesystem::absolute(p).lexically_normal().string();
  out << YAML::EndSeq;
}

std::string text_at(const YAML::Node& node, const char* key, const std::filesystem::path& file) {
  if (!node[key] || !node[key].IsScalar()) throw InputError(file.string() + ": not a cohort plan: no '" + key + "'");
  return node[key].as<std::string>();
}

}  // namespace

extern const char* const kBuiltinSnakefile;

const std::string& builtin_snakefile() {
  static const std::string text = kBuiltinSnakefile;
  return text;
}

std::string plan_yaml(const Cohort& cohort, const Plan& plan, const std::filesystem::path& pneuma) {
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << "pneuma-cohort-plan 1";
  out << YAML::Key << "name" << YAML::Value << cohort.name;
  out << YAML::Key << "cohort" << YAML::Value << std::filesystem::absolute(cohort.file).lexically_normal().string();
  out << YAML::Key << "pneuma" << YAML::Value << pneuma.string();
  out << YAML::Key << "threads" << YAML::Value << cohort.resources.threads;
  out << YAML::Key << "mem_mb" << YAML::Value << cohort.resources.memory_mb;
  out << YAML::Key << "runtime" << YAML::Value << cohort.resources.runtime_min;
  out << YAML::Key << "fields" << YAML::Value << YAML::BeginMap;
  for (const FieldJob& f : plan.fields) {
    out << YAML::Key << (f.subject + "/" + f.id) << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "subject" << YAML::Value << f.subject;
    out << YAML::Key << "id" << YAML::Value << f.id;
    out << YAML::Key << "scenario" << YAML::Value << f.scenario;
    emit_paths(out, "inputs", f.inputs);
    out << YAML::Key << "digest" << YAML::Value << f.digest;
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  out << YAML::Key << "runs" << YAML::Value << YAML::BeginMap;
  for (const RunJob& r : plan.runs) {
    out << YAML::Key << (r.subject + "/" + r.scenario) << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "subject" << YAML::Value << r.subject;
    out << YAML::Key << "scenario" << YAML::Value << r.scenario;
    out << YAML::Key << "field" << YAML::Value << r.field;
    emit_paths(out, "inputs", r.inputs);
    out << YAML::Key << "digest" << YAML::Value << r.digest;
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

PlanFile read_plan(const std::filesystem::path& output_dir) {
  const std::filesystem::path file = output_dir / kPlanFile;
  const std::string text = read_file_bytes(file);
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw InputError(location(file.string(), e.mark.line, e.mark.column) + ": not a cohort plan: " + e.msg);
  }
  if (!root.IsMap() || !root["format"] || root["format"].as<std::string>("") != "pneuma-cohort-plan 1")
    throw InputError(file.string() + ": not a cohort plan (format 'pneuma-cohort-plan 1'); run pneuma cohort again");
  PlanFile p;
  p.name = text_at(root, "name", file);
  p.cohort = text_at(root, "cohort", file);
  for (const auto& entry : root["fields"]) {
    FieldJob f;
    f.subject = text_at(entry.second, "subject", file);
    f.id = text_at(entry.second, "id", file);
    f.scenario = text_at(entry.second, "scenario", file);
    p.plan.fields.push_back(std::move(f));
  }
  for (const auto& entry : root["runs"]) {
    RunJob r;
    r.subject = text_at(entry.second, "subject", file);
    r.scenario = text_at(entry.second, "scenario", file);
    r.field = text_at(entry.second, "field", file);
    p.plan.runs.push_back(std::move(r));
  }
  return p;
}

std::vector<std::string> snakemake_command(const WorkflowOptions& o) {
  const std::filesystem::path dir = std::filesystem::absolute(o.output_dir).lexically_normal();
  // --ignore-incomplete: every output of the workflow is written whole or not at all (a run's
  // manifest.json appears last, when its outputs are complete; a field file is renamed into
  // place), so one that exists is complete. Snakemake's own marker would rerun a job killed
  // between its output appearing and Snakemake noting it; trusting the files reruns only the
  // missing ones. (Snakemake removes a job's outputs before it starts, so a rerun of a changed
  // job never leaves an old output standing for a new one.)
  std::vector<std::string> argv{o.snakemake.string(),  "--snakefile",  (dir / kSnakefile).string(), "--directory",
                                dir.string(),          "--configfile", (dir / kPlanFile).string(),  "--keep-going",
                                "--ignore-incomplete", "--nolock"};
  const int jobs =
      o.jobs > 0
          ? o.jobs
          : (o.executor == Executor::local ? static_cast<int>(std::max(1u, std::thread::hardware_concurrency())) : 100);
  switch (o.executor) {
    case Executor::local: argv.insert(argv.end(), {"--cores", std::to_string(jobs)}); break;
    case Executor::slurm:
      // Snakemake 7.21's own Slurm executor: one sbatch per job (rule resources: threads as
      // --cpus-per-task, mem_mb as --mem, runtime as -t; slurm_partition and slurm_account
      // through --default-resources), its state polled with sacct, else scontrol.
      argv.insert(argv.end(), {"--slurm", "--jobs", std::to_string(jobs)});
      break;
    case Executor::profile:
      argv.insert(argv.end(), {"--profile", o.profile});
      if (o.jobs > 0) argv.insert(argv.end(), {"--jobs", std::to_string(o.jobs)});
      break;
  }
  if (o.dry_run) argv.emplace_back("--dry-run");
  argv.insert(argv.end(), o.extra_args.begin(), o.extra_args.end());
  return argv;
}

namespace {

std::string trimmed(const std::string& line) {
  const auto first = line.find_first_not_of(" \t\r");
  if (first == std::string::npos) return {};
  const auto last = line.find_last_not_of(" \t\r");
  return line.substr(first, last - first + 1);
}

// Snakemake keeps what it forwards to the terminal, at most this much: the first failure is
// near the top of a failed run's output, and its last lines say why it stopped.
constexpr std::size_t kKeptLog = 1u << 20;

// Copies what arrives on `out` and `err` to this process's stdout and stderr until both close
// (Snakemake and every job holding them ended), and returns it (at most kKeptLog bytes). Reads
// on whatever happens to this process's own streams, so that Snakemake never blocks on a pipe.
std::string pass_on_and_keep(int out, int err) {
  std::string kept;
  std::array<pollfd, 2> fds{pollfd{out, POLLIN, 0}, pollfd{err, POLLIN, 0}};
  const std::array<int, 2> targets{STDOUT_FILENO, STDERR_FILENO};
  std::array<char, 4096> buffer{};
  int open = 2;
  while (open > 0) {
    if (::poll(fds.data(), fds.size(), -1) < 0) {
      if (errno == EINTR) continue;
      break;
    }
    for (std::size_t k = 0; k < fds.size(); ++k) {
      if (fds[k].fd < 0 || fds[k].revents == 0) continue;
      const ssize_t n = ::read(fds[k].fd, buffer.data(), buffer.size());
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        ::close(fds[k].fd);
        fds[k].fd = -1;
        --open;
        continue;
      }
      const auto bytes = static_cast<std::size_t>(n);
      for (std::size_t written = 0; written < bytes;) {
        const ssize_t w = ::write(targets[k], buffer.data() + written, bytes - written);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) break;
        written += static_cast<std::size_t>(w);
      }
      if (kept.size() < kKeptLog) kept.append(buffer.data(), std::min(bytes, kKeptLog - kept.size()));
    }
  }
  for (const pollfd& f : fds)
    if (f.fd >= 0) ::close(f.fd);
  return kept;
}

}  // namespace

std::string diagnose_snakemake(const std::string& log, const std::filesystem::path& dir) {
  std::vector<std::string> lines;
  {
    std::istringstream in(log);
    for (std::string line; std::getline(in, line);) lines.push_back(line);
  }
  // A job's facts: the indented "key: value" lines under a "rule NAME:" or "Error in rule NAME:".
  const auto facts_after = [&](std::size_t i) {
    std::map<std::string, std::string> facts;
    for (std::size_t j = i + 1; j < lines.size() && !lines[j].empty() && (lines[j][0] == ' ' || lines[j][0] == '\t');
         ++j) {
      const std::string fact = trimmed(lines[j]);
      const auto colon = fact.find(": ");
      if (colon != std::string::npos) facts.emplace(fact.substr(0, colon), fact.substr(colon + 2));
    }
    return facts;
  };
  // Snakemake 7.21 names a job's wildcards where it starts it, and only its jobid where it fails.
  static const std::regex job_start(R"(^(local)?rule (\S+):\s*$)");
  static const std::regex job_error(R"(^Error in rule (\S+):\s*$)");
  static const std::regex exit_note(R"(^exit status (\d+)$)");  // the Snakefile's ON_FAILURE line
  static const std::regex error_line(R"(^\S*(Error|Exception)\b.*)");
  std::map<std::string, std::string> wildcards_of_job;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (!std::regex_match(lines[i], job_start)) continue;
    auto facts = facts_after(i);
    if (facts.count("jobid") && facts.count("wildcards")) wildcards_of_job[facts["jobid"]] = facts["wildcards"];
  }
  for (std::size_t i = 0; i < lines.size(); ++i) {
    std::smatch m;
    if (!std::regex_match(lines[i], m, job_error)) continue;
    auto facts = facts_after(i);
    const std::string wildcards = wildcards_of_job.count(facts["jobid"]) ? wildcards_of_job[facts["jobid"]] : "";
    const std::string job_log = facts["log"].substr(0, facts["log"].find(" (check log"));
    // The job's own last word (pneuma's one-line error), and the exit status the Snakefile noted.
    std::string why, status;
    if (!job_log.empty()) {
      std::ifstream in(dir / job_log);
      for (std::string line; std::getline(in, line);) {
        line = trimmed(line);
        std::smatch e;
        if (std::regex_match(line, e, exit_note)) {
          status = e[1].str();
        } else if (!line.empty()) {
          why = line;
        }
      }
    }
    if (why.empty()) why = "its command failed";
    return fmt::format("rule {}{} failed{}: {}{}", m[1].str(), wildcards.empty() ? "" : " (" + wildcards + ")",
                       status.empty() ? "" : " (exit " + status + ")", why,
                       job_log.empty() ? "" : " (log: " + job_log + ")");
  }
  // Snakemake stopped before any job: its first error line, with the next when it ends in ':'.
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (!std::regex_match(lines[i], error_line)) continue;
    std::string text = trimmed(lines[i]);
    if (!text.empty() && text.back() == ':' && i + 1 < lines.size()) text += " " + trimmed(lines[i + 1]);
    return text;
  }
  for (auto it = lines.rbegin(); it != lines.rend(); ++it)
    if (!trimmed(*it).empty()) return trimmed(*it);
  return "no output";
}

WorkflowResult run_workflow(const Cohort& cohort, const Plan& plan, const WorkflowOptions& o) {
  const std::filesystem::path dir = std::filesystem::absolute(o.output_dir).lexically_normal();
  // A first run that Snakemake stops before any job (a workflow it refuses) leaves the folder as
  // it found it: no .cohort/ or .snakemake/ standing for a cohort that never started.
  const bool dir_existed = path_exists(dir);
  const bool first_run = !path_exists(dir / kStateDir) && !path_exists(dir / ".snakemake");
  std::error_code ec;
  std::filesystem::create_directories(dir / kStateDir, ec);
  if (ec) throw IoError((dir / kStateDir).string() + ": cannot create folder: " + ec.message());
  const DirectoryLock lock(dir);
  write_if_changed(dir / kPlanFile, plan_yaml(cohort, plan, o.pneuma));
  write_if_changed(dir / kSnakefile, o.snakefile ? read_file_bytes(*o.snakefile) : builtin_snakefile());

  // Snakemake 7.21's Slurm executor reads $USER to guess the account (slurm_submit.get_account)
  // and stops with a KeyError without it, as under cron, in containers and in CTest.
  if (o.executor != Executor::local && std::getenv("USER") == nullptr) {
    if (const passwd* user = ::getpwuid(::geteuid())) ::setenv("USER", user->pw_name, 0);
  }
  const std::vector<std::string> args = snakemake_command(o);
  std::vector<char*> argv;
  argv.reserve(args.size() + 1);
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);

  struct sigaction forward {};
  forward.sa_sigaction = forward_signal;
  forward.sa_flags = SA_SIGINFO;
  sigemptyset(&forward.sa_mask);
  struct sigaction old_int {
  }, old_term{};
  g_signal.store(0);
  ::sigaction(SIGINT, &forward, &old_int);
  ::sigaction(SIGTERM, &forward, &old_term);
  // Snakemake's stdout and stderr through pipes: passed on as they come, and kept to say why it
  // failed (7.21 writes a Snakefile's syntax error to stdout, a job's failure to stderr).
  std::array<std::array<int, 2>, 2> pipes{};
  for (auto& p : pipes)
    if (::pipe2(p.data(), O_CLOEXEC) != 0)
      throw IoError(std::string("cohort: cannot make a pipe: ") + std::strerror(errno));
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, pipes[0][1], STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&actions, pipes[1][1], STDERR_FILENO);
  pid_t pid = 0;
  const int spawned = ::posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  for (auto& p : pipes) ::close(p[1]);
  if (spawned != 0) {
    for (auto& p : pipes) ::close(p[0]);
    ::sigaction(SIGINT, &old_int, nullptr);
    ::sigaction(SIGTERM, &old_term, nullptr);
    throw UnsupportedError(
        fmt::format("pneuma: cohort: cannot start {}: {} (install Snakemake 7: scripts/install-deps)", args.front(),
                    std::strerror(spawned)));
  }
  g_snakemake.store(pid);
  const std::string kept = pass_on_and_keep(pipes[0][0], pipes[1][0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  g_snakemake.store(0);
  ::sigaction(SIGINT, &old_int, nullptr);
  ::sigaction(SIGTERM, &old_term, nullptr);
  WorkflowResult result;
  if (g_signal.load() != 0) {
    result.status = 128 + g_signal.load();
  } else if (WIFSIGNALED(status)) {
    result.status = 128 + WTERMSIG(status);
  } else {
    result.status = WIFEXITED(status) ? WEXITSTATUS(status) : 1;
  }
  if (result.status != 0) result.failure = diagnose_snakemake(kept, dir);
  if (result.status > 128) return result;
  const int code = result.status;
  // Every job writes its log under logs/ (the Snakefile): none there, none started.
  if (code != 0 && first_run && !path_exists(dir / "logs")) {
    std::filesystem::remove_all(dir / kStateDir, ec);
    std::filesystem::remove_all(dir / ".snakemake", ec);
    if (!dir_existed) std::filesystem::remove(dir, ec);  // only when empty
  }
  return result;
}

}  // namespace pneuma::cohort
