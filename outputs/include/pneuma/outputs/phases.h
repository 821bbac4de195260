#pragma once
// phases.csv: the run's frames sorted into respiratory bins as 4D-CT sorts its images
// (physiology/phases.h: 0 % = end-inspiration, bins centred on 0, 100/N, ... %), one row per bin
// with its frames' times, mean volume and the breath cycles they came from; and, with
// `surfaces`, the surface of each bin at its mean volume (phases/bin_NN.ply, metres).
//
//   outputs:
//     phases:                      # off by default
//       bins: 10                   # 2 to 100
//       method: phase              # phase | amplitude
//       irregular: {min: 50 %, max: 150 %}   # cycles outside this share of the median amplitude are left out
//       surfaces: true             # phases/bin_NN.ply
//
// The manifest gets phases.* facts (cycles, irregular cycles, unassigned frames) and, when the
// drive is a measured trace, trace.* facts (samples, invalid samples, gaps, drift, calibration).
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "pneuma/outputs/output.h"
#include "pneuma/physiology/phases.h"

namespace pneuma::outputs {

// The key of the phases output under `outputs:`.
inline constexpr const char* kPhasesKey = "phases";

struct PhasesSpec {
  physiology::PhaseBinningOptions binning;
  bool surfaces = true;
  double metres_per_unit = 1e-3;  // phases/bin_NN.ply in mm (`unit: m` for metres), as the frames
};

// Writes phases.csv atomically: the bins of `binning`, made from samples at `time_s`.
// Throws IoError.
void write_phases_csv(const std::filesystem::path& path, const std::vector<double>& time_s,
                      const physiology::PhaseBinning& binning);

// Each model lung's scale s at a bin: the lung at the bin's mean of the volume it follows (the
// total, or its compartment's), through the same volume -> scale map as the frames.
std::vector<double> phase_bin_scales(const model::Model& model, const physiology::SimulationResult& drive,
                                     const physiology::PhaseBin& bin);

// The bins of a run's frames as `outputs.phases` sets them (its defaults when it is off).
physiology::PhaseBinning run_phase_bins(const RunRecord& run);

// The same for an output that writes the bins (`key`: where the scenario asked for them): a run
// that holds no whole cycle (end-inspiration to end-inspiration) is an InputError naming the
// scenario, the key, the run's length and the cycle it needs, not an empty set of bins.
physiology::PhaseBinning required_phase_bins(const RunRecord& run, const std::string& key);

// The trace's processing report as manifest facts ("trace.invalid_samples", ...).
std::vector<std::pair<std::string, std::string>> trace_facts(const physiology::Trace& trace);

OutputPlugin phases_output();

}  // namespace pneuma::outputs
