// Sturdy runs: an interrupted or killed `pneuma run` never leaves a partial output that could be
// taken for a finished one, a damaged cache is replaced, and the outputs are the same bytes at
// any thread count.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <algorithm>
#include <csignal>
#include <fstream>
#include <map>
#include <set>

#include <nlohmann/json.hpp>

#include "pneuma/core/staged_output.h"
#include "pneuma/model/field_cache.h"
#include "test_support.h"

using pneuma::test::BackgroundPneuma;
using pneuma::test::read_text;
using pneuma::test::run_pneuma;
using pneuma::test::TempDir;
using pneuma::test::wait_until;
namespace fs = std::filesystem;

namespace {

// A coarse phantom breathing with PNG frames, glTF, HDF5 and a PLY sequence; `duration` long.
std::string scenario(const std::string& duration, bool png = true) {
  return "name: sturdy\nduration: " + duration +
         "\nframes: {rate: 10 Hz}\n"
         "mesh: {phantom: right, edge: 12 mm, share: 55 %}\n"
         "field: {tissue: healthy-upright}\n"
         "physiology: {preset: healthy-adult}\n"
         "outputs:\n  mesh_sequence: {format: ply, every: 5}\n" +
         (png ? "  png: {width: 160, height: 120, every: 2}\n" : "  png: false\n");
}

// Every file under `folder` with its bytes (stages included, by name).
std::map<std::string, std::string> snapshot(const fs::path& folder) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(folder)) {
    if (e.is_regular_file()) files[fs::relative(e.path(), folder).generic_string()] = read_text(e.path());
  }
  return files;
}

// The stage of a run in progress, once it holds at least `frames` PNG frames ("" when none).
fs::path stage_with_frames(const fs::path& folder, std::size_t frames) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(folder, ec)) {
    if (!e.path().filename().string().starts_with(pneuma::kStagePrefix)) continue;
    std::size_t n = 0;
    for ([[maybe_unused]] const auto& f : fs::directory_iterator(e.path() / "png", ec)) ++n;
    if (n >= frames) return e.path();
  }
  return {};
}

bool has_stage(const fs::path& folder) {
  for (const auto& e : fs::directory_iterator(folder)) {
    if (e.path().filename().string().starts_with(pneuma::kStagePrefix)) return true;
  }
  return false;
}

}  // namespace

TEST(Sturdiness, ASignalledRunLeavesThePreviousCompleteOutputByteForByte) {
  for (const int signal : {SIGTERM, SIGINT}) {
    TempDir dir;
    const auto out = dir / "out";
    const auto done = run_pneuma({"run", dir.write("short.yaml", scenario("3 s")).string(), "-o", out.string(), "-q"});
    ASSERT_EQ(done.exit_code, 0) << done.err;
    const auto before = snapshot(out);
    ASSERT_TRUE(before.count("manifest.json") && before.count("png/frame_00000.png"));

    BackgroundPneuma run({"run", dir.write("long.yaml", scenario("600 s")).string(), "-o", out.string(), "-q"});
    ASSERT_TRUE(wait_until([&] { return !stage_with_frames(out, 3).empty(); }, 120000)) << "no frames appeared";
    EXPECT_EQ(run.stop(signal), 128 + signal);
    EXPECT_EQ(snapshot(out), before) << "signal " << signal;
    EXPECT_FALSE(has_stage(out));
  }
}

TEST(Sturdiness, AKilledRunsStageAndTemporariesAreRemovedByTheNextRun) {
  TempDir dir;
  const auto out = dir / "out";
  fs::path stage;
  int killed_pid = 0;
  {
    BackgroundPneuma run({"run", dir.write("long.yaml", scenario("600 s")).string(), "-o", out.string(), "-q"});
    killed_pid = run.pid();
    ASSERT_TRUE(wait_until([&] { return !(stage = stage_with_frames(out, 2)).empty(); }, 120000));
    EXPECT_EQ(run.stop(SIGKILL), 128 + SIGKILL);
  }
  ASSERT_TRUE(fs::exists(stage)) << "SIGKILL cannot clean up: the stage is still there";
  EXPECT_FALSE(fs::exists(out / "manifest.json"));
  const auto temporary = dir.write("out/series.h5.tmp-" + std::to_string(killed_pid) + "-0", "half a file");

  const auto next = run_pneuma({"run", dir.write("short.yaml", scenario("2 s")).string(), "-o", out.string(), "-q"});
  ASSERT_EQ(next.exit_code, 0) << next.err;
  EXPECT_FALSE(fs::exists(stage));
  EXPECT_FALSE(fs::exists(temporary));
  EXPECT_FALSE(has_stage(out));
  EXPECT_TRUE(fs::exists(out / "manifest.json"));
}

TEST(Sturdiness, ARunIntoAFolderALiveRunIsWritingIsRefused) {
  TempDir dir;
  const pneuma::StagedOutput live(dir / "out");  // this test process: alive, lock held
  const auto r = run_pneuma({"run", dir.write("s.yaml", scenario("1 s")).string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 4);
  EXPECT_EQ(r.err, (dir / "out").string() + ": another pneuma run (process " + std::to_string(getpid()) +
                       ") is writing its outputs here; wait for it or choose another output folder\n");
}

TEST(Sturdiness, WhatThePreviousRunWroteAndThisOneDoesNotIsRemovedTheUsersFilesKept) {
  TempDir dir;
  const auto out = dir / "out";
  ASSERT_EQ(run_pneuma({"run", dir.write("a.yaml", scenario("2 s")).string(), "-o", out.string(), "-q"}).exit_code, 0);
  ASSERT_TRUE(fs::exists(out / "png"));
  dir.write("out/notes.txt", "mine");
  ASSERT_EQ(
      run_pneuma({"run", dir.write("b.yaml", scenario("2 s", false)).string(), "-o", out.string(), "-q"}).exit_code, 0);
  EXPECT_FALSE(fs::exists(out / "png"));
  EXPECT_EQ(read_text(out / "notes.txt"), "mine");
  const auto manifest = nlohmann::json::parse(read_text(out / "manifest.json"));
  std::set<std::string> listed, present;
  for (const auto& f : manifest["files"]) listed.insert(f["path"].get<std::string>());
  for (const auto& [name, bytes] : snapshot(out)) present.insert(name);
  present.erase("manifest.json");
  present.erase("notes.txt");
  EXPECT_EQ(listed, present) << "the folder holds exactly what the manifest lists (and the user's file)";
}

TEST(Sturdiness, ADamagedCacheInTheOutputFolderIsReplacedWithAWarning) {
  TempDir dir;
  const auto out = dir / "out";
  const auto yaml = dir.write("s.yaml", scenario("2 s", false));
  ASSERT_EQ(run_pneuma({"run", yaml.string(), "-o", out.string(), "-q"}).exit_code, 0);
  const std::string good = read_text(out / "field.h5");
  {
    std::ofstream truncated(out / "field.h5", std::ios::binary | std::ios::trunc);
    truncated << good.substr(0, good.size() / 2);
  }
  const auto r = run_pneuma({"run", yaml.string(), "-o", out.string(), "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err,
            "pneuma: warning: " + (out / "field.h5").string() +
                ": not a pneuma field file: its bytes do not match its seal (truncated or damaged); computed the field "
                "again and replaced the file\n");
  EXPECT_EQ(read_text(out / "field.h5"), good) << "the recomputed field is the same bytes as the first";
  const auto again = run_pneuma({"run", yaml.string(), "-o", out.string(), "-q"});
  EXPECT_TRUE(again.err.empty()) << again.err;
}

TEST(Sturdiness, TheSameBytesAtOneTwoAndFourThreads) {
  // Field computed in each run (fresh folders), every output kind, PNG frames included.
  TempDir dir;
  const auto yaml =
      dir.write("s.yaml", scenario("3 s") + "  gltf: true\n  hdf5: {positions: float64, compression: gzip}\n");
  std::map<std::string, std::string> reference;
  for (const char* threads : {"1", "2", "4"}) {
    const auto out = dir / (std::string("out-") + threads);
    const auto r = run_pneuma({"--threads", threads, "run", yaml.string(), "-o", out.string(), "-q"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    auto files = snapshot(out);
    ASSERT_TRUE(files.count("field.h5") && files.count("breathing.glb") && files.count("series.h5") &&
                files.count("png/frame_00000.png"));
    files.erase("manifest.json");  // holds the timings; its file list is checked through the files themselves
    if (reference.empty()) {
      reference = files;
      continue;
    }
    ASSERT_EQ(files.size(), reference.size());
    for (const auto& [name, bytes] : files)
      EXPECT_TRUE(bytes == reference[name]) << name << " at " << threads << " threads";
  }
}

// outputs.hdf5.compression reaches the file: HDF5 reports no filter on a frame's positions by
// default, and shuffle then deflate with `gzip`.
TEST(Sturdiness, Hdf5CompressionIsTheScenariosChoice) {
  TempDir dir;
  for (const std::string compression : {"", "none", "gzip"}) {
    const std::string option = compression.empty() ? "true" : "{compression: " + compression + "}";
    const auto yaml = dir.write("s.yaml", scenario("1 s", false) + "  hdf5: " + option + "\n");
    const auto out = dir / ("out-" + compression);
    const auto r = run_pneuma({"run", yaml.string(), "-o", out.string(), "-q"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const hid_t file = H5Fopen((out / "series.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(file, 0) << compression;
    const hid_t set = H5Dopen2(file, "/frames/positions/000000", H5P_DEFAULT);
    ASSERT_GE(set, 0) << compression;
    const hid_t dcpl = H5Dget_create_plist(set);
    const int filters = H5Pget_nfilters(dcpl);
    ASSERT_EQ(filters, compression == "gzip" ? 2 : 0) << compression;
    if (filters == 2) {
      EXPECT_EQ(H5Pget_filter2(dcpl, 0, nullptr, nullptr, nullptr, 0, nullptr, nullptr), H5Z_FILTER_SHUFFLE);
      EXPECT_EQ(H5Pget_filter2(dcpl, 1, nullptr, nullptr, nullptr, 0, nullptr, nullptr), H5Z_FILTER_DEFLATE);
    }
    H5Pclose(dcpl);
    H5Dclose(set);
    H5Fclose(file);
  }
}

TEST(Sturdiness, ThreadsIsAcceptedAfterTheSubcommandAndChecked) {
  TempDir dir;
  const auto yaml = dir.write("s.yaml", scenario("1 s", false));
  EXPECT_EQ(run_pneuma({"run", yaml.string(), "-o", (dir / "o").string(), "-q", "--threads", "2"}).exit_code, 0);
  const auto bad = run_pneuma({"--threads", "0", "run", yaml.string(), "-o", (dir / "p").string()});
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--threads"), std::string::npos) << bad.err;
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
  EXPECT_FALSE(fs::exists(dir / "p"));
}
