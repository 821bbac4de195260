#pragma once
// Regional stiffness (paper section 3; METHOD.md section 5): a shear modulus per mesh vertex,
// from a tissue YAML file (configs/tissue/*.yaml).
//
// Mesh coordinates. The tissue file names the mesh's up and anterior directions
// (`coordinates: {up: +z, anterior: -y}` by default: the DICOM LPS frame of the built-in
// phantom, x to the patient's left, y posterior, z up with the apex at the top). Gravity sets the axis of the gradient:
//   upright: from the top of the lung (apex, non-dependent) down to the base (dependent);
//   supine:  from the anterior surface (non-dependent) to the posterior one (dependent);
//   prone:   from posterior to anterior.
// `position` below runs from 0 at the most non-dependent vertex to 1 at the most dependent one.
//
// Models (key `stiffness.model`):
//   gradient    mu = nondependent .. dependent along the axis, `profile` linear or exponential
//               (geometric interpolation), optionally overridden by `bands` of position.
//   per_vertex  one value per vertex from a text file (`values`, `unit`).
//   regions     one label per vertex from a text file (`labels`), a modulus per label (`moduli`).
#include <Eigen/Core>
#include <filesystem>
#include <map>
#include <string>
#include <variant>
#include <vector>

#include "pneuma/engine/config.h"
#include "pneuma/mesh/triangle_mesh.h"

namespace pneuma::engine {

enum class Posture { upright, supine, prone };

struct StiffnessBand {
  double from = 0.0, to = 1.0;  // positions, 0 = non-dependent end, 1 = dependent end
  double shear_modulus_pa = 0.0;
};

struct GradientStiffness {
  enum class Profile { linear, exponential };
  Profile profile = Profile::linear;
  double nondependent_pa = 0.0;  // at position 0 (apex when upright)
  double dependent_pa = 0.0;     // at position 1 (base when upright)
  std::vector<StiffnessBand> bands;  // applied in order, later bands win
};

struct PerVertexStiffness {
  std::vector<double> shear_modulus_pa;  // read from the file
  std::string source;                    // the file, for messages
};

struct RegionStiffness {
  std::vector<std::string> labels;  // per vertex, read from the file
  std::map<std::string, double> shear_modulus_pa;
  std::string source;
};

struct Tissue {
  std::string name;
  Posture posture = Posture::upright;
  Eigen::Vector3d up{0, 0, 1};
  Eigen::Vector3d anterior{0, -1, 0};
  std::variant<GradientStiffness, PerVertexStiffness, RegionStiffness> stiffness;
};

// Reads a tissue file. Throws IoError / InputError ("<file>:<line>:<col>: <key>: <expected>").
Tissue load_tissue(const std::filesystem::path& path);
Tissue read_tissue(const config::Node& root);
// A shipped preset by name (configs/tissue/<name>.yaml) or a path.
std::filesystem::path tissue_file(const std::string& name_or_path, const std::filesystem::path& config_dir);

// The unit vector from the non-dependent to the dependent end for the tissue's posture.
Eigen::Vector3d dependent_direction(const Tissue& tissue);
// Per vertex: 0 at the most non-dependent vertex, 1 at the most dependent (all 0 if flat).
std::vector<double> dependent_position(const Tissue& tissue, const mesh::TriangleMesh& mesh);

// The shear modulus (Pa) of every vertex. Throws InputError when a per-vertex or label file
// does not hold one entry per vertex, or a label has no modulus.
std::vector<double> shear_modulus_per_vertex(const Tissue& tissue, const mesh::TriangleMesh& mesh);

}  // namespace pneuma::engine
