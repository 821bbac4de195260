// report.html (#18): what `pneuma run` embeds, checked against the run's other files, and the
// page itself in headless Chromium (its self-test hook, docs/formats.md).
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>

#include "pneuma/image/label_map.h"
#include "pneuma/outputs/report.h"
#include "pneuma/voxels/grid.h"
#include "pneuma/voxels/voxel_io.h"
#include "runner_fixture.h"
#include "test_support.h"

using pneuma::test::read_text;
using pneuma::test::run_pneuma;
using pneuma::test::TempDir;

namespace {

// 4 s of quiet breathing at 10 frames/s on a 12 mm phantom: one complete breath.
std::string small_scenario(const std::string& outputs, const std::string& output_rate = "100 Hz") {
  return R"(name: small <report> & "test"
description: A short run for the report's tests.
duration: 4 s
frames: {rate: 10 Hz}
mesh: {phantom: right, edge: 12 mm, share: 55 %}
field: {tissue: healthy-upright}
physiology:
  preset: healthy-adult
  output_rate: )" +
         output_rate + R"(
  driver: {mode: spontaneous, rate: 15 /min, ie_ratio: 1:2, tidal_volume: 500 mL}
outputs: )" +
         outputs + "\n";
}

// The text between `open` and the next `close` after it.
std::string between(const std::string& text, const std::string& open, const std::string& close) {
  const auto a = text.find(open);
  if (a == std::string::npos) return {};
  const auto b = text.find(close, a + open.size());
  if (b == std::string::npos) return {};
  return text.substr(a + open.size(), b - a - open.size());
}

std::size_t occurrences(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + what.size())) ++n;
  return n;
}

// RFC 4648 base64, written here independently of the encoder under test.
std::string decode_base64(const std::string& text) {
  auto value = [](char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
  };
  std::string out;
  unsigned bits = 0;
  int count = 0;
  for (char c : text) {
    if (c == '=') break;
    const int v = value(c);
    if (v < 0) continue;
    bits = (bits << 6) | static_cast<unsigned>(v);
    count += 6;
    if (count >= 8) {
      count -= 8;
      out += static_cast<char>((bits >> count) & 0xFF);
    }
  }
  return out;
}

struct Csv {
  std::vector<std::string> header;
  std::vector<std::vector<double>> rows;
  std::size_t column(const std::string& name) const {
    for (std::size_t i = 0; i < header.size(); ++i) {
      if (header[i] == name) return i;
    }
    ADD_FAILURE() << "no column " << name;
    return 0;
  }
};

Csv read_csv(const std::filesystem::path& path) {
  Csv csv;
  std::ifstream in(path);
  std::string line;
  auto split = [](const std::string& l) {
    std::vector<std::string> cells;
    std::stringstream s(l);
    for (std::string cell; std::getline(s, cell, ',');) cells.push_back(cell);
    return cells;
  };
  std::getline(in, line);
  csv.header = split(line);
  while (std::getline(in, line)) {
    std::vector<double> row;
    for (const auto& cell : split(line)) {
      char* end = nullptr;
      const double value = std::strtod(cell.c_str(), &end);
      row.push_back(end != cell.c_str() ? value : NAN);  // text cells (region names) as NaN
    }
    csv.rows.push_back(row);
  }
  return csv;
}

// NOLINTNEXTLINE(bugprone-exception-escape): reached inside nlohmann::json (other_error), not from here
struct Page {
  std::string html;
  nlohmann::json data;
  std::string glb;
};

Page read_page(const std::filesystem::path& path) {
  Page page;
  page.html = read_text(path);
  page.data =
      nlohmann::json::parse(between(page.html, R"(<script type="application/json" id="pneuma-data">)", "</script>"));
  page.glb =
      decode_base64(between(page.html, R"(<script type="application/octet-stream" id="pneuma-glb">)", "</script>"));
  return page;
}

// The page must hold everything: no external script, style, image or frame, no CDN.
void expect_self_contained(const std::string& html) {
  EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_EQ(occurrences(html, "<script src"), 0u);
  EXPECT_EQ(occurrences(html, "<link"), 0u);
  EXPECT_EQ(occurrences(html, "<iframe"), 0u);
  EXPECT_EQ(occurrences(html, "<img"), 0u);
  EXPECT_EQ(occurrences(html, R"(id="pneuma-data")"), 1u);
  EXPECT_EQ(occurrences(html, R"(id="pneuma-glb")"), 1u);
  EXPECT_EQ(occurrences(html, R"(<pre id="selftest">)"), 1u);
  EXPECT_EQ(occurrences(html, "@GLB_BASE64@"), 0u) << "a placeholder was left";
  EXPECT_EQ(occurrences(html, "@DATA_JSON@"), 0u);
  EXPECT_NE(html.find("REVISION=\"111\""), std::string::npos) << "three.js r111 inlined";
  EXPECT_NE(html.find("THREE.GLTFLoader"), std::string::npos);
  EXPECT_NE(html.find("THREE.OrbitControls"), std::string::npos);
}

// The morph weight the glb's animation gives at `t` (its LINEAR sampler, read with tinygltf).
double glb_weight_at(const std::string& glb, double t) {
  tinygltf::Model model;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  const bool ok = loader.LoadBinaryFromMemory(&model, &err, &warn, reinterpret_cast<const unsigned char*>(glb.data()),
                                              static_cast<unsigned>(glb.size()));
  if (!ok) {
    ADD_FAILURE() << err;
    return NAN;
  }
  auto floats = [&](int index) {
    const auto& a = model.accessors[static_cast<std::size_t>(index)];
    const auto& v = model.bufferViews[static_cast<std::size_t>(a.bufferView)];
    std::vector<float> out(a.count);
    std::memcpy(out.data(), model.buffers[0].data.data() + v.byteOffset + a.byteOffset, a.count * sizeof(float));
    return out;
  };
  const auto& sampler = model.animations.at(0).samplers.at(0);
  const auto times = floats(sampler.input), weights = floats(sampler.output);
  for (std::size_t k = 0; k + 1 < times.size(); ++k) {
    if (t >= times[k] && t <= times[k + 1]) {
      const double w = (t - times[k]) / (times[k + 1] - times[k]);
      return weights[k] + w * (weights[k + 1] - weights[k]);
    }
  }
  return weights.back();
}

}  // namespace

TEST(Report, StrideKeepsAtMostTheMaximumWithTheLastSample) {
  using pneuma::outputs::report_stride;
  EXPECT_EQ(report_stride(1), 1u);
  EXPECT_EQ(report_stride(4000), 1u);
  EXPECT_EQ(report_stride(4001), 2u);
  EXPECT_EQ(report_stride(6001), 2u);  // 60 s at 100 Hz: 3001 samples
  for (std::size_t n : {4001u, 6001u, 7997u, 7998u, 7999u, 12000u, 360001u}) {
    const std::size_t s = report_stride(n);
    const std::size_t kept = (n + s - 1) / s + ((n - 1) % s != 0 ? 1 : 0);
    EXPECT_LE(kept, pneuma::outputs::kReportMaxSamples) << n;
    EXPECT_GT(kept, pneuma::outputs::kReportMaxSamples / 2) << n;
  }
}

TEST(Report, EmbedsTheRunsGlbAndEveryPhysiologySample) {
  TempDir dir;
  const auto scenario = dir.write("small.yaml", small_scenario("{hdf5: false}"));
  const auto out = dir / "out";
  const auto r = run_pneuma({"run", scenario.string(), "-o", out.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  ASSERT_TRUE(std::filesystem::exists(out / "report.html"));
  EXPECT_NE(r.out.find("open " + (out / "report.html").string() + " in a browser"), std::string::npos) << r.out;

  const Page page = read_page(out / "report.html");
  expect_self_contained(page.html);
  // The name, escaped in the title, verbatim in the data.
  EXPECT_NE(page.html.find("<title>small &lt;report&gt; &amp; &quot;test&quot; - pneuma</title>"), std::string::npos);
  EXPECT_EQ(page.data["name"], "small <report> & \"test\"");
  EXPECT_EQ(occurrences(page.html, "<report>"), 0u) << "the name must not appear unescaped";

  // The glb: byte for byte the breathing.glb of the same run.
  EXPECT_EQ(page.glb, read_text(out / "breathing.glb"));

  // The plots: every physiology.csv row (no decimation below 4000 rows), the same values.
  const Csv csv = read_csv(out / "physiology.csv");
  ASSERT_EQ(csv.rows.size(), 401u);  // 4 s at 100 Hz
  const auto& series = page.data["series"];
  EXPECT_EQ(series["rows"], csv.rows.size());
  EXPECT_EQ(series["stride"], 1);
  for (const std::string name : {"time_s", "volume_mL", "flow_L_per_s", "airway_pressure_cmH2O",
                                 "alveolar_pressure_cmH2O", "pleural_pressure_cmH2O", "muscle_pressure_cmH2O"}) {
    const auto& values = series["columns"][name];
    ASSERT_EQ(values.size(), csv.rows.size()) << name;
    const std::size_t c = csv.column(name);
    for (std::size_t k = 0; k < csv.rows.size(); ++k) {
      ASSERT_NEAR(values[k].get<double>(), csv.rows[k][c], 1e-3) << name << " row " << k;
    }
  }
  EXPECT_EQ(page.data["duration_s"], 4.0);
  EXPECT_EQ(page.data["frame_count"], 41);

  // The motion table: the means over breaths of motion.csv (one breath here).
  const Csv motion = read_csv(out / "motion.csv");
  ASSERT_EQ(motion.rows.size(), 4u);  // one breath, four regions
  const auto& table = page.data["motion"];
  EXPECT_EQ(table["breaths"], 1);
  ASSERT_EQ(table["regions"].size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) {
    const auto& region = table["regions"][i];
    EXPECT_NEAR(region["magnitude_max_mm"].get<double>(), motion.rows[i][motion.column("magnitude_max_mm")], 1e-3);
    EXPECT_NEAR(region["volume_share_pct"].get<double>(), motion.rows[i][motion.column("volume_share_pct")], 1e-2);
  }

  // Listed in the manifest with the others.
  const auto manifest = nlohmann::json::parse(read_text(out / "manifest.json"));
  bool listed = false;
  for (const auto& f : manifest["files"]) listed = listed || f["path"] == "report.html";
  EXPECT_TRUE(listed);
  // The manifest's motion facts are the same means as the table (the report takes nothing away).
  EXPECT_NEAR(std::stod(manifest["facts"].at("motion.diaphragmatic.volume_share_pct").get<std::string>()),
              table["regions"][2]["volume_share_pct"].get<double>(), 0.006);
  EXPECT_EQ(table["regions"][2]["name"], "diaphragmatic");
}

// No empty panel: the lumped model's run plots its pressures; a measured trace, which knows none but
// the open airway's flat 0, gets no pressure panel at all.
TEST(Report, ATraceRunShowsNoPanelItHasNoDataFor) {
  TempDir dir;
  std::string trace = "time_s,amplitude_cm\n";
  for (int k = 0; k <= 12 * 25; ++k) {
    const double t = k / 25.0;
    trace += fmt::format("{:.2f},{:.6f}\n", t, 1.0 + 0.5 * (1.0 - std::cos(std::numbers::pi * t / 2.0)));
  }
  dir.write("trace.csv", trace);
  const auto scenario = dir.write(
      "trace.yaml", "name: trace\nduration: 10 s\nframes: {rate: 10 Hz}\nmesh: {phantom: right, edge: 12 mm}\n"
                    "physiology:\n  driver: {mode: trace, file: trace.csv, calibration: {tidal_volume: 500 mL}}\n"
                    "outputs: {hdf5: false}\n");
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "trace").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::vector<std::string> titles;
  const Page trace_page = read_page(dir / "trace/report.html");
  for (const auto& plot : trace_page.data["plots"]) titles.push_back(plot["title"]);
  EXPECT_EQ(titles, (std::vector<std::string>{"Volume above FRC", "Flow"}));

  const auto lumped = dir.write("small.yaml", small_scenario("{hdf5: false}"));
  ASSERT_EQ(run_pneuma({"run", lumped.string(), "-o", (dir / "lumped").string(), "--quiet"}).exit_code, 0);
  const Page lumped_page = read_page(dir / "lumped/report.html");
  const auto& plots = lumped_page.data["plots"];
  ASSERT_EQ(plots.size(), 3u);
  EXPECT_EQ(plots[2]["title"], "Pressures");
  EXPECT_EQ(plots[2]["columns"].size(), 4u);  // airway, alveolar, pleural, muscle
}

TEST(Report, WithoutGltfOutputEmbedsTheSameGlbAndDecimatesLongSeries) {
  TempDir dir;
  const auto with = dir / "with", without = dir / "without";
  ASSERT_EQ(run_pneuma({"run", dir.write("a.yaml", small_scenario("{hdf5: false, motion_csv: false}")).string(), "-o",
                        with.string(), "--quiet"})
                .exit_code,
            0);
  // 4 s at 1250 Hz: 5001 rows, more than the page keeps.
  const auto b = dir.write("b.yaml", small_scenario("{hdf5: false, gltf: false}", "1250 Hz"));
  const auto r = run_pneuma({"run", b.string(), "-o", without.string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_FALSE(std::filesystem::exists(without / "breathing.glb"));
  const Page page = read_page(without / "report.html");
  EXPECT_EQ(page.glb, read_text(with / "breathing.glb"));

  const Csv csv = read_csv(without / "physiology.csv");
  ASSERT_EQ(csv.rows.size(), 5001u);
  const auto& series = page.data["series"];
  const std::size_t stride = pneuma::outputs::report_stride(csv.rows.size());
  EXPECT_EQ(stride, 2u);
  EXPECT_EQ(series["stride"], stride);
  const auto& time = series["columns"]["time_s"];
  ASSERT_EQ(time.size(), 2501u);  // rows 0, 2, ..., 5000
  for (std::size_t i = 0; i < time.size(); ++i) {
    const std::size_t k = std::min(i * stride, csv.rows.size() - 1);
    ASSERT_NEAR(time[i].get<double>(), csv.rows[k][0], 1e-9) << i;
  }
}

TEST(Report, OffWhenTheScenarioSaysSo) {
  TempDir dir;
  const auto out = dir / "out";
  const auto r = run_pneuma({"run", dir.write("s.yaml", small_scenario("{hdf5: false, report: false}")).string(), "-o",
                             out.string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_FALSE(std::filesystem::exists(out / "report.html"));
  EXPECT_TRUE(std::filesystem::exists(out / "breathing.glb"));
}

// The page in headless Chromium (Debian's chromium, software WebGL): loads without errors,
// renders a non-blank lung at two times, the two renders differ (the lung moved), and the
// mesh's morph weight at each time is the glb's animation there (the one clock drives both).
// "#selftest=" times as the page reads them.
std::string fmt_times(double a, double b) {
  std::ostringstream text;
  text << a << "," << b;
  return text.str();
}

// The page at `html` opened by headless Chromium with `#selftest=<times>`: the dumped DOM's
// self-test result (report.js) and Chromium's log; all empty when Chromium is not installed.
struct Chromium {
  pneuma::test::CommandResult run;
  std::string selftest;  // the self-test's JSON text, or "" / "pending" when it did not finish
};
Chromium open_in_chromium(const TempDir& dir, const std::filesystem::path& html, const std::string& times) {
  const auto chromium = pneuma::test::find_program({"chromium", "chromium-browser"});
  if (chromium.empty()) return {};
  const auto url = "file://" + std::filesystem::absolute(html).string() + "#selftest=" + times;
  Chromium c;
  c.run = pneuma::test::run_program(
      "/usr/bin/timeout",
      {"120", chromium.string(), "--headless=new", "--no-sandbox", "--no-first-run", "--disable-gpu",
       "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--user-data-dir=" + (dir / "profile").string(),
       "--window-size=1280,900", "--virtual-time-budget=15000", "--enable-logging=stderr", "--v=0", "--dump-dom", url});
  c.selftest = between(c.run.out, R"(<pre id="selftest">)", "</pre>");
  return c;
}

TEST(Report, RendersInHeadlessChromiumAtTwoTimes) {
  const auto chromium = pneuma::test::find_program({"chromium", "chromium-browser"});
  if (chromium.empty()) GTEST_SKIP() << "chromium not installed (Debian: apt install chromium)";
  TempDir dir;
  const auto out = dir / "out";
  ASSERT_EQ(
      run_pneuma({"run", dir.write("s.yaml", small_scenario("{hdf5: false}")).string(), "-o", out.string(), "--quiet"})
          .exit_code,
      0);
  const double t0 = 0.1, t1 = 1.6;  // near rest and near the end of inspiration
  const Chromium c = open_in_chromium(dir, out / "report.html", "0.1,1.6");
  const auto& r = c.run;
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string& text = c.selftest;
  ASSERT_FALSE(text.empty()) << r.out.substr(0, 2000);
  ASSERT_NE(text, "pending") << "the page never finished loading\n" << r.err;
  const auto result = nlohmann::json::parse(text);
  EXPECT_EQ(result["errors"], 0) << result["messages"].dump();
  const double pixels = result["pixels"].get<double>();
  ASSERT_GT(pixels, 10000.0);
  ASSERT_EQ(result["nonblank"].size(), 2u);
  for (const auto& count : result["nonblank"]) EXPECT_GT(count.get<double>(), 0.01 * pixels) << "blank canvas";
  EXPECT_GT(result["changed"].get<double>(), 0.002 * pixels) << "the lung did not move between the two times";
  EXPECT_EQ(result["samples"], 401);
  const std::string glb = read_text(out / "breathing.glb");
  EXPECT_EQ(result["glb_bytes"], glb.size());
  EXPECT_NEAR(result["weights"][0].get<double>(), glb_weight_at(glb, t0), 1e-5);
  EXPECT_NEAR(result["weights"][1].get<double>(), glb_weight_at(glb, t1), 1e-5);
  EXPECT_GT(result["weights"][1].get<double>(), 0.5);

  // Chromium's own log of the page's console: no uncaught exception, no error.
  std::stringstream log(r.err);
  for (std::string line; std::getline(log, line);) {
    if (line.find("GL Driver Message") != std::string::npos) continue;  // Chromium's note on readPixels
    EXPECT_EQ(line.find("Uncaught"), std::string::npos) << line;
    if (line.find(":CONSOLE") != std::string::npos) {
      EXPECT_EQ(line.find("rror"), std::string::npos) << line;
    }
  }
}

// A ventilated run carries the breaths' bounds for the pressure-volume and flow-volume loops
// (a spontaneous one does not), and the page draws them without an error.
TEST(Report, VentilatedRunsDrawTheLoopsOfTheBreathUnderTheCursor) {
  TempDir dir;
  const auto out = dir / "out";
  const auto scenario = dir.write("v.yaml", R"(duration: 8 s
frames: {rate: 10 Hz}
mesh: {phantom: right, edge: 12 mm, share: 55 %}
field: {tissue: healthy-upright}
physiology:
  compliance: 0.05 L/cmH2O
  resistance: 10 cmH2O*s/L
  driver: {mode: vc_ac, rate: 15 /min, tidal_volume: 450 mL, inspiratory_time: 1 s, pause: 0.2 s, peep: 5 cmH2O}
  effort: {rate: 20 /min, muscle_pressure: 5 cmH2O}
outputs: {hdf5: false}
)");
  ASSERT_EQ(run_pneuma({"run", scenario.string(), "-o", out.string(), "--quiet"}).exit_code, 0);
  const Page page = read_page(out / "report.html");
  ASSERT_TRUE(page.data.contains("loops"));
  std::stringstream csv(read_text(out / "physiology-breaths.csv"));
  std::string line;
  std::getline(csv, line);
  std::vector<double> starts, ends;
  while (std::getline(csv, line)) {
    std::stringstream cells(line);
    std::string breath, start, duration;
    std::getline(cells, breath, ',');
    std::getline(cells, start, ',');
    std::getline(cells, duration, ',');
    starts.push_back(std::stod(start));
    ends.push_back(std::stod(start) + std::stod(duration));
  }
  const auto& bounds = page.data["loops"]["breath_starts"];
  ASSERT_EQ(bounds.size(), starts.size() + 1);
  for (std::size_t i = 0; i < starts.size(); ++i) EXPECT_NEAR(bounds[i].get<double>(), starts[i], 1e-6) << i;
  EXPECT_NEAR(bounds.back().get<double>(), ends.back(), 2e-6);

  const auto quiet = dir / "quiet";
  ASSERT_EQ(run_pneuma(
                {"run", dir.write("s.yaml", small_scenario("{hdf5: false}")).string(), "-o", quiet.string(), "--quiet"})
                .exit_code,
            0);
  EXPECT_FALSE(read_page(quiet / "report.html").data.contains("loops"));

  const auto chromium = pneuma::test::find_program({"chromium", "chromium-browser"});
  if (chromium.empty()) GTEST_SKIP() << "chromium not installed (Debian: apt install chromium)";
  const Chromium c = open_in_chromium(dir, out / "report.html", "1.5,6");
  const auto& r = c.run;
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string& text = c.selftest;
  ASSERT_FALSE(text.empty()) << r.out.substr(0, 2000);
  ASSERT_NE(text, "pending") << "the page never finished loading\n" << r.err;
  EXPECT_EQ(nlohmann::json::parse(text)["errors"], 0) << text;
  EXPECT_NE(r.out.find("Pressure-volume loop"), std::string::npos);
  std::stringstream log(r.err);
  for (std::string l; std::getline(log, l);) EXPECT_EQ(l.find("Uncaught"), std::string::npos) << l;
}

// The ventilator screen: the numerics of the breath under the cursor, checked against the closed
// forms of a passive VC-AC breath with a pause on an RC lung (C 50 mL/cmH2O, R 10 cmH2O*s/L, VT
// 450 mL in 0.8 s then 0.2 s pause, PEEP 5): PIP = PEEP + R q + VT / C = 19.625, Pplat = PEEP +
// VT / C = 14, I:E 1:3 (Ti 1 s of 4 s), RR 15 /min, Cdyn = VT / (PIP - PEEP) = 30.8 mL/cmH2O,
// VTi = VT; a high-pressure alarm at 19 cmH2O raised by every breath and shown with it.
TEST(Report, TheVentilatorScreenShowsTheBreathUnderTheCursor) {
  TempDir dir;
  const auto out = dir / "out";
  const auto scenario = dir.write("v.yaml", R"(duration: 9 s
frames: {rate: 10 Hz}
mesh: {phantom: right, edge: 12 mm, share: 55 %}
field: {tissue: healthy-upright}
physiology:
  compliance: 0.05 L/cmH2O
  resistance: 10 cmH2O*s/L
  driver: {mode: vc_ac, rate: 15 /min, tidal_volume: 450 mL, inspiratory_time: 1 s, pause: 0.2 s, peep: 5 cmH2O,
           alarms: {high_pressure: 19 cmH2O}}
outputs: {hdf5: false}
)");
  ASSERT_EQ(run_pneuma({"run", scenario.string(), "-o", out.string(), "--quiet"}).exit_code, 0);
  const Page page = read_page(out / "report.html");
  ASSERT_TRUE(page.data.contains("loops"));
  const auto& screen = page.data["loops"]["screen"];
  ASSERT_EQ(screen.size(), 2u);
  // The second breath starts on what the first left (x = VT e^(-Te / tau) = 450 e^-6 mL): its
  // pressures are x / C higher. The screen rounds to its digits (0.05 cmH2O, 0.05 mL/cmH2O).
  for (std::size_t k = 0; k < screen.size(); ++k) {
    const auto& b = screen[k];
    const double left = k == 0 ? 0.0 : 450.0 * std::exp(-6.0);
    const double pip = 5 + 10 * 0.5625 + (450 + left) / 50, plateau = 5 + (450 + left) / 50;
    EXPECT_NEAR(b["pip"].get<double>(), pip, 0.05 + 1e-9) << k;
    EXPECT_NEAR(b["pplat"].get<double>(), plateau, 0.05 + 1e-9) << k;
    EXPECT_DOUBLE_EQ(b["peep"].get<double>(), 5.0);
    EXPECT_DOUBLE_EQ(b["ie"].get<double>(), 3.0);
    EXPECT_DOUBLE_EQ(b["rr"].get<double>(), 15.0);
    EXPECT_DOUBLE_EQ(b["rr_spont"].get<double>(), 0.0);
    EXPECT_NEAR(b["cdyn"].get<double>(), 450 / (pip - 5), 0.05 + 1e-9) << k;
    EXPECT_DOUBLE_EQ(b["vti"].get<double>(), 450.0);
    EXPECT_EQ(b["alarms"], "high_pressure");
  }
  // VTe: all but what the 3 s expiration leaves (VT e^(-3 / 0.5)); MVe over the first 4 s, then 8 s.
  const double vte = 450.0 * (1 - std::exp(-6.0));
  EXPECT_NEAR(screen[0]["vte"].get<double>(), vte, 0.5);
  EXPECT_NEAR(screen[0]["mve"].get<double>(), vte * 15 / 1000, 0.005);

  const auto chromium = pneuma::test::find_program({"chromium", "chromium-browser"});
  if (chromium.empty()) GTEST_SKIP() << "chromium not installed (Debian: apt install chromium)";
  const Chromium c = open_in_chromium(dir, out / "report.html", "1.5,5");
  ASSERT_EQ(c.run.exit_code, 0) << c.run.err;
  ASSERT_FALSE(c.selftest.empty()) << c.run.out.substr(0, 2000);
  ASSERT_NE(c.selftest, "pending") << "the page never finished loading\n" << c.run.err;
  const auto result = nlohmann::json::parse(c.selftest);
  EXPECT_EQ(result["errors"], 0) << c.selftest;
  const auto& shown = result["ventilator"];
  EXPECT_EQ(shown["breath"], 2);  // 5 s is in the second breath, [4 s, 8 s)
  EXPECT_EQ(shown["values"]["pip"], "19.6");
  EXPECT_EQ(shown["values"]["pplat"], "14.0");
  EXPECT_EQ(shown["values"]["ie"], "1:3.00");
  EXPECT_EQ(shown["values"]["rr"], "15.0");
  EXPECT_EQ(shown["alarms"], "high_pressure");
  EXPECT_NE(c.run.out.find("Alarms: high_pressure"), std::string::npos);
}

// With phases and voxel outputs the page carries the respiratory bins (checked against
// phases.csv) and slices of the warped label map (checked against the physiology's volume: the
// plane holds the most lung near end-inspiration), and draws both under the cursor: the
// canvases read back show what the data holds, and the bin under the cursor is the frame's.
TEST(Report, BinsAndLabelSlicesFollowTheCursor) {
  TempDir dir;
  const auto out = dir / "out";
  const auto scenario = dir.write("v.yaml", R"(duration: 8 s
frames: {rate: 10 Hz}
mesh: {phantom: right, edge: 8 mm}
field: {tissue: healthy-upright, interior: {edge: 8 mm}}
physiology:
  preset: healthy-adult
  output_rate: 10 Hz
  driver: {mode: spontaneous, rate: 15 /min, ie_ratio: 1:2, tidal_volume: 800 mL}
outputs:
  hdf5: false
  phases: {bins: 4, surfaces: false}
  voxels: {at: [end_inspiration], spacing: 4 mm}
)");
  const auto run = run_pneuma({"run", scenario.string(), "-o", out.string(), "--quiet"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const Page page = read_page(out / "report.html");

  // The bins: each frame listed in phases.csv is in that bin on the page, and no other is.
  ASSERT_TRUE(page.data.contains("bins"));
  const auto& bin_of_frame = page.data["bins"]["bin_of_frame"];
  ASSERT_EQ(bin_of_frame.size(), 81u);
  std::vector<int> expected(81, -1);
  std::stringstream phases(read_text(out / "phases.csv"));
  std::string line;
  std::getline(phases, line);
  while (std::getline(phases, line)) {
    std::stringstream cells(line);
    std::string cell;
    std::vector<std::string> row;
    while (std::getline(cells, cell, ',')) row.push_back(cell);
    ASSERT_EQ(row.size(), 9u) << line;
    std::stringstream times(row[8]);
    for (double t = 0; times >> t;) expected[static_cast<std::size_t>(std::lround(t * 10.0))] = std::stoi(row[0]);
  }
  for (std::size_t k = 0; k < expected.size(); ++k) EXPECT_EQ(bin_of_frame[k].get<int>(), expected[k]) << k;

  // The slices: whole images; the plane with the most lung is near end-inspiration.
  ASSERT_TRUE(page.data.contains("slices"));
  const auto& lung_labels = page.data["slices"]["lung_labels"];
  const auto& planes = page.data["slices"]["planes"];
  ASSERT_EQ(planes.size(), 2u);
  const Csv physiology = read_csv(out / "physiology.csv");
  const std::size_t time_column = physiology.column("time_s"), volume_column = physiology.column("volume_mL");
  double most_volume = 0;
  for (const auto& row : physiology.rows) most_volume = std::max(most_volume, row[volume_column]);
  std::vector<std::vector<double>> lung_pixels(2);
  double most_lung_time = 0;
  for (std::size_t p = 0; p < 2; ++p) {
    const auto& plane = planes[p];
    EXPECT_EQ(plane["name"], p == 0 ? "coronal" : "sagittal");
    const std::size_t pixels = plane["width"].get<std::size_t>() * plane["height"].get<std::size_t>();
    const auto& times_s = plane["times_s"];
    ASSERT_EQ(times_s.size(), 32u);
    EXPECT_EQ(times_s.front().get<double>(), 0.0);
    EXPECT_NEAR(times_s.back().get<double>(), 8.0, 1e-9);
    std::size_t most = 0;
    for (std::size_t t = 0; t < times_s.size(); ++t) {
      const auto& runs = plane["labels"][t];
      std::size_t total = 0, lung = 0;
      for (std::size_t r = 0; r + 1 < runs.size(); r += 2) {
        total += runs[r + 1].get<std::size_t>();
        for (const auto& v : lung_labels) lung += v == runs[r] ? runs[r + 1].get<std::size_t>() : 0;
      }
      EXPECT_EQ(total, pixels) << p << " " << t;
      lung_pixels[p].push_back(static_cast<double>(lung));
      if (lung_pixels[p][t] > lung_pixels[p][most]) most = t;
    }
    const double t_most = times_s[most].get<double>();
    double volume = 0;
    for (const auto& row : physiology.rows) {
      if (std::abs(row[time_column] - t_most) < 1e-6) volume = row[volume_column];
    }
    EXPECT_GT(volume, 0.85 * most_volume) << plane["name"] << " holds the most lung at " << t_most << " s";
    EXPECT_GT(lung_pixels[p][most], 1.05 * lung_pixels[p][0]);
    if (p == 0) most_lung_time = t_most;
  }

  const Chromium c = open_in_chromium(dir, out / "report.html", fmt_times(0.0, most_lung_time));
  if (c.run.out.empty() && c.run.err.empty()) GTEST_SKIP() << "chromium not installed (Debian: apt install chromium)";
  ASSERT_EQ(c.run.exit_code, 0) << c.run.err;
  ASSERT_FALSE(c.selftest.empty() || c.selftest == "pending") << c.run.err;
  const auto result = nlohmann::json::parse(c.selftest);
  EXPECT_EQ(result["errors"], 0) << result["messages"].dump();
  const std::size_t peak_frame = static_cast<std::size_t>(std::lround(most_lung_time * 10.0));
  EXPECT_EQ(result["bins"][0].get<int>(), expected[0]);
  EXPECT_EQ(result["bins"][1].get<int>(), expected[peak_frame]);
  for (std::size_t p = 0; p < 2; ++p) {
    // What the canvas shows: the lung pixels of the data (less the dashed line's, at most a row).
    const double width = planes[p]["width"].get<double>();
    const double shown_rest = result["slices"][0][p]["lung_pixels"].get<double>();
    const double shown_peak = result["slices"][1][p]["lung_pixels"].get<double>();
    const auto& times_s = planes[p]["times_s"];
    std::size_t peak_index = 0;
    for (std::size_t t = 0; t < times_s.size(); ++t) {
      if (std::abs(times_s[t].get<double>() - most_lung_time) < 1e-9) peak_index = t;
    }
    EXPECT_NEAR(shown_rest, lung_pixels[p][0], width) << p;
    EXPECT_NEAR(shown_peak, lung_pixels[p][peak_index], width) << p;
  }
}

namespace {

// The phantom's 800 mL breath at 15 /min with voxel outputs (4 mm) and report.html: `duration`
// and `rate` of the frames, `at` the voxel time points, `voxels` what else goes inside
// outputs.voxels (", image: ct.nii.gz"), `gltf` whether the glb is written too.
std::string phantom_voxels_scenario(const std::string& duration, const std::string& rate, const std::string& at,
                                    const std::string& voxels, bool gltf = true) {
  return "duration: " + duration + "\nframes: {rate: " + rate +
         "}\nmesh: {phantom: right, edge: 8 mm}\nfield: {tissue: healthy-upright, interior: {edge: 8 mm}}\n"
         "physiology:\n  preset: healthy-adult\n"
         "  driver: {mode: spontaneous, rate: 15 /min, ie_ratio: 1:2, tidal_volume: 800 mL}\noutputs:\n  hdf5: false\n" +
         (gltf ? std::string() : std::string("  gltf: false\n")) + "  voxels: {at: [" + at + "], spacing: 4 mm" +
         voxels + "}\n";
}

}  // namespace

// With a CT given, each slice plane shows beside its labels the warped CT, |forward DVF| and the
// forward map's Jacobian (#45), and the page lists the voxel time points' figures. Oracles: at
// the first frame the lungs are at rest (s = 0): no displacement, J = 1 everywhere, and the CT is
// the synthetic scan (lung -849.5 HU, tissue 40 HU) exactly where the labels say; at
// end-inspiration the lung has moved, the Jacobian over the rest lung's pixels averages about the
// physiology's V / V0, and the lung is darker (its mass in a larger volume). The figures are
// voxels.csv's; Chromium draws every channel.
TEST(Report, SlicesShowTheWarpedCtDisplacementAndJacobian) {
  TempDir dir;
  auto with_image = [](const std::string& image) {
    return phantom_voxels_scenario("4 s", "10 Hz", "end_expiration, end_inspiration", image);
  };
  // The synthetic CT on the rest label map's grid: lung -849.5 HU, tissue 40 HU.
  const auto first = dir.write("rest.yaml", with_image(""));
  ASSERT_EQ(run_pneuma({"run", first.string(), "-o", (dir / "rest").string(), "--quiet"}).exit_code, 0);
  const auto rest = pneuma::image::read_label_map(dir / "rest/voxels/labels-end_expiration.nii.gz");
  pneuma::voxels::Image ct;
  ct.grid = pneuma::voxels::grid_of(rest);
  for (const std::int32_t label : rest.labels) ct.values.push_back(label == 1 ? -849.5f : 40.0f);
  pneuma::voxels::write_image(dir / "ct.nii.gz", ct);

  const auto out = dir / "out";
  const auto scenario = dir.write("ct.yaml", with_image(", image: ct.nii.gz"));
  const auto run = run_pneuma({"run", scenario.string(), "-o", out.string(), "--quiet"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const Page page = read_page(out / "report.html");
  const Csv physiology = read_csv(out / "physiology.csv");
  const std::size_t time_column = physiology.column("time_s"), volume_column = physiology.column("volume_mL");

  // Bytes to values, as the page's scale says (report.h: LabelSlice::Channel).
  auto value_of = [](const nlohmann::json& channel, unsigned char byte) {
    const double lo = channel["lo"].get<double>(), hi = channel["hi"].get<double>(), f = byte / 255.0;
    return channel["log"].get<bool>() ? std::exp(std::log(lo) + f * (std::log(hi) - std::log(lo))) : lo + f * (hi - lo);
  };
  auto pixel_labels = [](const nlohmann::json& runs) {
    std::vector<int> labels;
    for (std::size_t r = 0; r + 1 < runs.size(); r += 2)
      labels.insert(labels.end(), runs[r + 1].get<std::size_t>(), runs[r].get<int>());
    return labels;
  };
  const auto& planes = page.data["slices"]["planes"];
  ASSERT_EQ(planes.size(), 2u);
  for (const auto& plane : planes) {
    const auto& times_s = plane["times_s"];
    const auto& channel_times = plane["channel_times_s"];
    ASSERT_GE(channel_times.size(), 2u);
    ASSERT_LE(channel_times.size(), 9u);
    EXPECT_EQ(channel_times.front(), times_s.front());
    EXPECT_EQ(channel_times.back(), times_s.back());
    const auto& channels = plane["channels"];
    ASSERT_EQ(channels.size(), 3u);
    EXPECT_EQ(channels[0]["name"], "ct");
    EXPECT_EQ(channels[1]["name"], "displacement");
    EXPECT_EQ(channels[2]["name"], "jacobian");
    const std::size_t pixels = plane["width"].get<std::size_t>() * plane["height"].get<std::size_t>();
    auto bytes = [&](std::size_t channel, std::size_t t) {
      const std::string b = decode_base64(channels[channel]["images"][t].get<std::string>());
      EXPECT_EQ(b.size(), pixels);
      return std::vector<unsigned char>(b.begin(), b.end());
    };
    auto labels_at = [&](double t) {
      for (std::size_t k = 0; k < times_s.size(); ++k)
        if (times_s[k].get<double>() == t) return pixel_labels(plane["labels"][k]);
      ADD_FAILURE() << "no label slice at " << t;
      return std::vector<int>(pixels, 0);
    };

    // At rest: no motion, J = 1 (byte 128 of the log scale), the CT as scanned where the labels say.
    ASSERT_EQ(channel_times.front().get<double>(), 0.0);
    const std::vector<int> rest_labels = labels_at(0.0);
    const auto ct0 = bytes(0, 0), u0 = bytes(1, 0), j0 = bytes(2, 0);
    std::size_t lung_ok = 0, lung = 0, tissue_ok = 0, tissue = 0;
    for (std::size_t k = 0; k < pixels; ++k) {
      EXPECT_EQ(u0[k], 0) << plane["name"] << " pixel " << k;
      EXPECT_EQ(j0[k], 128) << plane["name"] << " pixel " << k;
      if (u0[k] != 0 || j0[k] != 128) break;
      const double hu = value_of(channels[0], ct0[k]);
      if (rest_labels[k] == 1) {
        ++lung;
        lung_ok += std::abs(hu - -849.5) <= 2.4;  // half a byte of the 1200 HU window
      } else if (ct0[k] > 0) {                    // 0: beyond the scan
        ++tissue;
        tissue_ok += std::abs(hu - 40.0) <= 2.4;
      }
    }
    ASSERT_GT(lung, 100u);
    EXPECT_GE(static_cast<double>(lung_ok), 0.99 * static_cast<double>(lung)) << plane["name"];
    EXPECT_GE(static_cast<double>(tissue_ok), 0.99 * static_cast<double>(tissue)) << plane["name"];

    // The channel time of the largest volume.
    std::size_t peak = 0;
    double peak_volume = -1.0;
    for (std::size_t c = 0; c < channel_times.size(); ++c) {
      for (const auto& row : physiology.rows) {
        if (std::abs(row[time_column] - channel_times[c].get<double>()) < 1e-6 && row[volume_column] > peak_volume) {
          peak_volume = row[volume_column];
          peak = c;
        }
      }
    }
    ASSERT_GT(peak_volume, 300.0) << "a channel time well into the breath";
    const auto ct1 = bytes(0, peak), u1 = bytes(1, peak), j1 = bytes(2, peak);
    const std::vector<int> peak_labels = labels_at(channel_times[peak].get<double>());
    double largest_mm = 0.0, j_sum = 0.0, hu_sum = 0.0;
    std::size_t j_count = 0, hu_count = 0;
    for (std::size_t k = 0; k < pixels; ++k) {
      largest_mm = std::max(largest_mm, value_of(channels[1], u1[k]));
      if (rest_labels[k] == 1) j_sum += value_of(channels[2], j1[k]), ++j_count;
      if (peak_labels[k] == 1) hu_sum += value_of(channels[0], ct1[k]), ++hu_count;
    }
    EXPECT_GT(largest_mm, 5.0) << plane["name"];
    EXPECT_LE(largest_mm, channels[1]["hi"].get<double>());
    // V / V0: the lung's volume at rest (the phantom's) and the physiology's change.
    const double rest_volume_ml =
        static_cast<double>(std::count(rest.labels.begin(), rest.labels.end(), 1)) * rest.voxel_volume_m3() * 1e6;
    const double growth = (rest_volume_ml + 0.55 * peak_volume) / rest_volume_ml;
    EXPECT_NEAR(j_sum / static_cast<double>(j_count), growth, 0.15 * (growth - 1.0) + 0.02) << plane["name"];
    EXPECT_LT(hu_sum / static_cast<double>(hu_count), -849.5 - 0.5 * (150.5 - 150.5 / growth)) << plane["name"];
  }

  // The voxel time points' figures, as voxels.csv has them.
  const Csv voxels_csv = read_csv(out / "voxels/voxels.csv");
  const auto& points = page.data["voxel_points"];
  ASSERT_EQ(points.size(), voxels_csv.rows.size());
  const std::size_t error_column = voxels_csv.column("volume_error_percent"),
                    min_j_column = voxels_csv.column("min_jacobian");
  for (std::size_t r = 0; r < points.size(); ++r) {
    EXPECT_NEAR(points[r]["volume_error_percent"].get<double>(), voxels_csv.rows[r][error_column], 1e-4);
    EXPECT_NEAR(points[r]["min_jacobian"].get<double>(), voxels_csv.rows[r][min_j_column], 1e-4);
  }
  EXPECT_EQ(points[0]["tag"], "end_expiration");
  EXPECT_EQ(points[1]["tag"], "end_inspiration");

  // Chromium draws every channel, each filling its canvas.
  const Chromium c = open_in_chromium(dir, out / "report.html", fmt_times(0.0, 2.0));
  if (c.run.out.empty() && c.run.err.empty()) GTEST_SKIP() << "chromium not installed (Debian: apt install chromium)";
  ASSERT_EQ(c.run.exit_code, 0) << c.run.err;
  ASSERT_FALSE(c.selftest.empty() || c.selftest == "pending") << c.run.err;
  const auto result = nlohmann::json::parse(c.selftest);
  EXPECT_EQ(result["errors"], 0) << result["messages"].dump();
  for (std::size_t p = 0; p < 2; ++p) {
    const std::size_t pixels = planes[p]["width"].get<std::size_t>() * planes[p]["height"].get<std::size_t>();
    for (std::size_t shot = 0; shot < 2; ++shot) {
      const auto& shown = result["slices"][shot][p]["channels"];
      ASSERT_EQ(shown.size(), 3u);
      for (const auto& channel : shown) EXPECT_EQ(channel["drawn"].get<std::size_t>(), pixels) << channel.dump();
    }
    // |DVF| at rest is the scale's zero (dark); at 2 s brighter.
    EXPECT_LT(result["slices"][0][p]["channels"][1]["mean_rgb"].get<double>(),
              result["slices"][1][p]["channels"][1]["mean_rgb"].get<double>());
  }
}

// voxels.points on the page (#48): each point's positions per frame are trajectories.csv's
// numbers exactly, and Chromium draws each point's marker where trajectories.csv puts it on both
// planes (projected: column along x or y, row down from the top along z) at two cursor times, so
// the marker moves by the pixels the CSV's displacement says. Two points inside the phantom's
// convex lung (from a first run's rest slice): its centre and just above its lowest row.
TEST(Report, PointTrajectoriesArePlottedAndTheirMarkersMoveOnTheSlices) {
  TempDir dir;
  auto with = [](const std::string& points) {
    return phantom_voxels_scenario("4 s", "10 Hz", "end_expiration, end_inspiration", points, false);
  };
  const auto first = dir.write("first.yaml", with(""));
  ASSERT_EQ(run_pneuma({"run", first.string(), "-o", (dir / "a").string(), "--quiet"}).exit_code, 0);
  const Page rest_page = read_page(dir / "a/report.html");
  ASSERT_FALSE(rest_page.data.contains("trajectories"));
  const auto& coronal = rest_page.data["slices"]["planes"][0];
  ASSERT_EQ(coronal["name"], "coronal");
  ASSERT_EQ(coronal["times_s"][0].get<double>(), 0.0);
  const std::size_t width = coronal["width"].get<std::size_t>(), height = coronal["height"].get<std::size_t>();
  const double h = coronal["pixel_mm"].get<double>();
  const auto& origin = coronal["origin_mm"];
  std::vector<int> labels;
  const auto& runs = coronal["labels"][0];
  for (std::size_t r = 0; r + 1 < runs.size(); r += 2)
    labels.insert(labels.end(), runs[r + 1].get<std::size_t>(), runs[r].get<int>());
  ASSERT_EQ(labels.size(), width * height);
  double sum_row = 0.0, sum_column = 0.0;
  std::size_t count = 0, lowest = 0;
  for (std::size_t row = 0; row < height; ++row)
    for (std::size_t c = 0; c < width; ++c)
      if (labels[row * width + c] == 1) {
        sum_row += static_cast<double>(row);
        sum_column += static_cast<double>(c);
        ++count;
        lowest = row;
      }
  ASSERT_GT(count, 50u);
  std::vector<std::size_t> lowest_columns;
  for (std::size_t c = 0; c < width; ++c)
    if (labels[lowest * width + c] == 1) lowest_columns.push_back(c);
  // A pixel's LPS centre (mm) on the coronal plane.
  auto lps = [&](double row, double column) {
    return std::array<double, 3>{origin[0].get<double>() + column * h, origin[1].get<double>(),
                                 origin[2].get<double>() + (static_cast<double>(height) - 1.0 - row) * h};
  };
  const auto centre =
      lps(std::round(sum_row / static_cast<double>(count)), std::round(sum_column / static_cast<double>(count)));
  const auto base =
      lps(static_cast<double>(lowest) - 2.0, static_cast<double>(lowest_columns[lowest_columns.size() / 2]));
  dir.write("points.csv", fmt::format("name,x_mm,y_mm,z_mm\ncentre,{},{},{}\nbase,{},{},{}\n", centre[0], centre[1],
                                      centre[2], base[0], base[1], base[2]));
  const auto second = dir.write("second.yaml", with(", points: points.csv"));
  const auto out = dir / "b";
  const auto run = run_pneuma({"run", second.string(), "-o", out.string(), "--quiet"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const Page page = read_page(out / "report.html");

  // The page's numbers are trajectories.csv's frame rows (the bins' rows are not plotted).
  std::ifstream csv_in(out / "voxels/trajectories.csv");
  std::string line;
  std::getline(csv_in, line);
  ASSERT_EQ(line, "point,moves_with,frame,time_s,bin,x_mm,y_mm,z_mm");
  std::map<std::string, std::vector<std::array<double, 3>>> csv_positions;
  std::vector<double> csv_times;
  while (std::getline(csv_in, line)) {
    std::vector<std::string> cells;
    std::stringstream s(line);
    for (std::string cell; std::getline(s, cell, ',');) cells.push_back(cell);
    ASSERT_EQ(cells.size(), 8u) << line;
    EXPECT_EQ(cells[1], "right interior") << line;
    if (cells[0] == "centre") csv_times.push_back(std::stod(cells[3]));
    csv_positions[cells[0]].push_back({std::stod(cells[5]), std::stod(cells[6]), std::stod(cells[7])});
  }
  const auto& tracks = page.data["trajectories"];
  ASSERT_EQ(tracks["times_s"].size(), csv_times.size());
  for (std::size_t k = 0; k < csv_times.size(); ++k)
    EXPECT_NEAR(tracks["times_s"][k].get<double>(), csv_times[k], 1e-6);
  ASSERT_EQ(tracks["points"].size(), 2u);
  for (const auto& point : tracks["points"]) {
    const auto& expected = csv_positions[point["name"].get<std::string>()];
    ASSERT_EQ(expected.size(), csv_times.size()) << point["name"];
    for (std::size_t k = 0; k < expected.size(); ++k) {
      EXPECT_EQ(point["x_mm"][k].get<double>(), expected[k][0]) << point["name"] << " frame " << k;
      EXPECT_EQ(point["y_mm"][k].get<double>(), expected[k][1]) << point["name"] << " frame " << k;
      EXPECT_EQ(point["z_mm"][k].get<double>(), expected[k][2]) << point["name"] << " frame " << k;
    }
  }
  EXPECT_NEAR(tracks["points"][0]["rest_mm"][2].get<double>(), centre[2], 1e-9);
  EXPECT_NEAR(tracks["points"][1]["rest_mm"][0].get<double>(), base[0], 1e-9);

  // Chromium at rest and at end-inspiration: each marker where the CSV puts it, on both planes.
  const Csv voxels_csv = read_csv(out / "voxels/voxels.csv");
  const auto inspiration = static_cast<std::size_t>(voxels_csv.rows[1][voxels_csv.column("frame")]);
  const Chromium c = open_in_chromium(dir, out / "report.html", fmt_times(0.0, csv_times[inspiration]));
  if (c.run.out.empty() && c.run.err.empty()) GTEST_SKIP() << "chromium not installed (Debian: apt install chromium)";
  ASSERT_EQ(c.run.exit_code, 0) << c.run.err;
  ASSERT_FALSE(c.selftest.empty() || c.selftest == "pending") << c.run.err;
  const auto result = nlohmann::json::parse(c.selftest);
  EXPECT_EQ(result["errors"], 0) << result["messages"].dump();
  const auto& planes = page.data["slices"]["planes"];
  for (std::size_t p = 0; p < 2; ++p) {
    const auto& plane = planes[p];
    const bool is_coronal = plane["name"] == "coronal";
    const double pixel = plane["pixel_mm"].get<double>();
    const auto& o = plane["origin_mm"];
    const double plane_height = plane["height"].get<double>();
    for (std::size_t k = 0; k < 2; ++k) {
      const std::string name = tracks["points"][k]["name"];
      std::array<double, 2> moved{};
      for (std::size_t shot = 0; shot < 2; ++shot) {
        const std::size_t frame = shot == 0 ? 0 : inspiration;
        const auto& x = csv_positions[name][frame];
        const double column =
            is_coronal ? (x[0] - o[0].get<double>()) / pixel + 0.5 : (x[1] - o[1].get<double>()) / pixel + 0.5;
        const double row = plane_height - 1.0 - (x[2] - o[2].get<double>()) / pixel + 0.5;
        const auto& marker = result["slices"][shot][p]["markers"][k];
        ASSERT_EQ(marker["name"], name);
        EXPECT_EQ(marker["frame"].get<std::size_t>(), frame);
        EXPECT_EQ(marker["pixels"].get<int>(), 9) << marker.dump();
        ASSERT_TRUE(marker["column"].is_number()) << marker.dump();
        // The 3 x 3 marker's centre is the pixel holding the point.
        EXPECT_NEAR(marker["column"].get<double>(), column, 0.5 + 1e-6) << plane["name"] << " " << marker.dump();
        EXPECT_NEAR(marker["row"].get<double>(), row, 0.5 + 1e-6) << plane["name"] << " " << marker.dump();
        moved[shot] = marker["row"].get<double>();
        if (shot == 1) {
          const auto& x0 = csv_positions[name][0];
          const double expected_rows = -(x[2] - x0[2]) / pixel;
          std::printf("%s on the %s plane: the marker moved %+.0f rows, the CSV %+.2f\n", name.c_str(),
                      plane["name"].get<std::string>().c_str(), moved[1] - moved[0], expected_rows);
          EXPECT_NEAR(moved[1] - moved[0], expected_rows, 1.0);
        }
      }
    }
  }
  // The base of the lung moves down (SI) by more than two pixels at end-inspiration.
  const auto& base_track = csv_positions["base"];
  EXPECT_LT(base_track[inspiration][2] - base_track[0][2], -2.0 * planes[0]["pixel_mm"].get<double>());
}

// voxels.structures on the page (#48): a ball mask in the phantom's lung, its figures listed as
// structures.csv and structures-summary.csv print them; on each plane at rest its mask is the ball
// file sampled at the pixel centres (the oracle: the test's own nearest-voxel sampling of the
// input), its ITV the written itv file sampled the same way, and Chromium draws exactly the
// outline pixels of both (counted by colour).
TEST(Report, StructuresAreOutlinedOnTheSlicesWithTheirItv) {
  TempDir dir;
  auto with = [](const std::string& structures) {
    return phantom_voxels_scenario("8 s", "5 Hz", "end_expiration, end_inspiration, phases",
                                   ", jacobian: false" + structures, false);
  };
  const auto first = dir.write("first.yaml", with(""));
  ASSERT_EQ(run_pneuma({"run", first.string(), "-o", (dir / "a").string(), "--quiet"}).exit_code, 0);
  const Page rest_page = read_page(dir / "a/report.html");
  const auto& rest_planes = rest_page.data["slices"]["planes"];
  ASSERT_EQ(rest_planes[0]["name"], "coronal");
  // The ball's centre on both planes (x of the sagittal one, y of the coronal one), at the middle
  // height of the lung's pixels on the coronal plane at rest.
  const auto& coronal = rest_planes[0];
  const std::size_t width = coronal["width"].get<std::size_t>(), height = coronal["height"].get<std::size_t>();
  const double h = coronal["pixel_mm"].get<double>();
  const auto& runs = coronal["labels"][0];
  std::size_t at = 0, count = 0;
  double rows = 0.0;
  for (std::size_t r = 0; r + 1 < runs.size(); r += 2) {
    const std::size_t n = runs[r + 1].get<std::size_t>();
    if (runs[r].get<int>() == 1)
      for (std::size_t q = at; q < at + n; ++q) {
        rows += std::floor(static_cast<double>(q) / static_cast<double>(width));  // the pixel's row
        ++count;
      }
    at += n;
  }
  ASSERT_EQ(at, width * height);
  ASSERT_GT(count, 50u);
  const Eigen::Vector3d centre(rest_planes[1]["origin_mm"][0].get<double>() * 1e-3,
                               coronal["origin_mm"][1].get<double>() * 1e-3,
                               (coronal["origin_mm"][2].get<double>() +
                                (static_cast<double>(height) - 1.0 - rows / static_cast<double>(count)) * h) *
                                   1e-3);
  const pneuma::image::LabelMap ball = pneuma::test::write_ball_mask(dir / "ball.nii.gz", centre);
  const auto second = dir.write("second.yaml", with(", structures: {target: ball.nii.gz}"));
  const auto out = dir / "b";
  const auto run = run_pneuma({"run", second.string(), "-o", out.string(), "--quiet"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const Page page = read_page(out / "report.html");

  // The listed figures are the CSVs' numbers.
  const auto& listed = page.data["structures"];
  ASSERT_EQ(listed.size(), 1u);
  EXPECT_EQ(listed[0]["name"], "target");
  const Csv csv = read_csv(out / "voxels/structures.csv");
  ASSERT_EQ(listed[0]["rows"].size(), csv.rows.size());
  ASSERT_EQ(csv.rows.size(), 12u);  // two frames and ten bins
  for (std::size_t r = 0; r < csv.rows.size(); ++r) {
    const auto& row = listed[0]["rows"][r];
    EXPECT_EQ(row["volume_mL"].get<double>(), csv.rows[r][csv.column("volume_mL")]) << r;
    EXPECT_EQ(row["weight"].get<double>(), csv.rows[r][csv.column("weight")]) << r;
    EXPECT_EQ(row["centroid_mm"][0].get<double>(), csv.rows[r][csv.column("centroid_x_mm")]) << r;
    EXPECT_EQ(row["centroid_mm"][1].get<double>(), csv.rows[r][csv.column("centroid_y_mm")]) << r;
    EXPECT_EQ(row["centroid_mm"][2].get<double>(), csv.rows[r][csv.column("centroid_z_mm")]) << r;
    EXPECT_EQ(row["time_s"].is_null(), row["tag"].get<std::string>().starts_with("bin_")) << r;
  }
  std::ifstream summary_in(out / "voxels/structures-summary.csv");
  std::string line;
  std::getline(summary_in, line);
  std::getline(summary_in, line);
  std::vector<std::string> summary;
  std::stringstream summary_cells(line);
  for (std::string cell; std::getline(summary_cells, cell, ',');) summary.push_back(cell);
  ASSERT_EQ(summary.size(), 9u) << line;
  EXPECT_EQ(listed[0]["itv_mL"].get<double>(), std::stod(summary[1]));
  EXPECT_EQ(listed[0]["midventilation"], summary[2]);
  for (std::size_t a = 0; a < 3; ++a) {
    EXPECT_EQ(listed[0]["midventilation_mm"][a].get<double>(), std::stod(summary[3 + a]));
    EXPECT_EQ(listed[0]["mean_mm"][a].get<double>(), std::stod(summary[6 + a]));
  }

  // A 0/1 image of a label map sampled at a plane's pixel centres (nearest voxel), as the least
  // and the largest value a pixel may have: a pixel centre within 1e-3 voxel of a voxel face
  // (the run's 4 mm grid and the 2 mm planes share such faces) may take either voxel's.
  auto sampled = [](const nlohmann::json& plane, const pneuma::image::LabelMap& map) {
    const std::size_t w = plane["width"].get<std::size_t>(), ht = plane["height"].get<std::size_t>();
    const double px = plane["pixel_mm"].get<double>() * 1e-3;
    const Eigen::Vector3d o(plane["origin_mm"][0].get<double>() * 1e-3, plane["origin_mm"][1].get<double>() * 1e-3,
                            plane["origin_mm"][2].get<double>() * 1e-3);
    const Eigen::Matrix4d to_ijk = map.ijk_to_lps.inverse();
    std::vector<std::pair<int, int>> image;
    for (std::size_t row = 0; row < ht; ++row)
      for (std::size_t c = 0; c < w; ++c) {
        Eigen::Vector3d x = o;
        x[plane["name"] == "coronal" ? 0 : 1] += static_cast<double>(c) * px;
        x[2] += static_cast<double>(ht - 1 - row) * px;
        const Eigen::Vector3d ijk = (to_ijk * x.homogeneous()).head<3>();
        std::array<std::vector<long>, 3> candidates;
        for (int a = 0; a < 3; ++a) {
          const double f = ijk[a] - std::floor(ijk[a]);
          if (std::abs(f - 0.5) < 1e-3) {
            candidates[static_cast<std::size_t>(a)] = {static_cast<long>(std::floor(ijk[a])),
                                                       static_cast<long>(std::floor(ijk[a])) + 1};
          } else {
            candidates[static_cast<std::size_t>(a)] = {std::lround(ijk[a])};
          }
        }
        std::pair<int, int> range{1, 0};
        for (const long i : candidates[0])
          for (const long j : candidates[1])
            for (const long k : candidates[2]) {
              int value = 0;
              if (i >= 0 && j >= 0 && k >= 0 && i < static_cast<long>(map.size[0]) &&
                  j < static_cast<long>(map.size[1]) && k < static_cast<long>(map.size[2]))
                value = map.labels[static_cast<std::size_t>(i) +
                                   map.size[0] *
                                       (static_cast<std::size_t>(j) + map.size[1] * static_cast<std::size_t>(k))] != 0;
              range = {std::min(range.first, value), std::max(range.second, value)};
            }
        image.push_back(range);
      }
    return image;
  };
  // The pixels of `page` outside the range `expected` allows, and those the range fixes to 1.
  auto mismatch = [](const std::vector<int>& page_mask, const std::vector<std::pair<int, int>>& expected) {
    std::pair<std::size_t, std::size_t> counts{0, 0};
    for (std::size_t i = 0; i < page_mask.size(); ++i) {
      counts.first += page_mask[i] < expected[i].first || page_mask[i] > expected[i].second;
      counts.second += expected[i].first == 1;
    }
    return counts;
  };
  auto decoded = [](const nlohmann::json& rle) {
    std::vector<int> labels;
    for (std::size_t r = 0; r + 1 < rle.size(); r += 2)
      labels.insert(labels.end(), rle[r + 1].get<std::size_t>(), rle[r].get<int>());
    return labels;
  };
  auto outline = [](const std::vector<int>& m, std::size_t w) {
    const std::size_t ht = m.size() / w;
    std::vector<int> o(m.size(), 0);
    for (std::size_t i = 0; i < m.size(); ++i) {
      if (!m[i]) continue;
      const std::size_t c = i % w, row = i / w;
      o[i] = c == 0 || c + 1 == w || row == 0 || row + 1 == ht || !m[i - 1] || !m[i + 1] || !m[i - w] || !m[i + w];
    }
    return o;
  };
  const pneuma::image::LabelMap itv = pneuma::image::read_label_map(out / "voxels/itv-target.nii.gz");
  const auto& planes = page.data["slices"]["planes"];
  std::vector<std::vector<int>> rest_masks, itv_masks;
  for (const auto& plane : planes) {
    ASSERT_EQ(plane["structures"].size(), 1u);
    const auto& s = plane["structures"][0];
    ASSERT_EQ(s["masks"].size(), plane["times_s"].size());
    ASSERT_EQ(plane["times_s"][0].get<double>(), 0.0);
    const std::vector<int> rest = decoded(s["masks"][0]);
    const auto expected = sampled(plane, ball);
    ASSERT_EQ(rest.size(), expected.size());
    const auto [differ, pixels] = mismatch(rest, expected);
    std::printf("%s: the ball's %zu pixels at rest, %zu differ from the mask sampled here\n",
                plane["name"].get<std::string>().c_str(), pixels, differ);
    EXPECT_GT(pixels, 100u);  // a 30 mm ball through its centre on 2 mm pixels: about 177
    EXPECT_EQ(differ, 0u);
    const std::vector<int> itv_pixels = decoded(s["itv"]);
    const auto [itv_differ, itv_count] = mismatch(itv_pixels, sampled(plane, itv));
    std::printf("%s: the ITV's %zu pixels, %zu differ from itv-target sampled here\n",
                plane["name"].get<std::string>().c_str(), itv_count, itv_differ);
    EXPECT_GE(itv_count, pixels);  // the ball moves: its ITV is larger than it is at rest
    EXPECT_EQ(itv_differ, 0u);
    rest_masks.push_back(rest);
    itv_masks.push_back(itv_pixels);
  }

  // Chromium at rest and at end-inspiration: the outline pixels of the mask shown and of the ITV
  // (less where the mask's outline is drawn over it).
  const Csv voxels_csv = read_csv(out / "voxels/voxels.csv");
  const double inspiration = voxels_csv.rows[1][voxels_csv.column("time_s")];
  const Chromium c = open_in_chromium(dir, out / "report.html", fmt_times(0.0, inspiration));
  if (c.run.out.empty() && c.run.err.empty()) GTEST_SKIP() << "chromium not installed (Debian: apt install chromium)";
  ASSERT_EQ(c.run.exit_code, 0) << c.run.err;
  ASSERT_FALSE(c.selftest.empty() || c.selftest == "pending") << c.run.err;
  const auto result = nlohmann::json::parse(c.selftest);
  EXPECT_EQ(result["errors"], 0) << result["messages"].dump();
  for (std::size_t p = 0; p < 2; ++p) {
    const std::size_t w = planes[p]["width"].get<std::size_t>();
    for (std::size_t shot = 0; shot < 2; ++shot) {
      const auto& shown = result["slices"][shot][p];
      std::size_t t = 0;
      for (std::size_t k = 0; k < planes[p]["times_s"].size(); ++k)
        if (planes[p]["times_s"][k] == shown["time_s"]) t = k;
      const std::vector<int> mask = shot == 0 ? rest_masks[p] : decoded(planes[p]["structures"][0]["masks"][t]);
      const std::vector<int> edge = outline(mask, w), itv_edge = outline(itv_masks[p], w);
      std::size_t edge_pixels = 0, itv_only = 0;
      for (std::size_t i = 0; i < edge.size(); ++i) {
        edge_pixels += edge[i];
        itv_only += itv_edge[i] && !edge[i];
      }
      EXPECT_GT(edge_pixels, 20u);
      EXPECT_EQ(shown["structures"][0]["outline_pixels"].get<std::size_t>(), edge_pixels) << shown.dump();
      EXPECT_EQ(shown["structures"][0]["itv_outline_pixels"].get<std::size_t>(), itv_only) << shown.dump();
    }
  }
}
