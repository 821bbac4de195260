// Bad inputs that used to get through (#29): each is refused with one line naming the file and
// the place, the documented exit code, and the output folder as the previous run left it.
#include <gtest/gtest.h>

#include <map>
#include <string>

#include <nlohmann/json.hpp>

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
                       "chest_wall_fraction, compartments, compliance, driver, effort, model, output_rate, preset, "
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
