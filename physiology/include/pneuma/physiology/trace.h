#pragma once
// A measured breathing signal as the source of V(t): a CSV trace (volume, flow or a surrogate
// amplitude), a Varian RPM `.vxp` file, or the CSV a Pulse Physiology Engine run writes.
//
// Reading (read_trace_file) checks every sample and names the file and line of the first bad
// one; processing (process_trace) turns the samples into the volume above FRC at the samples'
// times:
//   volume     the samples as given, minus the median end-expiratory volume (so V = 0 at FRC);
//   flow       integrated by the trapezoid rule, then the drift removed (below);
//   amplitude  drift removed, then scaled to volume by the calibration (a tidal volume, or a
//              volume per amplitude unit), and the median end-expiratory level set to 0.
// Drift: the least-squares line through the end-expiratory troughs (one per breath) is
// subtracted: for flow it is the integral of a constant flow offset (sensor offset, the
// inspired/expired gas mismatch), for a surrogate the slow baseline drift of the marker.
// Invalid samples (RPM validflag < 0) are dropped; a gap (no valid sample for more than 3 sample
// intervals: the RPM header's nominal one, else the median) is bridged by the straight line
// between its ends and counted. All of it is in TraceReport.
//
// Breaths are found by hysteresis around the signal's median (find_turning_points): for flow and
// amplitude on the signal with its least-squares line removed, for volume on the signal itself.
#include <cstddef>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "pneuma/physiology/simulate.h"

namespace pneuma::physiology {

enum class TraceSignal { volume, flow, amplitude };
enum class TraceFormat { csv, rpm };  // csv: any CSV with a header (Pulse's included)

struct Trace;

// How a surrogate amplitude becomes volume: exactly one of the three is given.
//   tidal_volume     the median breath's trough-to-peak swing becomes this volume;
//   volume_per_unit  the volume of one amplitude unit (cm for RPM);
//   spirometry       a volume (or flow) trace recorded at the same time, processed (FRC at 0):
//                    the volume per unit is the least-squares slope of its volume against the
//                    amplitude (drift removed) sampled at its times, over the stretch both cover.
struct TraceCalibration {
  double tidal_volume_m3 = 0.0;
  double volume_per_unit_m3 = 0.0;
  std::shared_ptr<const Trace> spirometry;
  double spirometry_offset_s = 0.0;  // the amplitude trace's time (from its first sample) of the spirometry's 0 s
};

struct TraceOptions {
  TraceFormat format = TraceFormat::csv;
  std::optional<TraceSignal> signal;  // CSV: which kind of column to use (default: found)
  std::string column;                 // CSV: the column's name as in the header (default: found)
  TraceCalibration calibration;       // amplitude only
  std::optional<bool> detrend;        // default: false for volume, true for flow and amplitude
  bool invert = false;                // amplitude: a marker that moves down on inspiration
  double start_s = 0.0;               // the trace's time that becomes the run's 0 s (from its first valid sample)
};

// The samples as read: times from the file's first sample, values in SI (m^3, m^3/s) or in the
// amplitude's own unit; one entry per data row.
struct RawTrace {
  std::filesystem::path file;
  TraceSignal signal = TraceSignal::volume;
  std::string column;          // the column used ("TotalLungVolume(mL)", "amplitude")
  std::string amplitude_unit;  // "cm" for RPM, the CSV header's unit, or "" (unitless)
  std::vector<double> time_s;
  std::vector<double> value;
  std::vector<bool> valid;          // false: flagged invalid by the file (RPM validflag < 0)
  std::vector<std::size_t> line;    // 1-based line of each sample, for messages
  double nominal_interval_s = 0.0;  // RPM: 1 / Samples_per_second; 0: unknown
};

// What processing did, for the manifest and phases.csv.
struct TraceReport {
  std::size_t samples = 0;
  std::size_t invalid_samples = 0;  // dropped
  std::size_t gaps = 0;             // bridged by a straight line
  double longest_gap_s = 0.0;
  double drift_m3_per_s = 0.0;      // slope of the removed trough line (volume units)
  double scale_m3_per_unit = 0.0;   // amplitude: the calibration applied
  double calibration_r2 = 0.0;      // spirometry: the squared correlation of the fit (1: exact)
  double calibration_span_s = 0.0;  // spirometry: the stretch both traces cover
  double reference_m3 = 0.0;        // what was subtracted so that FRC is 0 (volume: absolute FRC)
  std::size_t breaths = 0;
};

// A processed trace: the volume above FRC at the valid samples' times (from the file's first
// sample), ready to resample.
struct Trace {
  std::filesystem::path file;
  TraceSignal signal = TraceSignal::volume;
  std::string column;
  std::vector<double> time_s;
  std::vector<double> volume_m3;
  std::vector<std::size_t> line;
  TraceReport report;
  double start_s = 0.0;  // trace time of the run's 0 s
  double end_s() const { return time_s.empty() ? 0.0 : time_s.back(); }
};

// Reads a trace file. Throws IoError when it cannot be read, InputError
// ("<file>:<line>: <what is wrong>") for an empty file, a missing header field or column, text
// or NaN where a number goes, a time that does not increase, a volume below zero.
RawTrace read_trace_file(const std::filesystem::path& file, const TraceOptions& options);

// Processes a raw trace (see above). Throws InputError naming the file (and the line of the
// offending sample) for a trace with no breath, a calibration that cannot apply, or a volume
// far beyond a lung's range (more than 6 L above or 3 L below FRC).
Trace process_trace(const RawTrace& raw, const TraceOptions& options);

// One breath found on a volume signal: sample indices of its start trough, peak and end trough.
struct BreathCycle {
  std::size_t start = 0;
  std::size_t peak = 0;
  std::size_t end = 0;
};
// The turning points of a sampled volume signal, peaks and troughs alternating, in order: the
// extreme of each stretch beyond +-25 % of the half swing (5th to 95th percentile) around the
// median, for the stretches entered by a crossing (the first is cut; the last counts once the signal
// has turned back from its extreme by that band, else it may be unfinished).
struct TurningPoint {
  std::size_t index = 0;
  bool peak = false;
};
std::vector<TurningPoint> find_turning_points(const std::vector<double>& volume);
// Breaths of a sampled volume signal, trough to trough, in order. Throws nothing; fewer than
// three turning points give none.
std::vector<BreathCycle> find_breaths(const std::vector<double>& volume);

// The longest gap between samples a run may hold: beyond a few breaths the straight bridge over
// it is no breathing at all (a .vxp's first sample 1000 s early made a 30 s run one straight
// line 2.2 L above FRC, #49).
inline constexpr double kMaxGapInRunS = 15.0;
// Throws InputError ("<file>:<line>: ...", the sample after the gap) for the first gap longer
// than kMaxGapInRunS between samples within the run's window (trace time start_s from the first
// sample, for duration_s).
void check_gaps_in_run(const Trace& trace, double duration_s);

// The run's physiology from a trace: `duration_s` sampled at `rate_hz` from the trace's
// start_s (linear interpolation of the processed volume), flow the central difference of the
// interpolant over one sample interval, pressures NaN (a trace says nothing about them; the
// airway pressure is 0: spontaneous breathing at the open airway), breaths found by
// find_breaths (mode "trace"). Throws ValueError when the trace is shorter than the duration.
SimulationResult trace_result(const Trace& trace, double duration_s, double rate_hz);

const char* signal_name(TraceSignal signal);

}  // namespace pneuma::physiology
