#pragma once
// A breathing scenario (scenarios/*.yaml): the lung mesh, its tissue and field, the physiology
// that drives it, the frames and the outputs. Every value carries its unit; unknown keys are
// errors. See README.md for the keys.
#include <filesystem>
#include <optional>
#include <string>

#include "pneuma/engine/physiology_config.h"

namespace pneuma::engine {

struct MeshSpec {
  // The built-in phantom (`phantom: left|right`) or a file read with its unit.
  std::string phantom_lung = "right";  // empty when `file` is set
  std::filesystem::path file;
  double metres_per_unit = 1e-3;
  double edge_m = 0.0;                  // phantom resolution / remeshing target (0: keep the file's mesh)
  bool repair = true;                   // repair what is safe before use
  bool export_original = false;         // export the file's mesh with the field transferred to it
  double share = 1.0;                   // share of the total volume change this mesh takes
  double reference_volume_m3 = 0.0;     // physiological volume above FRC that the rest mesh shows
};

struct FieldSpec {
  std::string tissue = "healthy-upright";  // preset name in configs/tissue or a path
  std::filesystem::path tissue_file;       // resolved
  std::string solver;                      // empty: the default solver
  double tolerance = 1e-6;
  int clique_hops = 1;
  std::string cache = "auto";              // auto: <output>/field.h5; off; or a path
};

struct MeshSequenceSpec {
  std::string format = "ply";  // ply | obj | stl
  bool ascii = false;
  std::size_t every = 1;       // every n-th frame
};

struct PngSpec {
  int width = 640;
  int height = 480;
  std::string camera = "anterior";
  std::size_t every = 1;
  bool overlay = false;  // displacement magnitude colour map with a legend
};

struct OutputsSpec {
  bool physiology_csv = true;
  bool gltf = true;
  bool hdf5 = true;
  bool hdf5_positions = false;
  std::optional<MeshSequenceSpec> mesh_sequence;
  std::optional<PngSpec> png;
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

}  // namespace pneuma::engine
