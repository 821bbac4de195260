// Bad inputs that used to get through (#29): each is refused with one line naming the file and
// the place, the documented exit code, and the output folder as the previous run left it.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "pneuma/mesh/geometry/triangle_mesh.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "test_support.h"

using pneuma::test::read_text;
using pneuma::test::run_pneuma;
using pneuma::test::TempDir;
namespace fs = std::filesystem;

namespace {

constexpr const char* kScenario = R"(duration: 2 s
frames: {rate: 10 Hz}
mesh: {phantom: right, edge: 12 mm, share: 55 %}
field: {tissue: healthy-upright}
physiology: {preset: healthy-adult}
outputs:
  mesh_sequence: {format: ply, every: 5}
  png: false
)";

// Every file under `folder` with its bytes.
std::map<std::string, std::string> snapshot(const fs::path& folder) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(folder)) {
    if (e.is_regular_file()) files[fs::relative(e.path(), folder).generic_string()] = read_text(e.path());
  }
  return files;
}

}  // namespace

// A name JSON cannot hold used to fail while the manifest was written, after the other outputs
// had been moved into the folder (exit 1, a mixed folder). It is refused at load, and the
// previous output stays byte for byte.
TEST(BadInputs, ANameThatIsNotUtf8IsRefusedAtLoadAndThePreviousOutputKept) {
  TempDir dir;
  const auto out = dir / "out";
  const auto good = run_pneuma({"run", dir.write("good.yaml", kScenario).string(), "-o", out.string(), "-q"});
  ASSERT_EQ(good.exit_code, 0) << good.err;
  const auto before = snapshot(out);
  const auto bad = dir.write("bad.yaml", std::string("name: \"lung \xff\xfe\"\n") + kScenario);
  const auto r = run_pneuma({"run", bad.string(), "-o", out.string(), "-q"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, bad.string() + ":1:13: expected UTF-8 text, got the byte \\xff\n");
  EXPECT_EQ(snapshot(out), before);
}

// A scenario file whose name is not UTF-8 (the run's name by default): the manifest holds it with
// U+FFFD in place of the bad byte, and the run succeeds.
TEST(BadInputs, AScenarioFileNameThatIsNotUtf8StillGivesAValidManifest) {
  TempDir dir;
  const auto file = dir.write("lung-\xff.yaml", kScenario);
  const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto manifest = nlohmann::json::parse(read_text(dir / "out/manifest.json"));
  EXPECT_EQ(manifest["scenario"]["name"].get<std::string>(), "lung-\xef\xbf\xbd");
}

// Bytes of the input that would not print (ESC, form feed) are quoted in the message.
TEST(BadInputs, ControlBytesFromTheInputAreQuotedInTheMessage) {
  TempDir dir;
  const auto file = dir.write("s.yaml", "duration: 2 s\nphysiology: {preset: healthy-adult, \"\x1b[31mred\x0c\": 1}\n");
  const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, file.string() +
                       ":2:37: physiology.\\x1b[31mred\\x0c: unknown key; expected one of: actions, "
                       "chest_wall_fraction, compartments, compliance, driver, effort, expiratory_resistance, "
                       "flow_limitation, model, output_rate, preset, "
                       "pressure_volume_curve, resistance, solver, transpulmonary_pressure_at_rest\n");
  EXPECT_FALSE(fs::exists(dir / "out"));
}

// A device never ends: refused before it is read, as a scenario and as a preset.
TEST(BadInputs, ADeviceIsRefusedAsAScenarioAndAsAPreset) {
  TempDir dir;
  const auto r = run_pneuma({"run", "/dev/zero", "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, "/dev/zero: not a regular file (a device, pipe or socket); expected a file\n");
  EXPECT_FALSE(fs::exists(dir / "out"));
  const auto file = dir.write("s.yaml", "duration: 2 s\nphysiology: {preset: /dev/zero}\n");
  const auto p = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(p.exit_code, 3) << p.err;
  EXPECT_EQ(std::count(p.err.begin(), p.err.end(), '\n'), 1) << p.err;
  EXPECT_NE(p.err.find("/dev/zero"), std::string::npos) << p.err;
  EXPECT_FALSE(fs::exists(dir / "out"));
}

namespace {

struct TooBig {
  const char* name;
  const char* yaml;
  const char* message;  // after "<file>"
};

// Nothing in `folder` (it may not exist: a scenario refused at load; or be empty: refused while
// the model is compiled, before any output).
bool holds_nothing(const fs::path& folder) { return !fs::exists(folder) || fs::is_empty(folder); }

}  // namespace

class RunTooBig : public ::testing::TestWithParam<TooBig> {};

// What cannot finish (hours of frames, millions of vertices) is refused up front with the numbers.
TEST_P(RunTooBig, RefusedUpFrontWithTheNumbers) {
  TempDir dir;
  pneuma::test::run_pneuma({"phantom", "--lung", "right", "--edge", "12mm", "-o", (dir / "mm.ply").string()});
  const auto file = dir.write("s.yaml", GetParam().yaml);
  const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, file.string() + GetParam().message + "\n");
  EXPECT_TRUE(holds_nothing(dir / "out"));
}

INSTANTIATE_TEST_SUITE_P(
    Cases, RunTooBig,
    ::testing::Values(
        TooBig{"duration", "duration: 1e9 s\nphysiology: {preset: healthy-adult}\n",
               ":1:11: duration: expected at most 86400 s (one day), got 1e+09 s"},
        TooBig{"duration_1e308", "duration: 1e308 s\nphysiology: {preset: healthy-adult}\n",
               ":1:11: duration: expected at most 86400 s (one day), got 1e+308 s"},
        TooBig{"frame_rate", "duration: 4 s\nframes: {rate: 1e9 Hz}\nphysiology: {preset: healthy-adult}\n",
               ":2:16: frames.rate: 4e+09 frames (4 s at 1e+09 Hz); expected at most 1000000: lower frames.rate or "
               "the duration"},
        TooBig{"frame_rate_by_duration",
               "duration: 20000 s\nframes: {rate: 100 Hz}\nphysiology: {preset: healthy-adult}\n",
               ":2:16: frames.rate: 2e+06 frames (20000 s at 100 Hz); expected at most 1000000: lower frames.rate or "
               "the duration"},
        TooBig{"output_rate", "duration: 100 s\nphysiology: {preset: healthy-adult, output_rate: 1e9 Hz}\n",
               ":2:50: physiology.output_rate: 1e+11 physiology samples (100 s at 1e+09 Hz); expected at most "
               "10000000: lower physiology.output_rate or the duration"},
        TooBig{"edge", "duration: 4 s\nmesh: {phantom: right, edge: 0.1 mm}\nphysiology: {preset: healthy-adult}\n",
               ": mesh.edge: a surface of 0.07417 m2 at an edge of 0.1 mm would have about 8.56e+06 vertices; "
               "expected at most 2000000 (a coarser edge)"},
        // A file in millimetres read as metres is refused by its extent first (ASurfaceFarLargerThanALung...).
        TooBig{"file_edge", "duration: 4 s\nmesh: {file: mm.ply, edge: 0.1 mm}\nphysiology: {preset: healthy-adult}\n",
               ": mesh.edge: a surface of 0.07384 m2 at an edge of 0.1 mm would have about 8.53e+06 vertices; "
               "expected at most 2000000 (a coarser edge)"}),
    [](const auto& test_case) { return std::string(test_case.param.name); });

// Options out of range are usage errors (exit 2), refused before anything is read or written.
TEST(BadInputs, OptionsOutOfRangeAreUsageErrors) {
  TempDir dir;
  const auto file = dir.write("s.yaml", kScenario);
  for (const std::string edge : {"-1", "0", "1e-308", "0.01"}) {
    const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q", "--edge", edge + "mm"});
    EXPECT_EQ(r.exit_code, 2) << edge;
    EXPECT_EQ(r.err, "pneuma: --edge: expected an edge of at least 0.1 mm, got " + edge + " mm\n");
  }
  for (const char* values : {"", "0", "3,-1"}) {
    const auto labels =
        run_pneuma({"mesh", "from-labels", file.string(), "--labels", values, "-o", (dir / "out.ply").string()});
    EXPECT_EQ(labels.exit_code, 2) << values;
    EXPECT_EQ(labels.err, "pneuma: --labels: expected label values of 1 or more, such as 3,4,5\n") << values;
  }
  EXPECT_EQ(dir.files(), std::vector<std::string>{"s.yaml"});
}

namespace {

struct OutOfRange {
  const char* name;
  const char* yaml;
  const char* message;  // after "<dir>/"
};

}  // namespace

class RunOutOfRange : public ::testing::TestWithParam<OutOfRange> {};

// Lung parameters, solver tolerances and shear moduli at 1e308 or 1e-320 are refused at load, at
// their key in the file that gives them (CVODE or the field failed later without naming it).
TEST_P(RunOutOfRange, RefusedAtTheKeyInItsFile) {
  TempDir dir;
  std::string tissue = read_text(pneuma::test::source_dir() / "configs/tissue/healthy-upright.yaml");
  tissue.replace(tissue.find("apex: 3 kPa"), 11, "apex: 1e308 kPa");
  dir.write("stiff.yaml", tissue);
  const auto file = dir.write("s.yaml", GetParam().yaml);
  const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, (dir / GetParam().message).string() + "\n");
  EXPECT_FALSE(fs::exists(dir / "out"));
}

INSTANTIATE_TEST_SUITE_P(
    Cases, RunOutOfRange,
    ::testing::Values(
        OutOfRange{"compliance", "duration: 4 s\nphysiology: {preset: healthy-adult, compliance: 1e308 L/cmH2O}\n",
                   "s.yaml:2:49: physiology.compliance: expected a compliance from 0.001 to 10 L/cmH2O, got '1e308 "
                   "L/cmH2O'"},
        OutOfRange{"resistance",
                   "duration: 4 s\nphysiology:\n  preset: healthy-adult\n  resistance: 1e-320 cmH2O*s/L\n",
                   "s.yaml:4:15: physiology.resistance: expected a resistance from 0.1 to 1000 cmH2O*s/L, got "
                   "'1e-320 cmH2O*s/L'"},
        OutOfRange{"relative_tolerance",
                   "duration: 4 s\nphysiology:\n  preset: healthy-adult\n  solver: {relative_tolerance: 1e-320, "
                   "absolute_tolerance: 1e-9 L}\n",
                   "s.yaml:4:32: physiology.solver.relative_tolerance: expected a relative tolerance from 1e-12 to "
                   "0.1, got '1e-320'"},
        OutOfRange{"absolute_tolerance",
                   "duration: 4 s\nphysiology:\n  preset: healthy-adult\n  solver: {relative_tolerance: 1e-6, "
                   "absolute_tolerance: 1e308 L}\n",
                   "s.yaml:4:58: physiology.solver.absolute_tolerance: expected an absolute tolerance from 1e-12 L to "
                   "0.1 L, got '1e308 L'"},
        OutOfRange{"shear_modulus", "duration: 4 s\nfield: {tissue: stiff.yaml}\nphysiology: {preset: healthy-adult}\n",
                   "stiff.yaml:25:18: stiffness.moduli.apex: expected a shear modulus from 1 Pa to 1 GPa, got '1e308 "
                   "kPa'"}),
    [](const auto& test_case) { return std::string(test_case.param.name); });

// A surface the field cannot enlarge (its normals inward) is named by its file, not as "mesh".
TEST(BadInputs, AnInwardSurfaceIsNamedByItsFile) {
  TempDir dir;
  ASSERT_EQ(run_pneuma({"phantom", "--lung", "right", "--edge", "12mm", "-o", (dir / "r.obj").string()}).exit_code, 0);
  std::istringstream in(read_text(dir / "r.obj"));
  std::string flipped;
  for (std::string line; std::getline(in, line);) {
    if (line.starts_with("f ")) {
      std::istringstream face(line.substr(2));
      std::string a, b, c;
      face >> a >> b >> c;
      line = "f ";
      line.append(a).append(" ").append(c).append(" ").append(b);
    }
    flipped += line + "\n";
  }
  dir.write("inward.obj", flipped);
  const auto file = dir.write("s.yaml", "duration: 2 s\nmesh: {file: inward.obj, repair: false}\nphysiology: {preset: "
                                        "healthy-adult}\noutputs: {png: false}\n");
  const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 5);
  EXPECT_EQ(r.err, (dir / "inward.obj").string() +
                       ": pushing every vertex outward along its displacement direction does not increase the surface "
                       "area (is the mesh oriented with its normals outward?)\n");
  EXPECT_TRUE(holds_nothing(dir / "out"));
}

TEST(BadInputs, AMeshEdgeBelowATenthOfAMillimetreIsRefusedAtItsKey) {
  TempDir dir;
  const auto file = dir.write(
      "s.yaml", "duration: 2 s\nmesh: {phantom: right, edge: 1e-308 mm}\nphysiology: {preset: healthy-adult}\n");
  const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, file.string() + ":2:30: mesh.edge: expected an edge of at least 0.1 mm, got '1e-308 mm'\n");
  EXPECT_FALSE(fs::exists(dir / "out"));
}

// mesh.breath (#45): a moment by its name or a volume above FRC with its unit, else one line at
// the key saying what it takes; its older name reference_volume takes a volume only, and not both.
TEST(BadInputs, ABreathThatIsNeitherAMomentNorAVolumeIsRefusedAtItsKey) {
  TempDir dir;
  const std::string takes = "expected end_inspiration, end_expiration or a volume above FRC with its unit from 0 to "
                            "10 L, such as '500 mL'\n";
  for (const auto& [value, expected] : {std::pair<std::string, std::string>{"end_inhale", takes},
                                        {"500", takes},
                                        {"500 mm", takes},
                                        {"-20 mL", takes},
                                        {"11 L", takes},
                                        {"[500 mL]", takes}}) {
    SCOPED_TRACE(value);
    const auto file = dir.write("s.yaml", "duration: 2 s\nmesh: {phantom: right, breath: " + value +
                                              "}\nphysiology: {preset: healthy-adult}\n");
    const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"});
    EXPECT_EQ(r.exit_code, 3);
    EXPECT_EQ(r.err, file.string() + ":2:32: mesh.breath: " + expected);
    EXPECT_FALSE(fs::exists(dir / "out"));
  }
  const auto both = dir.write("both.yaml", "duration: 2 s\nmesh: {phantom: right, breath: end_inspiration, "
                                           "reference_volume: 100 mL}\nphysiology: {preset: healthy-adult}\n");
  const auto r = run_pneuma({"run", both.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, both.string() +
                       ":2:67: mesh.reference_volume: give either 'breath' or its older name 'reference_volume', not "
                       "both\n");
  const auto old = dir.write("old.yaml", "duration: 2 s\nmesh: {phantom: right, reference_volume: end_inspiration}\n"
                                         "physiology: {preset: healthy-adult}\n");
  const auto o = run_pneuma({"run", old.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(o.exit_code, 3);
  EXPECT_EQ(o.err, old.string() +
                       ":2:42: mesh.reference_volume: expected a volume above FRC with its unit from 0 to 10 L, such "
                       "as '500 mL'\n");
}

// A file that cannot be read for want of permission is reported as such, not as missing. As
// root (who reads everything), pneuma runs as nobody through setpriv.
TEST(BadInputs, PermissionDeniedIsReportedAsSuch) {
  std::vector<std::string> prefix;
  fs::path program;
  if (::geteuid() == 0) {
    const fs::path setpriv = pneuma::test::find_program({"setpriv"});
    if (setpriv.empty()) GTEST_SKIP() << "running as root without setpriv";
    prefix = {"--reuid", "65534", "--regid", "65534", "--clear-groups", PNEUMA_EXE};
    program = setpriv;
  }
  TempDir dir;
  fs::permissions(dir.path(), fs::perms::all);
  fs::create_directories(dir / "secret");
  dir.write("secret/lung.ply", "ply\n");
  fs::permissions(dir / "secret", fs::perms::owner_all);
  const auto yaml = "duration: 2 s\nmesh: {file: secret/lung.ply}\nphysiology: {preset: healthy-adult}\n";
  const auto readable = dir.write("m.yaml", yaml);
  const auto locked = dir.write("z.yaml", yaml);
  fs::permissions(locked, fs::perms::none);
  auto run = [&](const fs::path& scenario) {
    std::vector<std::string> args = prefix;
    args.insert(args.end(), {"run", scenario.string(), "-o", (dir / "out").string(), "-q"});
    return prefix.empty() ? run_pneuma(args) : pneuma::test::run_program(program, args);
  };
  const auto hidden = run(readable);
  EXPECT_EQ(hidden.exit_code, 3);
  EXPECT_EQ(hidden.err,
            readable.string() + ":2:14: mesh.file: permission denied: " + (dir / "secret/lung.ply").string() + "\n");
  const auto unreadable = run(locked);
  EXPECT_EQ(unreadable.exit_code, 4);
  EXPECT_EQ(unreadable.err, locked.string() + ": cannot open file: permission denied\n");
  fs::permissions(dir / "secret", fs::perms::owner_all | fs::perms::group_all | fs::perms::others_all);
}

// A key a physiology preset lacks (and the scenario does not give) is reported at the scenario's
// `preset:` line, naming the preset file.
TEST(BadInputs, AKeyMissingInAPhysiologyPresetIsReportedAtThePresetLine) {
  TempDir dir;
  const std::string preset = read_text(pneuma::test::source_dir() / "configs/physiology/healthy-adult.yaml");
  const auto line = preset.find("\nresistance:");
  ASSERT_NE(line, std::string::npos);
  dir.write("p.yaml", preset.substr(0, line) + preset.substr(preset.find('\n', line + 1)));
  const auto file = dir.write("s.yaml", "duration: 2 s\nphysiology:\n  preset: p.yaml\n");
  const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, file.string() + ":3:11: physiology.preset: " + (dir / "p.yaml").string() +
                       ": missing key 'resistance' (expected a resistance such as '2 cmH2O*s/L'), and physiology "
                       "does not give it either\n");
  EXPECT_FALSE(fs::exists(dir / "out"));
}

// A NUL byte of the input is quoted as \x00 like any other unprintable byte; it used to end the
// message there.
TEST(BadInputs, ANulByteIsQuotedAndTheMessageGoesOn) {
  TempDir dir;
  const auto file =
      dir.write("s.yaml", std::string("duration: 2 s\nphysiology: {preset: healthy-adult, \"ab") + '\0' + "cd\": 1}\n");
  const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, file.string() +
                       ":2:37: physiology.ab\\x00cd: unknown key; expected one of: actions, "
                       "chest_wall_fraction, compartments, compliance, driver, effort, expiratory_resistance, "
                       "flow_limitation, model, output_rate, preset, "
                       "pressure_volume_curve, resistance, solver, transpulmonary_pressure_at_rest\n");
  EXPECT_FALSE(fs::exists(dir / "out"));
}

// `mesh remesh` and `mesh from-labels` refuse up front, with the numbers, what could not finish:
// millions of vertices, a blur wider than the whole label map (they ran for minutes).
TEST(BadInputs, MeshCommandsThatCannotFinishAreRefusedUpFront) {
  TempDir dir;
  const auto ply = dir / "r.ply";
  ASSERT_EQ(run_pneuma({"phantom", "--lung", "right", "--edge", "12mm", "-o", ply.string()}).exit_code, 0);
  // The finest edge any command takes (0.1 mm), still millions of vertices on a lung.
  const auto remesh = run_pneuma({"mesh", "remesh", ply.string(), "--edge", "0.1mm", "-o", (dir / "o.ply").string()});
  EXPECT_EQ(remesh.exit_code, 2);
  // The estimate against the area of the file as read here: equilateral triangles, two per vertex.
  const double area_m2 = pneuma::mesh::surface_area(pneuma::mesh::read_mesh(ply));
  EXPECT_EQ(remesh.err, fmt::format("pneuma: --edge: {}: a surface of {:.4g} cm2 at an edge of 0.1 mm would have "
                                    "about {:.3g} vertices; expected at most 2000000 (a coarser edge)\n",
                                    ply.string(), area_m2 * 1e4, 2.0 * area_m2 / (std::sqrt(3.0) * 0.1e-3 * 0.1e-3)));
  // 12 x 12 x 12 voxels of 2 mm: 24 mm at the widest, a sigma of at most 8 mm.
  const auto nii = pneuma::test::source_dir() / "fuzz/corpus/nifti/blocks-uint8.nii";
  const auto smooth = run_pneuma(
      {"mesh", "from-labels", nii.string(), "--labels", "1", "--smooth", "1e308mm", "-o", (dir / "s.ply").string()});
  EXPECT_EQ(smooth.exit_code, 2);
  EXPECT_EQ(smooth.err, "pneuma: " + nii.string() +
                            ": smoothing: a sigma of 1e+308 mm blurs beyond the whole label map (12 x 12 x 12 "
                            "voxels, 24 mm at its widest); expected at most 8 mm (a third of its widest side)\n");
  const auto closing = run_pneuma(
      {"mesh", "from-labels", nii.string(), "--labels", "1", "--closing", "1e9mm", "-o", (dir / "s.ply").string()});
  EXPECT_EQ(closing.exit_code, 2);
  EXPECT_EQ(closing.err, "pneuma: " + nii.string() +
                             ": closing: a radius of 1e+09 mm is beyond the whole label map (12 x 12 x 12 voxels, "
                             "24 mm at its widest); expected at most 24 mm\n");
  const auto edge = run_pneuma(
      {"mesh", "from-labels", nii.string(), "--labels", "1", "--edge", "1e-6mm", "-o", (dir / "s.ply").string()});
  // Below every command's finest edge (this map's labels are too small for the size check at 0.1 mm).
  EXPECT_EQ(edge.exit_code, 2);
  EXPECT_EQ(edge.err, "pneuma: --edge: expected an edge of at least 0.1 mm, got 1e-06 mm\n");
  EXPECT_EQ(dir.files(), std::vector<std::string>{"r.ply"});
}

// A ventilator's pressures far beyond any breath are refused at their key (peep: 1e308 cmH2O
// ended in exit 1, "CVODE failed ... at the first call"; found by scripts/mutate).
TEST(BadInputs, AVentilatorPressureOutOfRangeIsRefusedAtItsKey) {
  TempDir dir;
  std::string text = read_text(pneuma::test::source_dir() / "scenarios/ventilator-pc-ac.yaml");
  const auto at = text.find("peep: 6 cmH2O");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, 13, "peep: 1e308 cmH2O");
  const auto file = dir.write("s.yaml", text);
  const auto value = at + 6;  // where '1e308' starts: line and column counted here
  const auto line = std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(value), '\n') + 1;
  const auto column = value - text.rfind('\n', value);
  const auto r = run_pneuma({"simulate", file.string(), "-o", (dir / "t.csv").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, fmt::format("{}:{}:{}: physiology.driver.peep: expected a pressure from -200 to 200 cmH2O, got "
                               "'1e308 cmH2O'\n",
                               file.string(), line, column));
  EXPECT_EQ(dir.files(), std::vector<std::string>{"s.yaml"});
}

// A pressure-volume curve far beyond any lung is refused at its key in the preset that gives it
// (volume_range: 2.2e300 L ended in exit 1, CVODE's first call; found by scripts/mutate).
TEST(BadInputs, APressureVolumeCurveOutOfRangeIsRefusedAtItsKeyInThePreset) {
  TempDir dir;
  std::string preset = read_text(pneuma::test::source_dir() / "configs/physiology/stiff-lung.yaml");
  const auto at = preset.find("volume_range: 2.2 L");
  ASSERT_NE(at, std::string::npos);
  preset.replace(at, 19, "volume_range: 2.2e300 L");
  dir.write("p.yaml", preset);
  const auto value = at + 14;  // where '2.2e300' starts
  const auto line = std::count(preset.begin(), preset.begin() + static_cast<std::ptrdiff_t>(value), '\n') + 1;
  const auto column = value - preset.rfind('\n', value);
  const auto file = dir.write("s.yaml", "duration: 2 s\nframes: {rate: 5 Hz}\nmesh: {phantom: right, edge: 10 mm}\n"
                                        "physiology: {preset: ./p.yaml}\n");
  const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3);
  // Named as the scenario names it (./p.yaml), at the preset's line and column.
  EXPECT_EQ(r.err, fmt::format("{}:{}:{}: physiology.pressure_volume_curve.volume_range: expected a volume of at "
                               "most 10 L, got '2.2e300 L'\n",
                               (dir / "./p.yaml").string(), line, column));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1);
  EXPECT_FALSE(std::filesystem::exists(dir / "out"));
}

// A breathing rate of a breath a year is refused at its key (rate: 1.2e-05 /min ran for hours:
// the tidal-volume calibration integrates eight whole breaths; found by scripts/mutate).
TEST(BadInputs, ABreathingRateOutOfRangeIsRefusedAtItsKey) {
  TempDir dir;
  const std::string text =
      "duration: 2 s\nframes: {rate: 5 Hz}\nmesh: {phantom: right, edge: 10 mm}\n"
      "physiology:\n  preset: healthy-adult\n  driver: {mode: spontaneous, rate: 1.2e-05 /min, tidal_volume: 500 mL}\n";
  const auto file = dir.write("s.yaml", text);
  const auto value = text.find("1.2e-05");
  const auto line = std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(value), '\n') + 1;
  const auto column = value - text.rfind('\n', value);
  const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, fmt::format("{}:{}:{}: physiology.driver.rate: expected a rate from 1 /min to 200 /min, got "
                               "'1.2e-05 /min'\n",
                               file.string(), line, column));
  EXPECT_EQ(dir.files(), std::vector<std::string>{"s.yaml"});
}

// A smoothing far below a voxel is no smoothing (--smooth 1e-308mm hung in Mesh_3: the kernel's
// sigma squared underflowed to 0 and its weights became NaN; found by scripts/mutate): the same
// surface as --smooth 0mm, byte for byte.
TEST(BadInputs, ASmoothingFarBelowAVoxelIsNoSmoothing) {
  TempDir dir;
  const auto nii = pneuma::test::source_dir() / "fuzz/corpus/nifti/blocks-uint8.nii";
  for (const char* sigma : {"0mm", "1e-308mm"}) {
    const auto r = run_pneuma({"mesh", "from-labels", nii.string(), "--labels", "1", "--smooth", sigma, "-o",
                               (dir / (std::string(sigma) + ".ply")).string()});
    ASSERT_EQ(r.exit_code, 0) << sigma << ": " << r.err;
  }
  EXPECT_EQ(read_text(dir / "0mm.ply"), read_text(dir / "1e-308mm.ply"));
}

// A surface kilometres across is not a lung: refused before remeshing (a damaged STL with one
// vertex at z = 11 km ran for hours in CGAL's isotropic remeshing; found by scripts/mutate).
TEST(BadInputs, ASurfaceFarLargerThanALungIsRefusedBeforeRemeshing) {
  TempDir dir;
  // An octahedron 0.2 m across with its top vertex pulled to 2 km.
  const auto obj = dir.write("far.obj", "v 0.1 0 0\nv -0.1 0 0\nv 0 0.1 0\nv 0 -0.1 0\nv 0 0 2000\nv 0 0 -0.1\n"
                                        "f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n");
  const auto file =
      dir.write("s.yaml", "duration: 2 s\nframes: {rate: 5 Hz}\nmesh: {file: far.obj, unit: m, edge: 10 mm}\n"
                          "physiology: {preset: healthy-adult}\n");
  const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err,
            fmt::format("{}: the surface spans 2000 m along z (0.2 x 0.2 x 2000 m); expected a lung, at most 1 m "
                        "across (is mesh.unit right, or a vertex damaged?)\n",
                        (dir / "far.obj").string()));
  EXPECT_EQ(dir.files(), (std::vector<std::string>{"far.obj", "s.yaml"}));
  // `mesh remesh` too (a damaged STL like it took 21.7 GB there; found by scripts/mutate).
  const auto remesh = run_pneuma(
      {"mesh", "remesh", obj.string(), "--unit", "m", "--edge", "12mm", "-o", (dir / "remeshed.ply").string()});
  EXPECT_EQ(remesh.exit_code, 3);
  EXPECT_EQ(remesh.err, fmt::format("{}: the surface spans 2000 m along z (0.2 x 0.2 x 2000 m); expected a lung, at "
                                    "most 1 m across (is --unit right, or a vertex damaged?)\n",
                                    obj.string()));
  EXPECT_EQ(dir.files(), (std::vector<std::string>{"far.obj", "s.yaml"}));
  // The usual cause: a file in millimetres declared in metres (the phantom, 243 mm tall).
  const auto ply = dir / "mm.ply";
  ASSERT_EQ(run_pneuma({"phantom", "--lung", "right", "--edge", "12mm", "-o", ply.string()}).exit_code, 0);
  const auto mm = dir.write("mm.yaml", "duration: 2 s\nmesh: {file: mm.ply, unit: m, edge: 4 mm}\n"
                                       "physiology: {preset: healthy-adult}\n");
  const auto m = run_pneuma({"run", mm.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(m.exit_code, 3);
  EXPECT_EQ(m.err, ply.string() + ": the surface spans 242.9 m along z (92.48 x 140.5 x 242.9 m); expected a lung, at "
                                  "most 1 m across (is mesh.unit right, or a vertex damaged?)\n");
  EXPECT_TRUE(!std::filesystem::exists(dir / "out") || std::filesystem::is_empty(dir / "out"));
}

// A file unit near the smallest doubles is refused (mesh remesh --unit 1e-308mm crashed in CGAL's
// remeshing, whose squared lengths underflowed; found by scripts/mutate), on the command line and
// in a scenario.
TEST(BadInputs, AFileUnitOutsideANanometreToAKilometreIsRefused) {
  TempDir dir;
  const auto ply = dir / "r.ply";
  ASSERT_EQ(run_pneuma({"phantom", "--lung", "right", "--edge", "12mm", "-o", ply.string()}).exit_code, 0);
  for (const char* unit : {"1e-308mm", "1e9m"}) {
    const auto r =
        run_pneuma({"mesh", "remesh", ply.string(), "--edge", "12mm", "--unit", unit, "-o", (dir / "o.ply").string()});
    EXPECT_EQ(r.exit_code, 2) << unit;
    EXPECT_EQ(r.err, std::string("pneuma: --unit: expected a length unit from 1 nm to 1 km, got '") + unit + "'\n");
  }
  const auto file = dir.write("s.yaml", "duration: 2 s\nmesh: {file: r.ply, unit: 1e-308 mm, edge: 12 mm}\n"
                                        "physiology: {preset: healthy-adult}\n");
  const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, file.string() + ":2:27: mesh.unit: expected a length unit from 1 nm to 1 km, got '1e-308 mm'\n");
  EXPECT_EQ(dir.files(), (std::vector<std::string>{"r.ply", "s.yaml"}));
}

// A NaN or a huge number in a NIfTI's orientation, or a fractional data offset, is refused before
// ITK sees it (they aborted or hung in ITK's SVD of the direction matrix, or made niftilib warn;
// found by scripts/mutate).
TEST(BadInputs, ANiftiOrientationThatIsNotFiniteIsRefused) {
  // Each case: the corpus' block map with a float written at a header offset, and the message.
  struct Case {
    std::size_t offset;
    float value;
    std::string message;
  };
  const std::vector<Case> cases{
      {320, std::numeric_limits<float>::quiet_NaN(),  // srow_z[2]: aborted in ITK's SVD
       ": srow_z is nan: expected a finite number of magnitude at most 1e6 (the voxel -> world orientation)"},
      {304, -1.7014118e38f,  // srow_y[2]: ITK's SVD ran for ever
       ": srow_y is -1.70141e+38: expected a finite number of magnitude at most 1e6 (the voxel -> world "
       "orientation)"},
      {108, 352.016f, ": vox_offset is 352.016: expected a whole number of bytes"},  // niftilib warned on stderr
      {320, 4.3368087e-19f,  // srow_z[2]: the smoothing kernel would have been 1e18 voxels wide
       ": the voxel size along axis 3 (sform) is 4.33681e-19 mm: expected at least 0.001 mm"},
  };
  for (const Case& c : cases) {
    TempDir dir;
    std::string bytes = read_text(pneuma::test::source_dir() / "fuzz/corpus/nifti/blocks-uint8.nii");
    ASSERT_GE(bytes.size(), 348u);
    const std::int16_t sform_code = 1;
    std::memcpy(bytes.data() + 254, &sform_code, sizeof sform_code);  // little-endian, as the corpus file
    std::memcpy(bytes.data() + c.offset, &c.value, sizeof c.value);
    const auto nii = dir.write("l.nii", bytes);
    const auto r = run_pneuma({"mesh", "from-labels", nii.string(), "--labels", "1", "-o", (dir / "s.ply").string()});
    EXPECT_EQ(r.exit_code, 3) << c.message;
    EXPECT_EQ(r.err, nii.string() + c.message + "\n");
    EXPECT_EQ(dir.files(), std::vector<std::string>{"l.nii"});
  }
}

// A preset that cannot be read (EIO from /proc/self/mem) is a file error naming it, not an
// internal error (found by scripts/mutate).
TEST(BadInputs, AFileThatFailsToReadIsAnIoError) {
  TempDir dir;
  const auto file = dir.write("s.yaml", "duration: 2 s\nmesh: {phantom: right, edge: 10 mm}\n"
                                        "physiology: {preset: /proc/self/mem}\n");
  const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 4);
  EXPECT_EQ(r.err, "/proc/self/mem: cannot read file (an input/output error)\n");
  EXPECT_EQ(dir.files(), std::vector<std::string>{"s.yaml"});
}

// #49: a key given twice is refused at the second (yaml-cpp answered with the first, and a
// cohort's second subject of one id vanished), in every YAML input; a byte-order mark is read as
// nothing; a value of 10 MB is quoted as its first 80 bytes with the total.
TEST(BadInputs, DuplicateKeysByteOrderMarksAndLongValues) {
  TempDir dir;
  const auto twice = dir.write("twice.yaml", std::string(kScenario) + "duration: 3 s\n");
  auto r = run_pneuma({"run", twice.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, twice.string() + ":9:1: duration: given twice (first at line 1): expected each key once\n");
  const auto nested = dir.write("nested.yaml", "duration: 2 s\nphysiology: {preset: healthy-adult, preset: x}\n");
  r = run_pneuma({"run", nested.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err,
            nested.string() + ":2:37: physiology.preset: given twice (first at line 2): expected each key once\n");
  EXPECT_FALSE(fs::exists(dir / "out"));

  const auto bom = dir.write("bom.yaml", "\xEF\xBB\xBF" + std::string(kScenario));
  r = run_pneuma({"run", bom.string(), "-o", (dir / "bom").string(), "-q"});
  EXPECT_EQ(r.exit_code, 0) << r.err;

  // A 10 MB value, as the issue found it (a message must not quote it whole).
  const std::string ten_megabytes(10000000, '7');  // NOLINT(bugprone-string-constructor): that large on purpose
  const auto long_value = dir.write("long.yaml", "duration: " + ten_megabytes + "x\n");
  r = run_pneuma({"run", long_value.string(), "-o", (dir / "out").string(), "-q"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, long_value.string() + ":1:11: duration: expected a duration such as '2 s', got '" +
                       std::string(80, '7') + "...' (10000001 bytes)\n");
  EXPECT_FALSE(fs::exists(dir / "out"));
}
