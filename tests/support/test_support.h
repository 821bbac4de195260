#pragma once
// Shared test helpers (in the spirit of MuJoCo's test/fixture.h): temporary folders, files,
// and running the `pneuma` executable to check its exact one-line errors and exit codes.
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace pneuma::test {

// A fresh folder under the system temp dir, removed when the object goes away.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }
  // Writes `text` to <dir>/<name> and returns the path.
  std::filesystem::path write(const std::string& name, const std::string& text) const;
  // Names of the files in the folder (to check that nothing partial was left behind).
  std::vector<std::string> files() const;

 private:
  std::filesystem::path path_;
};

struct CommandResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

// Runs the pneuma executable with `args` (no shell involved), in `working_dir` if given.
CommandResult run_pneuma(const std::vector<std::string>& args, const std::filesystem::path& working_dir = {});

// Runs any program (a path; no shell, no PATH lookup) with `args`, in `working_dir` if given.
CommandResult run_program(const std::filesystem::path& program, const std::vector<std::string>& args,
                          const std::filesystem::path& working_dir = {});

// The first of `names` found on PATH, as a path; empty when none is there.
std::filesystem::path find_program(const std::vector<std::string>& names);

// Whether a test may skip when a client it checks the outputs with (ParaView, Blender) is not
// installed: yes outside CI; in CI (the environment variable CI set, as .ci/run and CI services set
// it, to anything but "" "0" "false") no, so that scripts/install-deps' clients are really
// exercised; PNEUMA_ALLOW_MISSING_CLIENTS=1 allows it anywhere.
bool missing_client_may_skip();

// Skips the test (outside CI) or fails it (in CI) when `program` (a path from find_program) is
// empty. The caller includes <gtest/gtest.h>.
#define PNEUMA_REQUIRE_CLIENT(program, what)                                                         \
  do {                                                                                               \
    if ((program).empty()) {                                                                         \
      if (::pneuma::test::missing_client_may_skip()) GTEST_SKIP() << (what) << " not found";         \
      GTEST_FAIL() << (what) << " not found, and CI requires it (scripts/install-deps installs it; " \
                   << "PNEUMA_ALLOW_MISSING_CLIENTS=1 skips instead)";                               \
    }                                                                                                \
  } while (false)

// Starts pneuma with `args`, sends SIGINT after `delay_ms` milliseconds, and returns its exit
// status (128 + signal when it died of one, as a shell reports it).
int interrupt_pneuma(const std::vector<std::string>& args, int delay_ms);

// A pneuma process running in the background (stdout and stderr discarded), to be stopped by
// a signal. Killed and reaped on destruction if still running.
class BackgroundPneuma {
 public:
  explicit BackgroundPneuma(const std::vector<std::string>& args);
  ~BackgroundPneuma();
  BackgroundPneuma(const BackgroundPneuma&) = delete;
  BackgroundPneuma& operator=(const BackgroundPneuma&) = delete;
  int pid() const { return pid_; }
  // Sends `signal` and waits: the exit status, 128 + signal when it died of one.
  int stop(int signal);

 private:
  int pid_ = -1;
  bool reaped_ = false;
};

// Polls `condition` every 10 ms until it holds (true) or `timeout_ms` passes (false).
bool wait_until(const std::function<bool()>& condition, int timeout_ms);

// The source tree (for shipped scenarios and presets).
std::filesystem::path source_dir();

std::string read_text(const std::filesystem::path& path);

// zlib's inflate over each gzip member of `gz` in turn (a writer may concatenate several: pneuma's
// .nii.gz members); `members` gets their count. A member that does not end cleanly is a test
// failure (and ends the reading).
std::string gunzip(std::string_view gz, int* members = nullptr);
// Number of lines in a text file (0 when it cannot be read).
int count_lines(const std::filesystem::path& path);

// The folder of the six CT lobe label maps (../shared/data/ct-lobes beside the checkout, or
// PNEUMA_CT_LOBES); tests skip with a message when case004_lobes.nii.gz is not there.
std::filesystem::path ct_lobes_dir();

}  // namespace pneuma::test
