#pragma once
// A breathing scenario (scenarios/*.yaml): the lung mesh, its tissue and field, the physiology
// that drives it, the frames and the outputs. Every value carries its unit; unknown keys are
// errors. See README.md for the keys.
//
// The outputs are not known here: each output declares its own key under `outputs:` (OutputKey,
// listed by runner/output_registry.h), and the scenario keeps what each one read, unopened.
#include <any>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "pneuma/field/field.h"
#include "pneuma/field/interior.h"
#include "pneuma/field/tissue.h"
#include "pneuma/mesh/anatomy/lung.h"
#include "pneuma/mesh/volume/tetrahedralize.h"
#include "pneuma/scenario/config.h"
#include "pneuma/scenario/physiology_config.h"

namespace pneuma::scenario {

// One lung of a two-lung scenario (`phantom: both`, or `lungs: {right: ..., left: ...}`): where its
// surface comes from and how much of each breath it takes.
struct LungSpec {
  std::optional<mesh::Lung> side;  // nullopt only for a one-surface scenario's file or label map
  bool phantom = false;            // the built-in phantom of `side`
  std::filesystem::path file;      // `lungs.<side>.file`: a surface file (read with the mesh's unit)
  std::vector<int> label_values;   // `lungs.<side>: [3, 4, 5]` (or `.values`) of the mesh's label map
  // Segment names in that list (`[lung_upper_lobe_left, lung_lower_lobe_left]`): the compile stage
  // resolves them against the label map (image::resolve_labels) and adds their values.
  std::vector<std::string> label_names;
  double share = 1.0;  // share of each breath's volume change (of its compartment's, if set)
  // `lungs.<side>.compartment: NAME`: the lung follows this physiology compartment's volume
  // (two_compartment: upper | lower) instead of the total; index into the compartments; -1: total.
  int compartment = -1;
  std::string compartment_name;
};

struct MeshSpec {
  // The built-in phantom (`phantom: left|right`) or a file read with its unit.
  std::optional<mesh::Lung> phantom = mesh::Lung::right;  // nullopt when `file`, `labels` or two lungs are set
  std::filesystem::path file;
  // A NIfTI label map (`labels: FILE, values: [3, 4, 5]`): the surface of the union of `values`.
  std::filesystem::path labels_file;
  std::vector<int> label_values;
  std::vector<std::string> label_names;  // segment names given instead of numbers (see LungSpec)
  double metres_per_unit = 1e-3;         // `unit`; without it, the unit the file records, else mm
  bool unit_given = false;               // `unit` set: it wins over a unit recorded in the file
  double edge_m = 0.0;                   // phantom resolution / remeshing target (0: keep the file's mesh)
  bool repair = true;                    // repair what is safe before use
  bool export_original = false;          // export the file's mesh with the field transferred to it
  double share = 1.0;                    // share of the total volume change this mesh takes (0, 1]
  // Where the rest mesh (the scan) lies on the breath (`breath:`; `reference_volume:` is the same
  // key's older name): a volume above FRC (end_expiration: 0), or the peak of each lung's breath
  // (end_inspiration: a breath-hold scan), known once the physiology has run (model::compile).
  bool breath_at_end_inspiration = false;
  double reference_volume_m3 = 0.0;  // physiological volume above FRC that the rest mesh shows
  // Two lungs (`phantom: both` or `lungs:`), right then left; empty for one surface (the fields
  // above). With two lungs `share` is their sum and the label map, unit, edge and repair are shared.
  std::vector<LungSpec> lungs;
};

// The lungs of `mesh`: its two LungSpecs, or the one surface its fields describe (side, phantom,
// file, label values and share taken from them).
std::vector<LungSpec> lung_specs(const MeshSpec& mesh);
// The first label value of the right lung that the left lung has too (two lungs would overlap).
std::optional<int> label_in_both_lungs(const LungSpec& right, const LungSpec& left);

// "right", "left", or "lung" for a surface of no known side (file names, HDF5 groups, columns).
const char* lung_name(const std::optional<mesh::Lung>& side);

// Where the field is cached: `auto` (<output>/field.h5), `off`, or a file (relative to the scenario).
enum class FieldCache { automatic, off, file };

struct FieldSpec {
  std::string tissue_name = "healthy-upright";  // preset name in configs/tissue or a path
  std::filesystem::path tissue_file;            // resolved
  field::Tissue tissue;                         // the file, read when the scenario is loaded
  field::FieldOptions options;                  // solver, tolerance, clique (checked together)
  FieldCache cache = FieldCache::automatic;
  std::filesystem::path cache_file;  // resolved, for FieldCache::file
  // The lung's inside (`field.interior`), computed only when an output needs it (voxel outputs):
  // a tetrahedral mesh of `edge` and the interior field of `model` (field/interior.h).
  double interior_edge_m = 4e-3;
  mesh::TetMesher interior_mesher = mesh::TetMesher::delaunay;  // `mesher`: delaunay | lattice
  field::InteriorOptions interior;
};

// One key under `outputs:`, declared by the output that owns it (runner/output_registry.h).
struct Scenario;

struct OutputKey {
  std::string key;
  bool on_by_default = true;
  // Reads the output's options from `options`, its mapping (`key: {...}`), or from nothing
  // (`key: true`, or on by default), and returns its settings; only the output opens them
  // (std::any_cast). Every bad value is a one-line InputError from `options`. `run` is the
  // scenario read so far (all but its outputs: duration, frames, mesh, physiology), for options
  // that only make sense within the run (a time point after its end).
  std::function<std::any(const scenario::Node* options, const Scenario& run)> read;
};

// An output the scenario asks for, with the settings its OutputKey read.
struct OutputRequest {
  std::string key;
  std::any settings;
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
  std::vector<OutputRequest> outputs;  // the outputs on, in the order of the keys they were read with

  // The request for output `key`, or null when it is off.
  const OutputRequest* output(std::string_view key) const;
};

// Reads and checks a scenario file, its tissue and physiology presets included, with `outputs`
// the keys allowed under `outputs:`; every problem is one line (file:line:col: key: what).
Scenario load_scenario(const std::filesystem::path& file, std::span<const OutputKey> outputs,
                       const std::filesystem::path& config_dir = default_config_dir());
// The same from YAML already read (a scenario built in memory, e.g. from a Python dict):
// `file` stands for the file in messages and its folder anchors relative paths.
Scenario read_scenario(const scenario::Node& root, const std::filesystem::path& file,
                       std::span<const OutputKey> outputs,
                       const std::filesystem::path& config_dir = default_config_dir());

// The scenario's physiology, sampled at `output_rate_hz` (default: its own output rate). A
// protocol that cannot work becomes an InputError "<file>: physiology: <what>".
physiology::SimulationResult simulate_physiology(const Scenario& scenario,
                                                 std::optional<double> output_rate_hz = std::nullopt);

}  // namespace pneuma::scenario
