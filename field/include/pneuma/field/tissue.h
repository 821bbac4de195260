#pragma once
// Regional stiffness (paper section 3; METHOD.md section 5): a shear modulus per mesh vertex,
// as a tissue file (configs/tissue/*.yaml, read by scenario/tissue_config.h) describes it.
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
//   regions     one label per vertex from a text file (`labels`), a modulus per label (`moduli`);
//               without `labels`, the anatomical regions found on the surface (mesh/regions.h:
//               apex, costal, diaphragmatic, mediastinal, each needs a modulus), blended across
//               borders geometrically with the region weights: mu_i = prod_r mu_r^w_ir.
//               Optional `gravity: {nondependent: a, dependent: b}` multiplies mu by a factor
//               running linearly from a to b along the posture's axis (see `position` below).
//
// `displacement: {direction: vertex_normal | smoothed_normal | anatomical, smoothing: 20 mm,
// magnitude_smoothing: 3 mm}` (optional, default vertex_normal, no magnitude smoothing) chooses
// the field's displacement direction and how much its magnitude is blurred in space (field.h).
// `sliding: {caudal, anterior, mediastinal, exponent, base, blur}` (optional): the tangential slide along the chest
// wall (mesh/sliding.h).
#include <Eigen/Core>
#include <array>
#include <map>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "pneuma/field/field.h"
#include "pneuma/mesh/anatomy/regions.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::field {

enum class Posture { upright, supine, prone };

struct StiffnessBand {
  double from = 0.0, to = 1.0;  // positions, 0 = non-dependent end, 1 = dependent end
  double shear_modulus_pa = 0.0;
};

struct GradientStiffness {
  enum class Profile { linear, exponential };
  Profile profile = Profile::linear;
  double nondependent_pa = 0.0;      // at position 0 (apex when upright)
  double dependent_pa = 0.0;         // at position 1 (base when upright)
  std::vector<StiffnessBand> bands;  // applied in order, later bands win
};

struct PerVertexStiffness {
  std::vector<double> shear_modulus_pa;  // read from the file
  std::string source;                    // the file, for messages
};

struct RegionStiffness {
  std::vector<std::string> labels;  // per vertex, read from the file; empty: anatomical regions
  std::map<std::string, double> shear_modulus_pa;
  std::string source;
  bool anatomical = false;                                     // the regions are found on the surface
  double gravity_nondependent = 1.0, gravity_dependent = 1.0;  // factors on mu along the posture's axis
  double gravity_depth_m = 0.0;  // > 0: the factors of a lung this deep, the gradient per metre (gravity_factor)
};

struct Tissue {
  std::string name;
  Posture posture = Posture::upright;
  Eigen::Vector3d up{0, 0, 1};
  Eigen::Vector3d anterior{0, -1, 0};
  std::variant<GradientStiffness, PerVertexStiffness, RegionStiffness> stiffness;
  DirectionKind direction = DirectionKind::vertex_normal;
  double direction_smoothing_m = 0.02;
  double magnitude_smoothing_m = 0.0;  // 0: none (field.h, FieldOptions::magnitude_smoothing)
  // `load: {apex: a, costal: c, diaphragmatic: d, mediastinal: m}` (optional): the pressure drive
  // per anatomical region, relative (mesh::regional_load); none: the same load everywhere.
  // Optional `gravity: {nondependent: a, dependent: b}` inside `load`: the load times a factor
  // running linearly from a to b along the posture's axis (dependent regions ventilate more).
  // With `depth: D` the factors are those of a lung D deep: the gradient is (b - a) / D per metre
  // whatever the lung's depth (the pleural pressure's gradient per cm of height is the same in a
  // small lung as in a large one), about the lung's middle, where the factor is (a + b) / 2.
  std::optional<std::array<double, mesh::kRegionCount>> regional_load;
  double load_nondependent = 1.0, load_dependent = 1.0;
  double load_gravity_depth_m = 0.0;  // D above; 0: a and b at the lung's own ends, whatever its depth
  // Optional `dome: {radius: 60 mm, falloff: 20 mm, rim: 0.3}` inside `load`: the diaphragm's load
  // concentrated at its dome, its total kept (mesh::DomeLoad); none: no concentration.
  mesh::DomeLoad dome_load;
  // `sliding: {caudal: 1.2, anterior: 0.5, mediastinal: 0, exponent: 0.5, base: 0, blur: 15 mm}` (optional): the lung
  // slides along the chest wall (mesh/sliding.h, docs/realism.md 7.), in units of its diaphragm's mean descent; none:
  // no slide. Independent of the load: it scales with whatever descent the load gives.
  mesh::Sliding sliding;
  // `heart: {descent: 0.6, top: 0.5}` (optional): the lung's face on the heart descends with it
  // (field/heart.h, docs/voxels.md), in units of the diaphragm's mean descent; none: it stands still.
  HeartDescent heart;
};

// The body frame of the tissue's coordinates (up, anterior).
mesh::BodyAxes body_axes(const Tissue& tissue);
// `options` with the tissue's displacement direction, smoothing, body frame and, when the tissue
// has a regional load, the load per vertex of `mesh`; and with the regions of `mesh` (found once,
// here) when the tissue's load, moduli or direction need them.
FieldOptions with_tissue(FieldOptions options, const Tissue& tissue, const mesh::TriangleMesh& mesh);

// The unit vector from the non-dependent to the dependent end for the tissue's posture.
Eigen::Vector3d dependent_direction(const Tissue& tissue);
// Per vertex: 0 at the most non-dependent vertex, 1 at the most dependent (all 0 if flat).
std::vector<double> dependent_position(const Tissue& tissue, const mesh::TriangleMesh& mesh);
// Per vertex: a gravity factor running from `nondependent` (a) to `dependent` (b) along the
// posture's axis. depth_m <= 0: a and b at the lung's own ends, whatever its depth. depth_m > 0:
// the factors of a lung that deep, i.e. the gradient (b - a) / depth_m per metre about (a + b) / 2
// at the lung's middle, never below 0: the pleural pressure changes by about 0.25 cmH2O per cm of
// height in any lung (West; Agostoni 1972), so a shallower lung spans a smaller range.
std::vector<double> gravity_factor(const Tissue& tissue, const mesh::TriangleMesh& mesh, double nondependent,
                                   double dependent, double depth_m);
// The factor `load: {gravity: ...}` puts on the load (1 without it).
std::vector<double> load_gravity_factor(const Tissue& tissue, const mesh::TriangleMesh& mesh);

// The shear modulus (Pa) of every vertex. Throws InputError when a per-vertex or label file
// does not hold one entry per vertex, or a label has no modulus.
// `regions`: the surface's regions when already found (with_tissue's), else found here if needed.
// Throws InputError when a `gravity` with `depth` leaves no positive modulus on a lung this deep.
std::vector<double> shear_modulus_per_vertex(const Tissue& tissue, const mesh::TriangleMesh& mesh,
                                             const mesh::SurfaceRegions* regions = nullptr);

// Everything the field of `mesh` depends on beyond the mesh: the options with the tissue applied
// (with_tissue: directions, smoothing, body axes, load per vertex, the regions where needed) and
// the shear modulus of every vertex. What compute_field() takes, and what a cache key hashes.
struct TissueFieldInputs {
  std::string tissue_name;
  FieldOptions options;
  std::vector<double> shear_modulus_pa;
};
TissueFieldInputs tissue_field_inputs(const mesh::TriangleMesh& mesh, const Tissue& tissue,
                                      const FieldOptions& given = default_field_options);
// The field of `mesh` for these inputs (compute_field()).
ElastostaticField compute_field(const mesh::TriangleMesh& mesh, const TissueFieldInputs& inputs);

}  // namespace pneuma::field
