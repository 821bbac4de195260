// Mesh sequences carry ParaView's file-series index (frames/frame.<ext>.series): every frame file
// written, with its time in seconds, so ParaView plays them in seconds rather than by file index.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "pneuma/mesh/io/mesh_io.h"

#include "test_support.h"

using pneuma::test::read_text;
using pneuma::test::run_pneuma;
using pneuma::test::TempDir;
namespace fs = std::filesystem;

namespace {

std::string scenario(const std::string& format, const std::string& mesh) {
  return "duration: 2 s\nframes: {rate: 10 Hz}\n" + mesh +
         "\nphysiology: {preset: healthy-adult}\n"
         "outputs: {png: false, mesh_sequence: {format: " +
         format + ", every: 5}}\n";
}

// The files of `folder` whose name starts with `prefix` and ends with `.<format>`, sorted.
std::vector<std::string> frame_files(const fs::path& folder, const std::string& prefix, const std::string& format) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(folder)) {
    const std::string name = e.path().filename().string();
    if (name.starts_with(prefix) && name.ends_with("." + format)) names.push_back(name);
  }
  std::sort(names.begin(), names.end());
  return names;
}

// Checks `<prefix>.<format>.series` against the frames written: every file once, in order, at
// index / 10 Hz seconds (every 5th of 21 frames: 0, 0.5, 1, 1.5, 2 s).
void expect_series(const fs::path& frames, const std::string& prefix, const std::string& format) {
  const auto index = nlohmann::json::parse(read_text(frames / (prefix + "." + format + ".series")));
  EXPECT_EQ(index["file-series-version"], "1.0");
  const std::vector<std::string> written = frame_files(frames, prefix + "_", format);
  ASSERT_EQ(written.size(), 5u);
  ASSERT_EQ(index["files"].size(), written.size());
  for (std::size_t i = 0; i < written.size(); ++i) {
    EXPECT_EQ(index["files"][i]["name"], written[i]);
    EXPECT_NEAR(index["files"][i]["time"].get<double>(), 0.5 * static_cast<double>(i), 1e-12) << written[i];
  }
}

}  // namespace

TEST(MeshSeries, EachFormatHasItsSeriesIndexInSeconds) {
  for (const std::string format : {"ply", "stl", "obj"}) {
    TempDir dir;
    const auto file = dir.write("s.yaml", scenario(format, "mesh: {phantom: right, edge: 12 mm}"));
    const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    expect_series(dir / "out/frames", "frame", format);
    const auto manifest = nlohmann::json::parse(read_text(dir / "out/manifest.json"));
    const auto listed = std::any_of(manifest["files"].begin(), manifest["files"].end(),
                                    [&](const auto& f) { return f["path"] == "frames/frame." + format + ".series"; });
    EXPECT_TRUE(listed) << "the index is in the manifest";
  }
}

TEST(MeshSeries, TwoLungsHaveOneIndexEach) {
  TempDir dir;
  const auto file = dir.write("s.yaml", scenario("ply", "mesh: {phantom: both, edge: 12 mm}"));
  const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_series(dir / "out/frames", "right", "ply");
  expect_series(dir / "out/frames", "left", "ply");
}

// ParaView itself (pvpython, from scripts/install-deps; a missing one fails in CI) opens the index
// with its times in seconds.
TEST(MeshSeries, ParaViewReadsTheIndexWithTimesInSeconds) {
  const fs::path pvpython = pneuma::test::find_program({"pvpython"});
  PNEUMA_REQUIRE_CLIENT(pvpython, "pvpython (Debian: apt-get install paraview python3-paraview)");
  TempDir dir;
  const auto file = dir.write("s.yaml", scenario("ply", "mesh: {phantom: right, edge: 12 mm}"));
  ASSERT_EQ(run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"}).exit_code, 0);
  const auto script = dir.write("open.py", "import sys\n"
                                           "from paraview.simple import OpenDataFile\n"
                                           "r = OpenDataFile(sys.argv[1])\n"
                                           "r.UpdatePipeline(r.TimestepValues[-1])\n"
                                           "print(' '.join('%g' % t for t in r.TimestepValues), "
                                           "r.GetDataInformation().GetNumberOfPoints())\n");
  const auto r = pneuma::test::run_program(pvpython, {script.string(), (dir / "out/frames/frame.ply.series").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "0 0.5 1 1.5 2 642\n");
}

// Frames are in millimetres by default and `unit: m` writes metres: the same lung either way
// (each read back in the unit it records), its numbers 1000 times apart.
TEST(MeshSeries, UnitChoosesMillimetresOrMetres) {
  TempDir dir;
  const std::string mesh = "mesh: {phantom: right, edge: 12 mm}";
  const auto mm = dir.write("mm.yaml", scenario("ply", mesh));
  std::string in_m = scenario("ply", mesh);
  in_m.replace(in_m.find("every: 5}"), 9, "every: 5, unit: m}");
  const auto m = dir.write("m.yaml", in_m);
  ASSERT_EQ(run_pneuma({"run", mm.string(), "-o", (dir / "mm").string(), "-q"}).exit_code, 0);
  ASSERT_EQ(run_pneuma({"run", m.string(), "-o", (dir / "m").string(), "-q"}).exit_code, 0);
  const auto a = dir / "mm/frames/frame_00010.ply", b = dir / "m/frames/frame_00010.ply";
  EXPECT_EQ(pneuma::mesh::recorded_unit(a), 1e-3);
  EXPECT_EQ(pneuma::mesh::recorded_unit(b), 1.0);
  const auto from_mm = pneuma::mesh::read_mesh(a), from_m = pneuma::mesh::read_mesh(b);
  const auto numbers = pneuma::mesh::read_mesh(a, {.metres_per_unit = 1.0, .unit_from_file = false});
  ASSERT_EQ(from_mm.vertex_count(), from_m.vertex_count());
  for (std::size_t i = 0; i < from_mm.vertex_count(); ++i) {
    EXPECT_LT((from_mm.vertices[i] - from_m.vertices[i]).norm(), 1e-7) << i;  // float32 of 0.1 m
    EXPECT_NEAR(numbers.vertices[i].norm(), 1e3 * from_m.vertices[i].norm(), 1e-4) << i;
  }
  std::string bad = scenario("ply", mesh);
  bad.replace(bad.find("every: 5}"), 9, "every: 5, unit: cm}");
  const auto r = run_pneuma({"run", dir.write("bad.yaml", bad).string(), "-o", (dir / "bad").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("outputs.mesh_sequence.unit"), std::string::npos) << r.err;
}
