#include <fmt/format.h>

#include <cmath>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "pneuma/model/compile.h"
#include "pneuma/model/frame.h"
#include "pneuma/outputs/frame_outputs.h"
#include "pneuma/outputs/phases.h"

namespace pneuma::outputs {
namespace {

namespace kind = units::kind;

std::string joined(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) {
    if (!out.empty()) out += ' ';
    out += item;
  }
  return out;
}

std::any read_spec(const scenario::Node* options, const scenario::Scenario& /*run*/) {
  PhasesSpec spec;
  if (!options) return spec;
  spec.binning.bins = static_cast<int>(options->integer("bins", 10, 2, 100));
  if (options->has("method"))
    spec.binning.method = options->choice("method", {"phase", "amplitude"}) == "amplitude"
                              ? physiology::BinningMethod::amplitude
                              : physiology::BinningMethod::phase;
  if (auto band = options->optional_map("irregular")) {
    if (auto lo = band->optional_quantity("min", kind::fraction)) spec.binning.min_amplitude_ratio = *lo;
    if (auto hi = band->optional_quantity("max", kind::fraction)) spec.binning.max_amplitude_ratio = *hi;
    if (!(spec.binning.min_amplitude_ratio >= 0.0 &&
          spec.binning.max_amplitude_ratio > spec.binning.min_amplitude_ratio))
      band->fail("expected 0 <= min < max, such as '{min: 50 %, max: 150 %}'");
    band->finish();
  }
  spec.surfaces = options->boolean("surfaces", true);
  spec.metres_per_unit = read_mesh_file_unit(*options);
  return spec;
}

class Phases final : public Output {
 public:
  Phases(std::filesystem::path dir, PhasesSpec spec) : dir_(std::move(dir)), spec_(spec) {}
  std::string name() const override { return kPhasesKey; }

  std::vector<std::filesystem::path> finish(const model::Model& model, const RunRecord& run) override {
    const auto& series = run.drive->series;
    // The bins the report and voxels use.
    const physiology::PhaseBinning binning = required_phase_bins(run, std::string("outputs.") + kPhasesKey);
    std::vector<std::filesystem::path> files{dir_ / "phases.csv"};
    write_phases_csv(files.front(), series.time_s, binning);
    facts_ = {{"phases.bins", std::to_string(binning.bins.size())},
              {"phases.method", physiology::binning_method_name(binning.method)},
              {"phases.cycles", std::to_string(binning.cycles)},
              {"phases.irregular_cycles", std::to_string(binning.irregular_cycles)},
              {"phases.unassigned_frames", std::to_string(binning.unassigned_samples)}};
    if (run.scenario && run.scenario->physiology.trace) {
      for (auto& fact : trace_facts(*run.scenario->physiology.trace)) facts_.push_back(std::move(fact));
    }
    if (spec_.surfaces) {
      // Each bin's surface at its mean volume (phase_bin_scales). Two lungs: one surface per lung
      // per bin (bin_00_right.ply, bin_00_left.ply).
      std::filesystem::create_directories(dir_ / "phases");
      model::Frame frame(model);
      std::vector<mesh::TriangleMesh> surfaces;
      for (const model::LungModel& lung : model.lungs) surfaces.push_back(lung.rest);
      mesh::WriteOptions options;
      options.metres_per_unit = spec_.metres_per_unit;
      for (std::size_t b = 0; b < binning.bins.size(); ++b) {
        const physiology::PhaseBin& bin = binning.bins[b];
        if (bin.samples.empty()) continue;
        model::FrameInput input{b, 0.0, bin.mean_volume_m3, {}};
        const std::vector<double> scales = phase_bin_scales(model, *run.drive, bin);
        for (std::size_t i = 0; i < model.lungs.size(); ++i) input.scale[i] = scales[i];
        model::advance(model, input, frame);
        for (std::size_t i = 0; i < model.lungs.size(); ++i) {
          surfaces[i].vertices = frame.lungs[i].positions;
          const std::string name = model.two_lungs()
                                       ? fmt::format("bin_{:02}_{}.ply", b, scenario::lung_name(model.lungs[i].side))
                                       : fmt::format("bin_{:02}.ply", b);
          files.push_back(dir_ / "phases" / name);
          mesh::write_mesh(files.back(), surfaces[i], options);
        }
      }
    }
    return files;
  }
  std::vector<std::pair<std::string, std::string>> facts() const override { return facts_; }

 private:
  std::filesystem::path dir_;
  PhasesSpec spec_;
  std::vector<std::pair<std::string, std::string>> facts_;
};

}  // namespace

void write_phases_csv(const std::filesystem::path& path, const std::vector<double>& time_s,
                      const physiology::PhaseBinning& binning) {
  write_stream_atomically(path, false, [&](std::ostream& out) {
    out << "bin,phase_percent,frames,cycle_count,mean_volume_mL,min_volume_mL,max_volume_mL,cycles,times_s\n";
    for (std::size_t b = 0; b < binning.bins.size(); ++b) {
      const physiology::PhaseBin& bin = binning.bins[b];
      std::vector<std::string> cycles, times;
      for (std::size_t c : bin.cycles) cycles.push_back(std::to_string(c + 1));
      for (std::size_t k : bin.samples) times.push_back(fmt::format("{:.6f}", time_s[k]));
      auto ml = [](double m3) { return std::isfinite(m3) ? fmt::format("{:.6g}", m3 * 1e6) : std::string(); };
      out << fmt::format("{},{:.6g},{},{},{},{},{},{},{}\n", b, bin.centre_percent, bin.samples.size(),
                         bin.cycles.size(), ml(bin.mean_volume_m3), ml(bin.min_volume_m3), ml(bin.max_volume_m3),
                         joined(cycles), joined(times));
    }
  });
}

std::vector<double> phase_bin_scales(const model::Model& model, const physiology::SimulationResult& drive,
                                     const physiology::PhaseBin& bin) {
  std::vector<double> scales;
  for (const model::LungModel& lung : model.lungs) {
    double volume = bin.mean_volume_m3;
    if (lung.compartment >= 0) {
      const std::vector<double>& v = lung.volumes(drive);
      volume = 0.0;
      for (std::size_t k : bin.samples) volume += v[k];
      volume /= static_cast<double>(bin.samples.size());
    }
    scales.push_back(lung.scales({0.0}, {volume}).front());
  }
  return scales;
}

physiology::PhaseBinning required_phase_bins(const RunRecord& run, const std::string& key) {
  physiology::PhaseBinning binning = run_phase_bins(run);
  if (binning.cycles > 0) return binning;
  const auto& t = run.drive->series.time_s;
  const double length_s = t.empty() ? 0.0 : t.back() - t.front();
  const std::string irregular =
      binning.irregular_cycles > 0 ? fmt::format(" ({} irregular ones left out)", binning.irregular_cycles) : "";
  throw InputError(fmt::format(
      "{}: {}: the {:.3g} s run holds no whole breathing cycle, end-inspiration to end-inspiration{}, to bin into "
      "phases; expected a longer duration, two breaths at least",
      run.scenario->file.string(), key, length_s, irregular));
}

physiology::PhaseBinning run_phase_bins(const RunRecord& run) {
  PhasesSpec spec;
  if (const scenario::OutputRequest* phases = run.scenario->output(kPhasesKey)) {
    spec = std::any_cast<PhasesSpec>(phases->settings);
  }
  const auto& series = run.drive->series;
  return physiology::bin_phases(series.time_s, series.volume_m3, spec.binning);
}

std::vector<std::pair<std::string, std::string>> trace_facts(const physiology::Trace& trace) {
  const physiology::TraceReport& r = trace.report;
  std::vector<std::pair<std::string, std::string>> facts{
      {"trace.file", trace.file.filename().string()},
      {"trace.signal", physiology::signal_name(trace.signal)},
      {"trace.column", trace.column},
      {"trace.samples", std::to_string(r.samples)},
      {"trace.invalid_samples", std::to_string(r.invalid_samples)},
      {"trace.gaps", std::to_string(r.gaps)},
      {"trace.longest_gap_s", fmt::format("{:.6g}", r.longest_gap_s)},
      {"trace.breaths", std::to_string(r.breaths)},
      {"trace.drift_mL_per_min", fmt::format("{:.6g}", r.drift_m3_per_s * 1e6 * 60.0)},
      {"trace.frc_reference_mL", fmt::format("{:.6g}", r.reference_m3 * 1e6)}};
  if (trace.signal == physiology::TraceSignal::amplitude)
    facts.emplace_back("trace.calibration_mL_per_unit", fmt::format("{:.6g}", r.scale_m3_per_unit * 1e6));
  if (r.calibration_span_s > 0.0) {
    facts.emplace_back("trace.calibration_r2", fmt::format("{:.6g}", r.calibration_r2));
    facts.emplace_back("trace.calibration_span_s", fmt::format("{:.6g}", r.calibration_span_s));
  }
  return facts;
}

OutputPlugin phases_output() {
  return {{kPhasesKey, false, read_spec}, {}, [](const std::any& settings, const std::filesystem::path& out) {
            return std::make_unique<Phases>(out, std::any_cast<PhasesSpec>(settings));
          }};
}

}  // namespace pneuma::outputs
