// Staged outputs: complete or not at all, the previous output kept until the new one is
// complete, stale stages of dead processes removed, live ones respected.
#include "pneuma/core/staged_output.h"

#include <gtest/gtest.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fcntl.h>

#include <csignal>
#include <fstream>

#include "pneuma/core/error.h"
#include "test_support.h"

using pneuma::StagedOutput;
using pneuma::test::read_text;
using pneuma::test::TempDir;

namespace {

std::vector<std::string> stages_in(const std::filesystem::path& folder) {
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(folder)) {
    const auto name = e.path().filename().string();
    if (name.starts_with(pneuma::kStagePrefix)) names.push_back(name);
  }
  return names;
}

// A pid that belonged to a process that has exited and been reaped.
pid_t dead_pid() {
  const pid_t child = fork();
  if (child == 0) _exit(0);
  int status = 0;
  waitpid(child, &status, 0);
  return child;
}

}  // namespace

TEST(StagedOutput, NothingAppearsBeforeCommitAndEverythingAfter) {
  TempDir dir;
  const auto folder = dir / "out";
  {
    StagedOutput staged(folder);
    EXPECT_EQ(staged.stage().parent_path(), std::filesystem::absolute(folder));
    std::ofstream(staged.stage() / "a.csv") << "new a";
    std::filesystem::create_directory(staged.stage() / "frames");
    std::ofstream(staged.stage() / "frames" / "1.png") << "new frame";
    EXPECT_FALSE(std::filesystem::exists(folder / "a.csv"));
    staged.commit();
  }
  EXPECT_EQ(read_text(folder / "a.csv"), "new a");
  EXPECT_EQ(read_text(folder / "frames" / "1.png"), "new frame");
  EXPECT_TRUE(stages_in(folder).empty());
}

TEST(StagedOutput, AnAbandonedStageLeavesThePreviousOutputAsItWas) {
  TempDir dir;
  const auto folder = dir / "out";
  dir.write("out/a.csv", "old a");
  dir.write("out/frames/1.png", "old frame");
  {
    StagedOutput staged(folder);
    std::ofstream(staged.stage() / "a.csv") << "new a";
    std::filesystem::create_directory(staged.stage() / "frames");
  }  // an exception would end here: no commit
  EXPECT_EQ(read_text(folder / "a.csv"), "old a");
  EXPECT_EQ(read_text(folder / "frames" / "1.png"), "old frame");
  EXPECT_TRUE(stages_in(folder).empty());
}

TEST(StagedOutput, CommitReplacesFilesAndWholeFoldersAndRemovesObsoleteEntries) {
  TempDir dir;
  const auto folder = dir / "out";
  dir.write("out/a.csv", "old a");
  dir.write("out/frames/1.png", "old frame 1");
  dir.write("out/frames/2.png", "old frame 2");
  dir.write("out/old.glb", "old glb");
  dir.write("out/notes.txt", "the user's");
  StagedOutput staged(folder);
  std::ofstream(staged.stage() / "a.csv") << "new a";
  std::filesystem::create_directory(staged.stage() / "frames");
  std::ofstream(staged.stage() / "frames" / "1.png") << "new frame 1";
  staged.commit({"old.glb", "../escape", "frames/2.png"});
  EXPECT_EQ(read_text(folder / "a.csv"), "new a");
  EXPECT_EQ(read_text(folder / "frames" / "1.png"), "new frame 1");
  EXPECT_FALSE(std::filesystem::exists(folder / "frames" / "2.png")) << "the old folder is replaced, not merged";
  EXPECT_FALSE(std::filesystem::exists(folder / "old.glb"));
  EXPECT_EQ(read_text(folder / "notes.txt"), "the user's");
  EXPECT_TRUE(stages_in(folder).empty());
}

TEST(StagedOutput, StagesAndTemporariesOfDeadProcessesAreRemoved) {
  TempDir dir;
  const auto folder = dir / "out";
  const pid_t dead = dead_pid();
  const std::string dead_stage = pneuma::kStagePrefix + std::to_string(dead) + "-0";
  dir.write("out/" + dead_stage + "/lock", "");  // its lock is free: the owner is gone
  dir.write("out/" + dead_stage + "/png/frame_00001.png", "partial");
  const std::string no_lock = pneuma::kStagePrefix + std::to_string(dead) + "-1";
  std::filesystem::create_directories(folder / no_lock);  // killed before its lock existed
  dir.write("out/series.h5.tmp-" + std::to_string(dead) + "-3", "half");
  dir.write("out/series.h5.tmp-" + std::to_string(getpid()) + "-3", "ours, live");
  dir.write("out/series.h5", "complete");
  StagedOutput staged(folder);
  EXPECT_EQ(stages_in(folder), std::vector<std::string>{staged.stage().filename().string()});
  EXPECT_FALSE(std::filesystem::exists(folder / ("series.h5.tmp-" + std::to_string(dead) + "-3")));
  EXPECT_TRUE(std::filesystem::exists(folder / ("series.h5.tmp-" + std::to_string(getpid()) + "-3")));
  EXPECT_EQ(read_text(folder / "series.h5"), "complete");
}

TEST(StagedOutput, ALiveStageInTheFolderIsRefusedWithOneLine) {
  TempDir dir;
  const auto folder = dir / "out";
  // Another live process holding its stage's lock: a child that locks and waits.
  const std::string stage = std::string(pneuma::kStagePrefix) + "1-0";
  dir.write("out/" + stage + "/lock", "");
  int ready[2];
  ASSERT_EQ(pipe(ready), 0);
  const pid_t child = fork();
  if (child == 0) {
    const int fd = open((folder / stage / "lock").c_str(), O_RDONLY);
    flock(fd, LOCK_EX);
    (void)!write(ready[1], "x", 1);
    pause();
    _exit(0);
  }
  char byte = 0;
  ASSERT_EQ(read(ready[0], &byte, 1), 1);
  try {
    StagedOutput staged(folder);
    ADD_FAILURE() << "a folder with a live stage was accepted";
  } catch (const pneuma::IoError& e) {
    EXPECT_EQ(std::string(e.what()), folder.string() + ": another pneuma run (process 1) is writing its outputs here; "
                                                       "wait for it or choose another output folder");
  }
  kill(child, SIGKILL);
  waitpid(child, nullptr, 0);
  StagedOutput now_free(folder);  // the lock died with its process
  EXPECT_EQ(stages_in(folder).size(), 1u);
  close(ready[0]);
  close(ready[1]);
}
