#pragma once
// Phase and amplitude binning of a breathing volume signal, as 4D-CT sorts its images.
//
// Convention (Varian RPM's): 0 % is end-inspiration. Cycles run from one end-inspiration (a
// peak of the volume, its time refined by the parabola through the peak sample and its two
// neighbours) to the next.
//   phase      the time within the cycle, linear: 0 % at its first peak, 100 % at the next;
//   amplitude  the volume within the cycle: 0 % at end-inspiration, 50 % at end-expiration
//              (the cycle's trough), from 0 to 50 % as the volume falls from the peak to the
//              trough (linearly in volume), from 50 to 100 % as it rises to the next peak.
// N bins (10 by default) are centred on 0, 100/N, ... %: bin b holds the samples within
// +-50/N % of b*100/N % (bin 0 takes both sides of end-inspiration). Samples before the first
// peak or after the last belong to no cycle and to no bin. A cycle whose amplitude (the mean of
// its two peaks above its trough) is outside [min, max] times the median cycle's is irregular:
// its samples are left out, and counted.
#include <cstddef>
#include <limits>
#include <vector>

namespace pneuma::physiology {

enum class BinningMethod { phase, amplitude };

// "phase" or "amplitude": the name the scenario, the manifest and the report use.
const char* binning_method_name(BinningMethod method);

struct PhaseBinningOptions {
  int bins = 10;
  BinningMethod method = BinningMethod::phase;
  double min_amplitude_ratio = 0.0;  // of the median cycle's amplitude
  double max_amplitude_ratio = std::numeric_limits<double>::infinity();
};

struct PhaseBin {
  double centre_percent = 0.0;       // b * 100 / N
  std::vector<std::size_t> samples;  // indices into the signal, in order
  std::vector<std::size_t> cycles;   // the cycles they came from (0-based), in order, once each
  double mean_volume_m3 = 0.0;       // NaN for an empty bin
  double min_volume_m3 = 0.0, max_volume_m3 = 0.0;
};

struct PhaseBinning {
  BinningMethod method = BinningMethod::phase;  // how the samples were binned
  std::vector<PhaseBin> bins;
  std::vector<double> position;        // per sample: phase or amplitude position in [0, 1), NaN outside any cycle
  std::vector<int> bin_of;             // per sample: its bin, -1 for none
  std::size_t cycles = 0;              // end-inspiration to end-inspiration
  std::size_t irregular_cycles = 0;    // left out
  std::size_t unassigned_samples = 0;  // outside any cycle or in an irregular one
};

// Bins the samples (time_s increasing, volume above any reference). Throws ValueError for
// fewer than 2 bins or more than 100, or mismatched sizes. A signal without two peaks gives
// empty bins (every sample unassigned).
PhaseBinning bin_phases(const std::vector<double>& time_s, const std::vector<double>& volume_m3,
                        const PhaseBinningOptions& options = {});

}  // namespace pneuma::physiology
