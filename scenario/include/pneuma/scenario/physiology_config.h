#pragma once
// Reads the `physiology` section of a scenario (with its preset) into a physiology::Protocol.
//
//   physiology:
//     preset: healthy-adult          # configs/physiology/healthy-adult.yaml; keys here override it
//     model: single                  # single | two_compartment
//     compliance: 0.1 L/cmH2O        # or pressure_volume_curve: {...} (Venegas sigmoid)
//     resistance: 2 cmH2O*s/L
//     driver: {mode: spontaneous, rate: 12 /min, ie_ratio: 1:2, tidal_volume: 500 mL}
//     actions:
//       - {at: 30 s, rate: 16 /min}                 # patch the current driver
//       - {at: 60 s, mode: volume_control, tidal_volume: 450 mL, peep: 5 cmH2O}
//       - {at: 90 s, compliance: 0.04 L/cmH2O}       # patch the mechanics
//       - {at: 120 s, expiratory_hold: 3 s}          # occlude at the next end of expiration
//     output_rate: 100 Hz
//     solver: {relative_tolerance: 1e-8, absolute_tolerance: 1e-9 L, max_step: 0.05 s}
//
// or a measured trace instead of the lumped model (physiology/trace.h; no preset, mechanics or
// actions then: the trace gives the volume):
//   physiology:
//     driver:
//       mode: trace
//       file: patient.vxp            # .vxp: Varian RPM; else CSV with a header (Pulse's too)
//       format: auto                 # auto (by extension) | csv | rpm
//       signal: amplitude            # volume | flow | amplitude (CSV: default, the column found)
//       column: TotalLungVolume(mL)  # CSV: the column to use (default: found by its name)
//       calibration: {tidal_volume: 500 mL}   # amplitude: or {volume_per_unit: 400 mL}
//       detrend: true                # default: false for volume, true for flow and amplitude
//       invert: false                # amplitude: the marker moves down on inspiration
//       start: 0 s                   # the trace's time that becomes the run's 0 s
//     output_rate: 100 Hz
//
// Every error is one line naming the file, line:column and key path.
#include <filesystem>
#include <optional>

#include "pneuma/physiology/simulate.h"
#include "pneuma/physiology/trace.h"
#include "pneuma/scenario/config.h"

namespace pneuma::scenario {

struct PhysiologyConfig {
  physiology::Protocol protocol;           // empty when `trace` is set
  std::optional<physiology::Trace> trace;  // a measured trace, read and processed at load time
  physiology::SimulationOptions options;   // duration comes from the scenario
};

// `section` is the scenario's physiology mapping; `config_dir` is where named presets live.
// Reads every key of the section (and its preset) and calls finish() on each mapping.
PhysiologyConfig read_physiology(const scenario::Node& section, double duration_s,
                                 const std::filesystem::path& config_dir);

// The folder of shipped presets (configs/: physiology/, tissue/), the first of: $PNEUMA_CONFIG_DIR
// if set; <prefix>/share/pneuma/configs beside the installed binary (bin/pneuma, or the Python
// module under <prefix>/lib/python3/dist-packages/pneuma); the source tree's configs/ when the
// binary lies in the build tree it was built in. Else the installed path (which is missing).
std::filesystem::path default_config_dir();

}  // namespace pneuma::scenario
