#pragma once
// The one interface every output implements (ARCHITECTURE.md: a new output is one plugin and one
// line in runner/src/output_registry.cpp), and what the run hands it.
//
// An output plugin owns, in one place: its key under `outputs:` in a scenario and how its options
// are read (scenario::OutputKey, at load time, so a bad option fails before any work), what it
// needs of the run, and the Output it makes for a run. The run calls begin() once, frame() for
// every frame in order, then finish() once with the whole run; finish() returns the files written
// (for the manifest). Files appear under their final names only when complete: an output that
// fails or is destroyed early leaves nothing partial behind.
#include <any>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <typeindex>
#include <utility>
#include <vector>

#include "pneuma/model/frame.h"
#include "pneuma/model/model.h"
#include "pneuma/outputs/breath_motion.h"
#include "pneuma/physiology/simulate.h"
#include "pneuma/scenario/scenario.h"

namespace pneuma::outputs {

// Facts about the whole run that outputs need before the first frame.
struct RunInfo {
  std::size_t frame_count = 0;
  double frame_rate_hz = 0.0;
  std::vector<double> min_scale;  // per model lung (model::Model::lungs), over all frames
  std::vector<double> max_scale;
  std::filesystem::path output_dir;
};

// What one output computes from the run that others may use too (such as the voxel setting, whose
// label map the voxel files and report.html's slices share): each kind made once, by the first
// output that asks, and kept for the rest of the run. Keyed by type: the run needs to know none.
class RunShared {
 public:
  template <class T, class Make>
  const T& get(Make make) const {
    std::shared_ptr<const void>& slot = items_[std::type_index(typeid(T))];
    if (!slot) slot = std::shared_ptr<const T>(make());
    return *static_cast<const T*>(slot.get());
  }
  // What an earlier output shared, or null (an output finished before another reads it: the
  // registry's order, runner/output_registry.cpp).
  template <class T>
  const T* find() const {
    const auto it = items_.find(std::type_index(typeid(T)));
    return it == items_.end() ? nullptr : static_cast<const T*>(it->second.get());
  }

 private:
  mutable std::map<std::type_index, std::shared_ptr<const void>> items_;
};

// The whole run, as finish() sees it. The runner fills every field; an output reads only what
// its plugin's OutputNeeds asked for (the rest may be null or empty).
struct RunRecord {
  const scenario::Scenario* scenario = nullptr;
  RunInfo info;
  const physiology::SimulationResult* drive = nullptr;       // at the frame rate: one sample per frame
  const physiology::SimulationResult* physiology = nullptr;  // at the scenario's output rate (needs.physiology)
  std::vector<std::span<const double>> scales;               // per model lung: s of every frame
  const std::vector<BreathMotion>* motion = nullptr;         // per breath and region (needs.breath_motion)
  bool field_reused = false;
  // The output folder, where what a previous run kept for the next one is looked up (the rest
  // lungs' mask: VoxelScene); RunInfo::output_dir is its stage. Empty: nothing is looked up.
  std::filesystem::path cache_dir;
  RunShared shared;  // what outputs compute once and share
};

class Output {
 public:
  virtual ~Output() = default;
  virtual std::string name() const = 0;
  virtual void begin(const model::Model& /*model*/, const RunInfo& /*run*/) {}
  virtual void frame(const model::Model& /*model*/, const model::Frame& /*frame*/) {}
  // Writes what needs the whole run and completes the files; returns them (absolute paths).
  virtual std::vector<std::filesystem::path> finish(const model::Model& model, const RunRecord& run) = 0;
  // Facts for the manifest ({"motion.apex.caudal_mean_mm", "1.2"}), after finish().
  virtual std::vector<std::pair<std::string, std::string>> facts() const { return {}; }
};

// What an output needs the run to compute for it (each computed once, for all that need it).
struct OutputNeeds {
  bool physiology = false;     // the physiology at the scenario's output rate (RunRecord::physiology)
  bool breath_motion = false;  // the motion of each region in each breath (RunRecord::motion)
  bool interior = false;       // each lung's inside (model::LungModel::interior; field.interior in the scenario)
};

struct OutputPlugin {
  scenario::OutputKey key;  // its key, default and options (read at load time)
  OutputNeeds needs;
  // The output for a run writing under `output_dir`, from the settings `key.read` returned.
  std::function<std::unique_ptr<Output>(const std::any& settings, const std::filesystem::path& output_dir)> make;
};

// For plugins whose options are `key: true|false` only: reads nothing, returns no settings.
inline std::any no_settings(const scenario::Node* /*options*/, const scenario::Scenario& /*run*/) { return {}; }

}  // namespace pneuma::outputs
