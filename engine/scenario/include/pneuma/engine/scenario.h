#pragma once
// A breathing scenario (scenarios/*.yaml): the lung mesh, its tissue and field, the physiology
// that drives it, the frames and the outputs. Every value carries its unit; unknown keys are
// errors. See README.md for the keys.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "pneuma/engine/field.h"
#include "pneuma/engine/physiology_config.h"
#include "pneuma/engine/sinks.h"
#include "pneuma/mesh/phantom.h"
#include "pneuma/render/png_sink.h"

namespace pneuma::engine {

struct MeshSpec {
  // The built-in phantom (`phantom: left|right`) or a file read with its unit.
  std::optional<mesh::Lung> phantom = mesh::Lung::right;  // nullopt when `file` or `labels` is set
  std::filesystem::path file;
  // A NIfTI label map (`labels: FILE, values: [3, 4, 5]`): the surface of the union of `values`.
  std::filesystem::path labels_file;
  std::vector<int> label_values;
  double metres_per_unit = 1e-3;        // `unit`; without it, the unit the file records, else mm
  bool unit_given = false;              // `unit` set: it wins over a unit recorded in the file
  double edge_m = 0.0;                  // phantom resolution / remeshing target (0: keep the file's mesh)
  bool repair = true;                   // repair what is safe before use
  bool export_original = false;         // export the file's mesh with the field transferred to it
  double share = 1.0;                   // share of the total volume change this mesh takes (0, 1]
  double reference_volume_m3 = 0.0;     // physiological volume above FRC that the rest mesh shows
};

// Where the field is cached: `auto` (<output>/field.h5), `off`, or a file (relative to the scenario).
enum class FieldCache { automatic, off, file };

struct FieldSpec {
  std::string tissue = "healthy-upright";  // preset name in configs/tissue or a path
  std::filesystem::path tissue_file;       // resolved
  FieldOptions options;                    // solver, tolerance, clique (checked together)
  FieldCache cache = FieldCache::automatic;
  std::filesystem::path cache_file;        // resolved, for FieldCache::file
};

struct OutputsSpec {
  bool physiology_csv = true;
  bool gltf = true;
  bool hdf5 = true;
  PositionPrecision hdf5_positions = PositionPrecision::float32;
  bool motion_csv = true;  // per breath and anatomical region (docs/realism.md)
  bool report = true;      // report.html: the lung, the plots and the motion table in one page
  std::optional<MeshSequenceSpec> mesh_sequence;
  std::optional<render::PngSinkOptions> png;  // frames in png/, rendered headless
};

struct Scenario {
  std::filesystem::path file;
  std::string name;
  std::string description;
  double duration_s = 0.0;
  double frame_rate_hz = 30.0;
  MeshSpec mesh;
  FieldSpec field;
  PhysiologyConfig physiology;
  OutputsSpec outputs;
};

// Reads and checks a scenario file; every problem is one line (file:line:col: key: what).
Scenario load_scenario(const std::filesystem::path& file,
                       const std::filesystem::path& config_dir = default_config_dir());
// The same from YAML already read (a scenario built in memory, e.g. from a Python dict):
// `file` stands for the file in messages and its folder anchors relative paths.
Scenario read_scenario(const config::Node& root, const std::filesystem::path& file,
                       const std::filesystem::path& config_dir = default_config_dir());

// The scenario's physiology, sampled at `output_rate_hz` (default: its own output rate). A
// protocol that cannot work becomes an InputError "<file>: physiology: <what>".
physiology::SimulationResult simulate_physiology(const Scenario& scenario,
                                                 std::optional<double> output_rate_hz = std::nullopt);

}  // namespace pneuma::engine
