// Measured traces: every reader on files written here from closed forms, the processing against
// the closed form it came from, and the one-line errors of bad files.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <string>

#include <fmt/format.h>

#include "pneuma/core/error.h"
#include "pneuma/physiology/phases.h"
#include "pneuma/physiology/trace.h"
#include "test_support.h"

namespace {

using pneuma::InputError;
using namespace pneuma::physiology;
using pneuma::test::TempDir;

constexpr double kPi = 3.14159265358979323846;
constexpr double kPeriod = 4.3;    // s
constexpr double kTidal = 0.5e-3;  // m^3

// The breath every trace below records: volume above FRC, 0 at end-expiration (t = 0, T, ...).
double volume(double t) { return 0.5 * kTidal * (1.0 - std::cos(2.0 * kPi * t / kPeriod)); }
double flow(double t) { return 0.5 * kTidal * (2.0 * kPi / kPeriod) * std::sin(2.0 * kPi * t / kPeriod); }

Trace load(const std::filesystem::path& file, const TraceOptions& options = {}) {
  return process_trace(read_trace_file(file, options), options);
}

// Largest |sampled - closed form| over the run, as a share of the tidal volume.
double worst_error(const SimulationResult& r, double offset_s = 0.0) {
  double worst = 0.0;
  for (std::size_t k = 0; k < r.series.size(); ++k)
    worst = std::max(worst, std::abs(r.series.volume_m3[k] - volume(r.series.time_s[k] + offset_s)));
  return worst / kTidal;
}

std::string message_of(const std::filesystem::path& file, const TraceOptions& options = {}) {
  try {
    load(file, options);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(Trace, VolumeCsvIsReferencedToFrcAndResampled) {
  TempDir dir;
  std::string text = "time_s,volume_mL\n";
  for (int k = 0; k <= 40 * 50; ++k) {  // 40 s at 50 Hz, absolute volume (FRC 2.4 L)
    const double t = k / 50.0;
    text += fmt::format("{:.4f},{:.6f}\n", t, (2.4e-3 + volume(t)) * 1e6);
  }
  const Trace trace = load(dir.write("v.csv", text));
  EXPECT_EQ(trace.signal, TraceSignal::volume);
  EXPECT_NEAR(trace.report.reference_m3, 2.4e-3, 1e-9);
  EXPECT_EQ(trace.report.breaths, 8u);  // troughs at 0, 4.3, ..., 38.7 s: 9 troughs, the first cut
  const SimulationResult r = trace_result(trace, 30.0, 30.0);
  ASSERT_EQ(r.series.size(), 901u);
  EXPECT_LT(worst_error(r), 5e-3);
  // Flow: the central difference of the volume.
  for (std::size_t k = 1; k + 1 < r.series.size(); k += 37)
    EXPECT_NEAR(r.series.flow_m3_per_s[k], flow(r.series.time_s[k]), 0.01 * flow(kPeriod / 4));
  ASSERT_GE(r.breaths.size(), 5u);
  for (const BreathMetrics& b : r.breaths) {
    EXPECT_NEAR(b.duration_s, kPeriod, 0.05);
    EXPECT_NEAR(b.tidal_volume_m3, kTidal, 0.005 * kTidal);
    EXPECT_STREQ(b.mode, "trace");
  }
}

TEST(Trace, FlowWithOffsetAndNoiseIsIntegratedAndItsDriftRemoved) {
  TempDir dir;
  std::mt19937 random(7);
  std::normal_distribution<double> noise(0.0, 0.001);  // L/s
  std::string text = "# a spirometer export\ntime (s), flow (L/s)\n";
  const double offset = 0.03;  // L/s: 1.8 L/min of drift, 60 % of a tidal volume in 10 s
  for (int k = 0; k <= 60 * 100; ++k) {
    const double t = k / 100.0;
    text += fmt::format("{:.3f}, {:.7f}\n", t, flow(t) * 1e3 + offset + noise(random));
  }
  const Trace trace = load(dir.write("q.csv", text));
  EXPECT_EQ(trace.signal, TraceSignal::flow);
  EXPECT_NEAR(trace.report.drift_m3_per_s, offset * 1e-3, 0.02 * offset * 1e-3);
  const SimulationResult r = trace_result(trace, 55.0, 30.0);
  EXPECT_LT(worst_error(r), 5e-3);
}

TEST(Trace, AmplitudeWithDriftAndNoiseFollowsTheBreathWithinHalfAPercentAfterCalibration) {
  TempDir dir;
  std::mt19937 random(11);
  std::uniform_real_distribution<double> noise(-0.001, 0.001);  // cm, 0.1 % of the swing
  std::string text = "t_s,amplitude_cm\n";
  for (int k = 0; k <= 50 * 25; ++k) {
    const double t = k / 25.0;
    // 1 cm of marker motion per breath, a baseline sinking by 0.01 cm/s, and noise.
    text += fmt::format("{:.3f},{:.6f}\n", t, volume(t) / kTidal * 1.0 - 0.01 * t + 3.0 + noise(random));
  }
  TraceOptions options;
  options.calibration.tidal_volume_m3 = kTidal;
  const Trace trace = load(dir.write("a.csv", text), options);
  EXPECT_EQ(trace.signal, TraceSignal::amplitude);
  EXPECT_NEAR(trace.report.scale_m3_per_unit, kTidal, 0.005 * kTidal);  // 500 mL per cm
  const SimulationResult r = trace_result(trace, 48.0, 30.0);
  EXPECT_LT(worst_error(r), 5e-3);

  // The same with a volume per unit, and a marker that moves the other way.
  std::string inverted = "time_s,amplitude\n";
  for (int k = 0; k <= 30 * 25; ++k)
    inverted += fmt::format("{:.3f},{:.6f}\n", k / 25.0, -2.0 * volume(k / 25.0) / kTidal);
  TraceOptions per_unit;
  per_unit.invert = true;
  per_unit.calibration.volume_per_unit_m3 = 0.25e-3;
  EXPECT_LT(worst_error(trace_result(load(dir.write("b.csv", inverted), per_unit), 25.0, 10.0)), 1e-3);
}

TEST(Trace, StartShiftsTheRunIntoTheTrace) {
  TempDir dir;
  std::string text = "time_ms,volume_L\n";
  for (int k = 0; k <= 2000; ++k) text += fmt::format("{},{:.7f}\n", k * 10, (2.0e-3 + volume(k / 100.0)) * 1e3);
  TraceOptions options;
  options.start_s = 2.0;
  const Trace trace = load(dir.write("v.csv", text), options);
  EXPECT_LT(worst_error(trace_result(trace, 15.0, 20.0), 2.0), 2e-3);
  EXPECT_THROW(trace_result(trace, 18.5, 20.0), pneuma::ValueError);
}

TEST(Trace, PulseEngineCsvDrivesByItsTotalLungVolume) {
  TempDir dir;
  std::string text = "Time(s),HeartRate(1/min),TidalVolume(mL),TotalLungVolume(mL),RespirationRate(1/min)\n";
  for (int k = 0; k <= 30 * 50; ++k) {
    const double t = k / 50.0;
    text += fmt::format("{:.2f},72.0,500.0,{:.4f},14.0\n", t, (2.3e-3 + volume(t)) * 1e6);
  }
  const Trace trace = load(dir.write("pulse.csv", text));
  EXPECT_EQ(trace.column, "TotalLungVolume(mL)");
  EXPECT_NEAR(trace.report.reference_m3, 2.3e-3, 1e-9);
  EXPECT_LT(worst_error(trace_result(trace, 25.0, 30.0)), 2e-3);
}

// The marker of the RPM files below: 1.2 cm per breath above a 0.4 cm baseline.
double marker_cm(double t) { return 1.2 * volume(t) / kTidal + 0.4; }

// A Varian RPM .vxp file as plastimatch's readrpm.m reads it: the amplitude in cm is the value
// times Scale_factor / 10, the timestamp in ms, validflag < 0 invalid.
std::string vxp(int seconds, double rate_hz, bool with_invalid, double scale_factor = 10.0) {
  std::string text =
      "[Header]\nCRC=12345\nVersion=1.6\nData_layout=amplitude,phase,timestamp,validflag,ttlin,mark,ttlout\n"
      "Patient_ID=phantom\nDate=11-24-2026\nTotal_study_time=" +
      std::to_string(seconds) + "\nSamples_per_second=" + fmt::format("{}", rate_hz) +
      fmt::format("\nScale_factor={:.1f}\n[Data]\n", scale_factor);
  const int n = static_cast<int>(seconds * rate_hz);
  for (int k = 0; k <= n; ++k) {
    const double t = k / rate_hz;
    const double phase = std::fmod(2.0 * kPi * (t / kPeriod + 0.5), 2.0 * kPi);  // 0 at end-inspiration
    const bool invalid = with_invalid && (k % 97 == 5 || (k >= 300 && k < 320));
    const double value = invalid ? 87.0 : marker_cm(t) * 10.0 / scale_factor;
    const char* mark = std::abs(phase) < 1e-9 ? "Z" : "";
    text += fmt::format("{:.5f},{:.4f},{:.0f},{},0,{},0\n", value, phase, 5000.0 + t * 1000.0, invalid ? -1 : 0, mark);
  }
  return text;
}

// The older RPM .dat as readrpm.m reads it: "CRC..." and "VERSION = 1.x," then 8 more header
// lines, then rows of amplitude (cm), [two more fields in 1.7,] phase, timestamp (ms), validflag,
// video index, ttlin, beam.
std::string dat(const char* version, int seconds, double rate_hz) {
  std::string text =
      fmt::format("CRC=2F4A\nVERSION = {},\n0.4000,0.0000,\n#TRUE#,\n30.0000,70.0000,\n0,\n0,\n0,\n0,\n0,\n", version);
  const bool v17 = std::string(version) == "1.7";
  const int n = static_cast<int>(seconds * rate_hz);
  for (int k = 0; k <= n; ++k) {
    const double t = k / rate_hz;
    const double phase = std::fmod(2.0 * kPi * (t / kPeriod + 0.5), 2.0 * kPi);
    const int valid = k % 53 == 7 ? -2 : 0;  // -2: non-periodic breathing (a cough)
    const double amplitude = valid < 0 ? -5.0 : marker_cm(t);
    text += fmt::format("{:.5f},{}{:.4f},{:.0f},{},{},0,0,\n", amplitude, v17 ? "0,0," : "", phase, 2000.0 + t * 1000.0,
                        valid, k);
  }
  return text;
}

TEST(Trace, RpmVxpDropsInvalidSamplesAndBridgesTheGap) {
  TempDir dir;
  TraceOptions options;
  options.format = TraceFormat::rpm;
  options.calibration.tidal_volume_m3 = kTidal;
  const RawTrace raw = read_trace_file(dir.write("p.vxp", vxp(40, 30.0, true)), options);
  EXPECT_EQ(raw.amplitude_unit, "cm");
  EXPECT_NEAR(raw.value[1], marker_cm(1.0 / 30.0), 1e-5);  // cm
  // Another Scale_factor, the same marker: Scale_factor 1 stores tenfold values (mm).
  const RawTrace mm = read_trace_file(dir.write("mm.vxp", vxp(40, 30.0, true, 1.0)), options);
  for (std::size_t k = 0; k < raw.value.size(); k += 50) {
    if (raw.valid[k]) {
      EXPECT_NEAR(mm.value[k], raw.value[k], 1e-5) << k;
    }
  }
  EXPECT_EQ(raw.line.front(), 11u);
  const Trace trace = process_trace(raw, options);
  std::size_t expected_invalid = 20;
  for (int k = 0; k <= 1200; ++k) expected_invalid += (k % 97 == 5 && !(k >= 300 && k < 320)) ? 1 : 0;
  EXPECT_EQ(trace.report.invalid_samples, expected_invalid);
  EXPECT_EQ(trace.report.gaps, 1u);  // the 20 samples in a row; single ones are 2 intervals
  EXPECT_NEAR(trace.report.longest_gap_s, 21.0 / 30.0, 1e-6);
  EXPECT_NEAR(trace.report.scale_m3_per_unit, kTidal / 1.2, 0.005 * kTidal / 1.2);  // per cm
  // The gap lies at 10 - 10.67 s, where a straight line cannot follow the breath: compare elsewhere.
  const SimulationResult r = trace_result(trace, 38.0, 30.0);
  double worst = 0.0;
  for (std::size_t k = 0; k < r.series.size(); ++k) {
    const double t = r.series.time_s[k];
    if (t > 9.9 && t < 10.8) continue;
    worst = std::max(worst, std::abs(r.series.volume_m3[k] - volume(t)));
  }
  EXPECT_LT(worst / kTidal, 5e-3);
}

TEST(Trace, RpmDatVersions14And17ReadAsPlastimatchReadsThem) {
  TempDir dir;
  TraceOptions options;
  options.format = TraceFormat::rpm;
  options.calibration.tidal_volume_m3 = kTidal;
  for (const char* version : {"1.4", "1.7"}) {
    const RawTrace raw = read_trace_file(dir.write("p.dat", dat(version, 30, 25.0)), options);
    ASSERT_EQ(raw.time_s.size(), 751u) << version;
    EXPECT_EQ(raw.line.front(), 11u);
    EXPECT_EQ(raw.amplitude_unit, "cm");
    EXPECT_NEAR(raw.time_s[100], 4.0, 1e-9);  // from the first sample's 2000 ms
    EXPECT_NEAR(raw.value[100], marker_cm(4.0), 1e-5);
    EXPECT_FALSE(raw.valid[7]);
    const Trace trace = process_trace(raw, options);
    std::size_t coughs = 0;
    for (int k = 0; k <= 750; ++k) coughs += k % 53 == 7;
    EXPECT_EQ(trace.report.invalid_samples, coughs) << version;
    EXPECT_NEAR(trace.report.scale_m3_per_unit, kTidal / 1.2, 0.005 * kTidal / 1.2) << version;  // per cm
    EXPECT_LT(worst_error(trace_result(trace, 29.0, 25.0)), 5e-3) << version;
  }
  const std::string d = dir.path().string() + "/";
  std::string v9 = dat("1.4", 10, 25.0);
  v9.replace(v9.find("VERSION = 1.4"), 13, "VERSION = 1.9");
  EXPECT_EQ(message_of(dir.write("v9.dat", v9), options),
            d + "v9.dat:2: RPM .dat version 'VERSION = 1.9,' (expected 'VERSION = 1.4' or 'VERSION = 1.7')");
  std::string short_row = dat("1.7", 10, 25.0);
  short_row.replace(short_row.find("0,0,", short_row.find("\n0,\n0,\n0,\n0,\n0,\n") + 10), 4, "");
  EXPECT_EQ(message_of(dir.write("short.dat", short_row), options),
            d + "short.dat:11: expected 9 fields (amplitude,_,_,phase,timestamp,validflag,video,ttlin,beam), got 7");
  EXPECT_EQ(message_of(dir.write("head.dat", "CRC=1\nVERSION = 1.4,\n0,0,\n"), options),
            d + "head.dat:3: no samples after the RPM .dat header (10 lines)");
}

// A surrogate calibrated by a spirometer recorded over part of the session: the marker is the
// volume times 2.4 cm/L, plus a sinking baseline and noise; the spirometer's volume (absolute,
// its own clock starting 6 s into the marker's) covers 20 s. The calibration is the slope of the
// one against the other: 1 / 2.4 L per cm.
TEST(Trace, SpirometryCalibratesAnAmplitudeToVolume) {
  TempDir dir;
  std::mt19937 random(7);
  std::normal_distribution<double> noise(0.0, 0.005);  // cm
  std::string marker = "time_s,amplitude_cm\n";
  for (int k = 0; k <= 60 * 25; ++k) {
    const double t = k / 25.0;
    marker += fmt::format("{:.3f},{:.5f}\n", t, 2.4e3 * volume(t) + 1.0 - 0.003 * t + noise(random));
  }
  std::string spiro = "time_s,volume_mL\n";
  for (int k = 0; k <= 20 * 50; ++k) {
    const double t = k / 50.0;
    spiro += fmt::format("{:.3f},{:.4f}\n", t, (2.6e-3 + volume(t + 6.0)) * 1e6);
  }
  TraceOptions options;
  options.calibration.spirometry = std::make_shared<const Trace>(load(dir.write("spiro.csv", spiro)));
  options.calibration.spirometry_offset_s = 6.0;
  const Trace trace = load(dir.write("marker.csv", marker), options);
  EXPECT_NEAR(trace.report.scale_m3_per_unit, 1e-3 / 2.4, 0.005 * 1e-3 / 2.4);
  EXPECT_GT(trace.report.calibration_r2, 0.99);
  EXPECT_NEAR(trace.report.calibration_span_s, 20.0, 1e-6);
  // The calibrated trace follows the closed form within 0.5 % of a breath (the noise is 0.8 %
  // of a breath per sample; the frames interpolate it).
  EXPECT_LT(worst_error(trace_result(trace, 55.0, 25.0)), 0.02);
  double mean_error = 0.0;
  const SimulationResult r = trace_result(trace, 55.0, 25.0);
  for (std::size_t k = 0; k < r.series.size(); ++k)
    mean_error += std::abs(r.series.volume_m3[k] - volume(r.series.time_s[k]));
  EXPECT_LT(mean_error / static_cast<double>(r.series.size()) / kTidal, 0.005);

  // The wrong offset (half a breath off): the two disagree, and the message says so.
  options.calibration.spirometry_offset_s = 6.0 + kPeriod / 2;
  const std::string wrong = message_of(dir.path() / "marker.csv", options);
  EXPECT_NE(wrong.find("marker.csv: the amplitude falls as the spirometer's volume rises"), std::string::npos) << wrong;
  options.calibration.spirometry_offset_s = 6.0 + kPeriod / 4;
  const std::string quarter = message_of(dir.path() / "marker.csv", options);
  EXPECT_NE(quarter.find("agree poorly over their common 20.0 s"), std::string::npos) << quarter;
  // A spirometry beyond the marker's end.
  options.calibration.spirometry_offset_s = 58.0;
  const std::string outside = message_of(dir.path() / "marker.csv", options);
  EXPECT_NE(outside.find("spiro.csv: the spirometry (58.0 to 78.0 s on this trace's clock) covers no whole breath"),
            std::string::npos)
      << outside;
}

TEST(Trace, BadFilesAreOneLineNamingFileAndLine) {
  TempDir dir;
  const auto f = [&](const std::string& name, const std::string& text) { return dir.write(name, text); };
  const std::string d = dir.path().string() + "/";
  EXPECT_EQ(message_of(f("empty.csv", "")),
            d + "empty.csv: empty trace (expected a header line such as 'time_s,volume_mL', then samples)");
  EXPECT_EQ(message_of(f("header.csv", "time_s,volume_mL\n")),
            d + "header.csv:1: no samples after the header (expected rows such as '0.0,2400')");
  EXPECT_EQ(message_of(f("order.csv", "time_s,volume_mL\n0,2400\n0.1,2410\n0.1,2420\n")),
            d + "order.csv:4: time 0.1 is not after the previous sample's 0.1 (times must increase)");
  EXPECT_EQ(message_of(f("text.csv", "time_s,volume_mL\n0,2400\n0.1,abc\n")),
            d + "text.csv:3: column 'volume_mL': expected a number, got 'abc'");
  EXPECT_EQ(message_of(f("nan.csv", "time_s,volume_mL\n0,2400\n0.1,nan\n")),
            d + "nan.csv:3: column 'volume_mL': expected a number, got 'nan'");
  EXPECT_EQ(message_of(f("negative.csv", "time_s,volume_mL\n0,2400\n0.1,-5\n")),
            d + "negative.csv:3: volume -5 mL is below zero (expected a lung volume)");
  EXPECT_EQ(message_of(f("huge.csv", "time_s,volume_L\n0,2.4\n0.1,2400\n")),
            d + "huge.csv:3: volume 2400 L is far beyond a lung's range (at most 10 L; is the unit right?)");
  EXPECT_EQ(
      message_of(f("notime.csv", "seconds,volume_mL\n0,2400\n")),
      d + "notime.csv:1: no time column (expected a header such as 'time_s' or 'Time(s)'; columns: 'seconds', 'volume_mL')");
  EXPECT_EQ(message_of(f("timeunit.csv", "time,volume_mL\n0,2400\n")),
            d + "timeunit.csv:1: column 'time': expected a time with its unit, such as 'time_s' or 'time (s)'");
  EXPECT_EQ(
      message_of(f("volunit.csv", "time_s,volume\n0,2400\n")),
      d + "volunit.csv:1: column 'volume': expected a volume with its unit, such as 'volume_mL' or 'volume (mL)'");
  EXPECT_EQ(
      message_of(f("nocol.csv", "time_s,pressure_cmH2O\n0,5\n")),
      d + "nocol.csv:1: no volume, flow or amplitude column (columns: 'time_s', 'pressure_cmH2O'; name one with the driver's 'column')");
  EXPECT_EQ(message_of(f("short.csv", "time_s,volume_mL\n0,2400\n0.1\n")),
            d + "short.csv:3: expected 2 columns, got 1");
  EXPECT_EQ(
      message_of(f("flat.csv", "time_s,volume_mL\n0,2400\n1,2400\n2,2400\n3,2400\n")),
      d + "flat.csv: no breath found in column 'volume_mL' (expected at least one trough-to-trough cycle of a breathing signal)");
  // A breath of 8 L above FRC.
  std::string big = "time_s,volume_mL\n";
  for (int k = 0; k <= 200; ++k)
    big += fmt::format("{:.2f},{:.1f}\n", k / 10.0, 1000.0 + 8000.0 * volume(k / 10.0) / kTidal);
  EXPECT_EQ(message_of(f("big.csv", big)).substr(0, d.size() + 11), d + "big.csv:17:");
  EXPECT_NE(message_of(f("big.csv", big)).find("far beyond a lung's range (-3000 mL to +6000 mL"), std::string::npos);

  TraceOptions rpm;
  rpm.format = TraceFormat::rpm;
  rpm.calibration.tidal_volume_m3 = kTidal;
  std::string no_scale = vxp(10, 10.0, false);
  no_scale.erase(no_scale.find("Scale_factor=10.0\n"), 18);
  EXPECT_EQ(
      message_of(f("noscale.vxp", no_scale), rpm),
      d + "noscale.vxp:1: the RPM header has no 'Scale_factor' (needed: Version, Data_layout, Samples_per_second, Scale_factor)");
  std::string v2 = vxp(10, 10.0, false);
  v2.replace(v2.find("Version=1.6"), 11, "Version=2.0");
  EXPECT_EQ(message_of(f("v2.vxp", v2), rpm), d + "v2.vxp:3: RPM version '2.0' (expected 1.5 or 1.6)");
  EXPECT_EQ(message_of(f("csv.vxp", "time_s,volume_mL\n"), rpm),
            d + "csv.vxp:1: expected '[Header]' (a Varian RPM .vxp file), got 'time_s,volume_mL'");
  std::string bad_row = vxp(10, 10.0, false);
  bad_row.replace(bad_row.find("[Data]\n") + 7, 6, "x.xxxx");
  EXPECT_EQ(message_of(f("row.vxp", bad_row), rpm).substr(0, d.size() + 27), d + "row.vxp:11: amplitude: expe");
}

// Phase binning of a regular sinusoid against its closed form: the peaks are at t = T/2 + i T.
TEST(PhaseBins, RegularSinusoidBinsHoldTheExpectedTimePoints) {
  std::vector<double> t, v;
  for (int k = 0; k <= 30 * 40; ++k) {
    t.push_back(k / 30.0);
    v.push_back(volume(t.back()));
  }
  for (BinningMethod method : {BinningMethod::phase, BinningMethod::amplitude}) {
    const PhaseBinning bins = bin_phases(t, v, {10, method});
    ASSERT_EQ(bins.bins.size(), 10u);
    EXPECT_EQ(bins.method, method);
    EXPECT_EQ(bins.cycles, 8u);  // peaks at 2.15, 6.45, ..., 36.55 s
    std::size_t checked = 0, near_edge = 0;
    for (std::size_t k = 0; k < t.size(); ++k) {
      const double phase = (t[k] - kPeriod / 2) / kPeriod;  // cycles since the first peak
      if (phase < 0.0 || phase >= 8.0) {
        EXPECT_EQ(bins.bin_of[k], -1) << t[k];
        continue;
      }
      const double in_cycle = phase - std::floor(phase);
      // Amplitude position: (1 - cos)/4 from the peak down to the trough (in_cycle 1/2), then back up.
      const double a = 0.5 * (1.0 + std::cos(2.0 * kPi * in_cycle));
      const double position =
          method == BinningMethod::phase ? in_cycle : (in_cycle < 0.5 ? 0.5 * (1.0 - a) : 0.5 + 0.5 * a);
      const double x = position * 10.0 + 0.5;
      if (std::abs(x - std::round(x)) < 2e-3) {  // on a bin edge: either side is right
        ++near_edge;
        continue;
      }
      EXPECT_EQ(bins.bin_of[k], static_cast<int>(std::floor(x)) % 10) << "t = " << t[k];
      ++checked;
    }
    EXPECT_LT(near_edge, 12u);
    EXPECT_GT(checked, 1000u);
    if (method == BinningMethod::phase) {
      // Equal phase bins of a regular breath hold equal shares of its time (within one sample per cycle).
      for (const PhaseBin& b : bins.bins) EXPECT_NEAR(static_cast<double>(b.samples.size()), 8 * kPeriod * 3.0, 8.0);
      // The mean volume of a phase bin is the mean of the closed form over its phase interval.
      for (std::size_t b = 0; b < 10; ++b) {
        const double c = 2.0 * kPi * static_cast<double>(b) / 10.0, h = kPi / 10.0;
        // V = T/2 (1 + cos(2 pi phase)) from the peak: mean over [c - h, c + h].
        const double expected = 0.5 * kTidal * (1.0 + (std::sin(c + h) - std::sin(c - h)) / (2.0 * h));
        EXPECT_NEAR(bins.bins[b].mean_volume_m3, expected, 0.01 * kTidal) << b;
      }
    } else {
      // Amplitude bins 0 and 5 sit at end-inspiration and end-expiration.
      EXPECT_NEAR(bins.bins[0].mean_volume_m3, kTidal, 0.06 * kTidal);
      EXPECT_NEAR(bins.bins[5].mean_volume_m3, 0.0, 0.06 * kTidal);
    }
  }
}

TEST(PhaseBins, IrregularBreathsAreLeftOutAndCounted) {
  std::vector<double> t, v;
  for (int k = 0; k <= 20 * 40; ++k) {
    t.push_back(k / 20.0);
    const double deep = (t.back() > 3 * kPeriod && t.back() < 4 * kPeriod) ? 2.0 : 1.0;  // one deep breath
    v.push_back(deep * volume(t.back()));
  }
  PhaseBinningOptions options;
  options.min_amplitude_ratio = 0.8;
  options.max_amplitude_ratio = 1.2;
  const PhaseBinning bins = bin_phases(t, v, options);
  EXPECT_EQ(bins.cycles, 8u);
  EXPECT_EQ(bins.irregular_cycles, 2u);  // the deep breath's peak ends one cycle and starts the next
  for (std::size_t k = 0; k < t.size(); ++k) {
    if (t[k] > 2.5 * kPeriod && t[k] < 4.5 * kPeriod) {
      EXPECT_EQ(bins.bin_of[k], -1) << t[k];
    }
  }
  EXPECT_THROW(bin_phases(t, v, {1}), pneuma::ValueError);
}

}  // namespace

namespace {

// The run's trace as the scenario reader makes it, then its window checked for gaps.
std::string gap_message(const std::filesystem::path& file, const TraceOptions& options, double duration_s) {
  try {
    check_gaps_in_run(load(file, options), duration_s);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

// #49: Excel's "CSV UTF-8" writes a byte-order mark, read as nothing in every trace format; a
// first sample 1000 s before the rest made a 30 s run one straight line, now refused at the line
// after the gap unless the run starts after it.
TEST(Trace, ByteOrderMarkIsReadAsNothingAndALongGapInTheRunIsRefused) {
  TempDir dir;
  TraceOptions rpm;
  rpm.format = TraceFormat::rpm;
  rpm.calibration.tidal_volume_m3 = kTidal;
  const std::string text = vxp(40, 30.0, false);
  const RawTrace plain = read_trace_file(dir.write("p.vxp", text), rpm);
  const RawTrace bom = read_trace_file(dir.write("bom.vxp", "\xEF\xBB\xBF" + text), rpm);
  EXPECT_EQ(bom.time_s, plain.time_s);
  EXPECT_EQ(bom.value, plain.value);
  const std::string csv = "time_s,volume_mL\n0,2400\n1,2700\n2,2400\n";
  const RawTrace csv_bom = read_trace_file(dir.write("bom.csv", "\xEF\xBB\xBF" + csv), {});
  EXPECT_EQ(csv_bom.value, read_trace_file(dir.write("plain.csv", csv), {}).value);

  std::string early = text;
  const std::size_t first_row = early.find("[Data]\n") + 7;
  early.replace(early.find(",5000,", first_row), 6, ",-995000,");  // line 11: 1000 s before line 12
  const auto file = dir.write("early.vxp", early);
  EXPECT_EQ(gap_message(file, rpm, 30.0),
            file.string() +
                ":12: no sample for 1000.03 s before this one, inside the run (trace time 0 to 30 s): expected gaps of "
                "at most 15 s (a few breaths); start the run after it with the trace's 'start'");
  TraceOptions later = rpm;
  later.start_s = 1001.0;
  EXPECT_EQ(gap_message(file, later, 30.0), "no error");
  EXPECT_EQ(gap_message(dir.write("whole.vxp", text), rpm, 30.0), "no error");
}
