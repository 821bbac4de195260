#pragma once
// A run's outputs appear complete or not at all. They are written into a stage,
// <folder>/.pneuma-stage-<pid>-<n>/, and commit() moves each entry into <folder>, replacing
// the previous run's entry of the same name; until then the previous complete output stays as
// it was. Destroyed without commit() (an error), the stage is removed; on Ctrl-C or SIGTERM
// the interrupt handler (interrupt.h) removes it. A stage left by a killed run (SIGKILL, power
// loss) is removed by the next run into the same folder: each stage holds an flock(2) on its
// `lock` file for as long as its process lives, so a stage whose lock can be taken is dead.
#include <filesystem>
#include <string>
#include <vector>

namespace pneuma {

class StagedOutput {
 public:
  // Creates <folder> if needed, removes the leftovers of dead runs in it (stages, and
  // temporaries "<name>.tmp-<pid>-<n>" of processes that no longer exist), and creates the
  // stage. Throws IoError when the folder cannot be written, or when a live process is
  // writing a stage there (two runs into one folder would interleave their files).
  explicit StagedOutput(std::filesystem::path folder);
  ~StagedOutput();
  StagedOutput(const StagedOutput&) = delete;
  StagedOutput& operator=(const StagedOutput&) = delete;

  const std::filesystem::path& folder() const { return folder_; }
  const std::filesystem::path& stage() const { return stage_; }

  // Moves every entry of the stage (files and folders, top level) into the folder, the one
  // named `last` (if any: the manifest, whose presence says the folder is complete) after all
  // the others, then removes the entries named in `obsolete` (relative names, top level: what
  // the previous output had and this one has not), then the stage. Call it inside a
  // DeferInterruptions scope. Throws IoError when an entry cannot be moved.
  void commit(const std::vector<std::string>& obsolete = {}, const std::string& last = {});

 private:
  std::filesystem::path folder_;
  std::filesystem::path stage_;
  int lock_fd_ = -1;
  int slot_ = -1;
  bool committed_ = false;
};

// The prefix of stage folders (so listings and tools can recognise them).
inline constexpr const char* kStagePrefix = ".pneuma-stage-";

// Removes every stage still registered, with async-signal-safe calls only (the interrupt
// handler's use).
void remove_pending_stages() noexcept;

}  // namespace pneuma
