#include "test_support.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>
#include <thread>

extern char** environ;

namespace pneuma::test {

TempDir::TempDir() {
  std::random_device rd;
  for (int attempt = 0; attempt < 100; ++attempt) {
    auto candidate = std::filesystem::temp_directory_path() / ("pneuma-test-" + std::to_string(rd()));
    if (std::filesystem::create_directory(candidate)) {
      path_ = candidate;
      return;
    }
  }
  throw std::runtime_error("cannot create a temporary folder");
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

std::filesystem::path TempDir::write(const std::string& name, const std::string& text) const {
  auto p = path_ / name;
  std::filesystem::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary) << text;
  return p;
}

std::vector<std::string> TempDir::files() const {
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::recursive_directory_iterator(path_)) {
    if (e.is_regular_file()) names.push_back(std::filesystem::relative(e.path(), path_).string());
  }
  return names;
}

std::string gunzip(std::string_view gz, int* members) {
  std::string out;
  int count = 0;
  std::vector<char> chunk(1 << 20);
  for (std::size_t at = 0; at < gz.size(); ++count) {
    z_stream z{};
    EXPECT_EQ(inflateInit2(&z, 15 + 16), Z_OK);  // gzip only
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(gz.data() + at));
    z.avail_in = static_cast<uInt>(gz.size() - at);
    int status = Z_OK;
    while (status == Z_OK) {
      z.next_out = reinterpret_cast<Bytef*>(chunk.data());
      z.avail_out = static_cast<uInt>(chunk.size());
      status = inflate(&z, Z_NO_FLUSH);
      out.append(chunk.data(), chunk.size() - z.avail_out);
    }
    at += z.total_in;
    inflateEnd(&z);
    if (status != Z_STREAM_END) {
      ADD_FAILURE() << "gzip member " << count << " ends with zlib status " << status;
      break;
    }
  }
  if (members != nullptr) *members = count;
  return out;
}

std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::filesystem::path source_dir() { return PNEUMA_SOURCE_DIR; }

namespace {

// Starts `program` with `args`, its stdout and stderr sent to the given files; returns its pid.
pid_t spawn(const std::string& program, const std::vector<std::string>& args, const char* out_path,
            const char* err_path, const std::filesystem::path& working_dir) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, out_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&actions, 2, err_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (!working_dir.empty()) posix_spawn_file_actions_addchdir_np(&actions, working_dir.c_str());
  std::vector<std::string> storage{program};
  storage.insert(storage.end(), args.begin(), args.end());
  std::vector<char*> argv;
  argv.reserve(storage.size() + 1);
  for (auto& s : storage) argv.push_back(s.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int started = posix_spawn(&pid, program.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (started != 0) throw std::runtime_error("cannot start " + program);
  return pid;
}

pid_t spawn_pneuma(const std::vector<std::string>& args, const char* out_path, const char* err_path,
                   const std::filesystem::path& working_dir) {
  return spawn(PNEUMA_EXE, args, out_path, err_path, working_dir);
}

// Waits for `pid`; its exit status, or 128 + signal when it died of one (as a shell says).
int wait_for(pid_t pid) {
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

}  // namespace

CommandResult run_program(const std::filesystem::path& program, const std::vector<std::string>& args,
                          const std::filesystem::path& working_dir) {
  TempDir capture;
  const auto out_path = capture / "stdout", err_path = capture / "stderr";
  CommandResult result;
  result.exit_code = wait_for(spawn(program.string(), args, out_path.c_str(), err_path.c_str(), working_dir));
  result.out = read_text(out_path);
  result.err = read_text(err_path);
  return result;
}

CommandResult run_pneuma(const std::vector<std::string>& args, const std::filesystem::path& working_dir) {
  return run_program(PNEUMA_EXE, args, working_dir);
}

std::filesystem::path find_program(const std::vector<std::string>& names) {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "/usr/bin:/bin");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    for (const auto& name : names) {
      auto candidate = std::filesystem::path(dir.empty() ? "." : dir) / name;
      if (access(candidate.c_str(), X_OK) == 0) return candidate;
    }
  }
  return {};
}

bool missing_client_may_skip() {
  const char* allow = std::getenv("PNEUMA_ALLOW_MISSING_CLIENTS");
  if (allow && std::string(allow) == "1") return true;
  const char* ci = std::getenv("CI");
  const std::string value = ci ? ci : "";
  return value.empty() || value == "0" || value == "false";
}

int interrupt_pneuma(const std::vector<std::string>& args, int delay_ms) {
  const pid_t pid = spawn_pneuma(args, "/dev/null", "/dev/null", {});
  std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
  kill(pid, SIGINT);
  return wait_for(pid);
}

BackgroundPneuma::BackgroundPneuma(const std::vector<std::string>& args)
    : pid_(spawn_pneuma(args, "/dev/null", "/dev/null", {})) {}

BackgroundPneuma::~BackgroundPneuma() {
  if (!reaped_) stop(SIGKILL);
}

int BackgroundPneuma::stop(int signal) {
  kill(pid_, signal);
  reaped_ = true;
  return wait_for(pid_);
}

bool wait_until(const std::function<bool()>& condition, int timeout_ms) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  while (!condition()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

int count_lines(const std::filesystem::path& path) {
  std::ifstream in(path);
  int n = 0;
  for (std::string line; std::getline(in, line);) ++n;
  return n;
}

std::filesystem::path ct_lobes_dir() {
  if (const char* env = std::getenv("PNEUMA_CT_LOBES")) return env;
  const auto source = source_dir();
  for (const auto& candidate :
       {source / ".." / "shared" / "data" / "ct-lobes", source / ".." / ".." / "shared" / "data" / "ct-lobes"}) {
    if (std::filesystem::exists(candidate / "case004_lobes.nii.gz")) return candidate;
  }
  return source / ".." / "shared" / "data" / "ct-lobes";
}

}  // namespace pneuma::test
