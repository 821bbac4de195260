// Breathing traces: the CSV reader (EXTENSION .csv) or the Varian RPM reader (.vxp), then the
// processing (breaths, drift, calibration, range checks) and the binning of what comes out.
#include <string>

#include "fuzz_input.h"
#include "pneuma/core/error.h"
#include "pneuma/physiology/phases.h"
#include "pneuma/physiology/trace.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace pneuma::physiology;
  const std::string extension = PNEUMA_FUZZ_EXTENSION;
  TraceOptions options;
  options.format = extension == ".vxp" ? TraceFormat::rpm : TraceFormat::csv;
  options.calibration.tidal_volume_m3 = 0.5e-3;
  try {
    const Trace trace =
        process_trace(read_trace_file(pneuma::fuzz::write_input(data, size, PNEUMA_FUZZ_EXTENSION), options), options);
    const double duration = trace.end_s() - trace.time_s.front();
    if (duration > 0.0 && duration < 3600.0) {
      const SimulationResult r = trace_result(trace, duration, 10.0);
      (void)bin_phases(r.series.time_s, r.series.volume_m3);
    }
  } catch (const pneuma::Error&) {
  }
  return 0;
}
