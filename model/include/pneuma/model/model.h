#pragma once
// The model: everything a run computes once and never changes while it runs (cf. MuJoCo's
// mjModel). compile() (compile.h) makes it from a scenario; model::advance() reads it by const&.
// A model holds one lung (a phantom, a file or a label map) or two (right, then left), each its
// own surface, regions, field, volume cubic and share of every breath.
#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "pneuma/field/interior.h"
#include "pneuma/image/label_map.h"
#include "pneuma/mesh/geometry/tet_mesh.h"
#include "pneuma/mesh/volume/tetrahedralize.h"
#include "pneuma/model/body_motion.h"

#include "pneuma/mesh/anatomy/lung.h"
#include "pneuma/mesh/anatomy/regions.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"
#include "pneuma/model/volume_scale.h"
#include "pneuma/physiology/simulate.h"

namespace pneuma::model {

// Most lungs in a model: the right and the left.
inline constexpr std::size_t kMaxLungs = 2;

// A lung's inside (field/interior.h), where an output needs it: tetrahedra filling the rest
// surface and their unit displacement, so the inside at scale s is nodes + s * unit_displacement,
// like the surface. Boundary nodes take the surface field (carried to them barycentrically).
struct LungInterior {
  mesh::TetMesh mesh;                              // metres, LPS
  std::vector<std::uint32_t> boundary_nodes;       // ascending
  std::vector<Eigen::Vector3d> unit_displacement;  // per node, metres per unit of s
  double edge_m = 0.0;                             // the tetrahedra's target size
  mesh::TetMesher mesher = mesh::TetMesher::delaunay;
  field::InteriorOptions options;
  field::InteriorReport report;
  std::string key;  // what it was made from (field_cache.h: interior_key), for the cache
};

// One lung of the model: what one breathing surface needs.
struct LungModel {
  // ---- The surface at rest (metres, LPS) ------------------------------------------------------
  mesh::TriangleMesh rest;               // the exported surface
  std::vector<Eigen::Vector3d> normals;  // area-weighted unit normals of `rest`, one per vertex
  double rest_area_m2 = 0.0;
  mesh::SurfaceRegions regions;  // apex, costal, diaphragmatic, mediastinal (docs/realism.md)

  // ---- The field: a frame is rest + s * unit_displacement ----------------------------------------
  std::vector<Eigen::Vector3d> unit_displacement;  // u: metres per area unit of s, one per vertex
  double area_unit_m2 = 1e-4;                      // s counts these: A(s) - A(0) ~ s * area_unit

  // ---- Volume to scale --------------------------------------------------------------------------
  VolumeScaleMap volume_map;  // V(s) of rest + s u, an exact cubic

  // ---- Which lung, and its part of each breath (set by compile(); scenario::LungSpec) -------------
  std::optional<mesh::Lung> side;    // nullopt: a one-surface run of a file or label map
  double share = 1.0;                // mesh volume = rest + share * (V - reference)
  double reference_volume_m3 = 0.0;  // the volume above FRC the scan shows (mesh.breath, resolved)
  // The field's smoothing in space for a breath below the scan (field_for_deflation; 0: none).
  double deflation_sigma_m = 0.0;
  int compartment = -1;                // V is this physiology compartment's volume; -1: the total
  std::vector<int> label_values = {};  // the label map's values of this lung (names resolved); empty: no label map
  // The label map's faces this lung's labels reach ("inferior face (k = 0)"): cut flat by the scan there.
  std::vector<std::string> label_map_edges = {};

  // ---- The inside (compile with CompileOptions::interior; else null) -------------------------------
  std::shared_ptr<const LungInterior> interior = nullptr;

  // ---- Volume to scale ----------------------------------------------------------------------------
  // The volumes this lung follows in `drive`: the total, or its compartment's.
  const std::vector<double>& volumes(const physiology::SimulationResult& drive) const;
  // The scale of every sample of the lung volumes `lung_volume_m3` (physiology, above FRC): mesh
  // volume = rest volume + share * (V - reference). Throws UnsupportedError naming the first sample
  // whose volume the field cannot reach ("frame k (t = ... s): ...").
  std::vector<double> scales(const std::vector<double>& time_s, const std::vector<double>& lung_volume_m3) const;
};

// The scales of one lung over a run.
struct LungScales {
  std::vector<double> scales;  // s_k for every sample k of the drive
  double min_scale = 0.0, max_scale = 0.0;
};

// What compile() did: for the manifest and the user.
struct CompileReport {
  bool field_reused = false;                              // every lung's field came from the cache
  std::vector<std::pair<std::string, double>> timings_s;  // each step, in order
  std::vector<std::string> warnings;                      // e.g. a damaged cache file replaced
};

struct Model {
  std::vector<LungModel> lungs;  // one, or two: right then left
  // How the body outside the lungs moves (body_motion.h); with the interiors, else null.
  std::shared_ptr<const BodyMotion> body = nullptr;
  // The label map the lungs came from, read once by compile(); with the interiors, else null.
  std::shared_ptr<const image::LabelMap> label_map = nullptr;
  std::filesystem::path scenario_file;  // what the model was compiled from, for messages
  CompileReport report;

  Model() = default;
  explicit Model(LungModel lung) { lungs.push_back(std::move(lung)); }
  explicit Model(std::vector<LungModel> both) : lungs(std::move(both)) {}

  std::size_t lung_count() const { return lungs.size(); }
  bool two_lungs() const { return lungs.size() == 2; }
  std::size_t vertex_count() const;    // over the lungs
  std::size_t triangle_count() const;  // over the lungs

  // Every lung's scale at every sample of `drive` (its physiology at the frame rate). Throws
  // UnsupportedError as LungModel::scales (two lungs: "the <side> lung: ...").
  std::vector<LungScales> scales(const physiology::SimulationResult& drive) const;
};

// The one CGAL check of the most deformed frames: a self-intersecting surface is refused, and so
// are two lungs that cut into each other (both at their lowest scales, then both at their highest:
// end-expiration and end-inspiration). Throws UnsupportedError naming the scenario file.
void check_no_fold(const Model& model, std::span<const LungScales> scales);

// The volumes a lung following `compartment` (-1: the total) reads in `drive`. Throws ValueError
// for a compartment the drive lacks.
const std::vector<double>& lung_volumes(const physiology::SimulationResult& drive, int compartment);

// The surface field for a lung that deflates `depth_m3` below its rest shape (a scan above FRC):
// `u` itself where rest + s u at 1.5 times that depth neither self-intersects nor stretches two
// surface points apart by more than their distance (s u a contraction: field::is_contraction) and
// where at the depth itself |s (u_i - u_j)| < |x_i - x_j| / 2, so that the pull-back moves no two
// points apart by more than their distance; else u smoothed in space
// (field::smooth_field_in_space) at the first of 2, 4, 6, 8, 12, 16 mm whose deflation passes all
// three (the largest when none does: `passes` is then false; a surface that crosses itself at the
// run's own scales fails check_no_fold, a stretch is the run's warning).
// docs/voxels.md, "The scan's place on the breath".
struct DeflationField {
  std::vector<Eigen::Vector3d> unit_displacement;
  double sigma_m = 0.0;
  bool passes = true;  // the kept field deflates cleanly (1.5 times the depth, and the depth by half)
};
DeflationField field_for_deflation(const mesh::TriangleMesh& rest, const std::vector<Eigen::Vector3d>& u,
                                   double depth_m3);

// The model of `rest` moved by `unit_displacement`: normals, the volume cubic, the rest area and
// the anatomical regions (in the body `axes`, of the lung `side` where given) are computed here,
// once; `regions`, when given, are rest's regions already found in `axes` (the field's), and are
// used instead where they are of `side`.
// Throws ValueError when `regions` are not of `rest` in `axes` (mesh::require_regions_of).
LungModel make_model(mesh::TriangleMesh rest, std::vector<Eigen::Vector3d> unit_displacement, double area_unit_m2,
                     const mesh::BodyAxes& axes = {}, const mesh::SurfaceRegions* regions = nullptr,
                     std::optional<mesh::Lung> side = std::nullopt);

// The inside of the surface `rest` as tetrahedra of about `edge_m` by `mesher` (mesh::tetrahedralize) and its
// interior field for `options`, with `unit_displacement` (per vertex of `rest`) on the boundary.
// Throws ValueError when the surface bounds no volume.
std::shared_ptr<LungInterior> compute_interior(const mesh::TriangleMesh& rest,
                                               const std::vector<Eigen::Vector3d>& unit_displacement, double edge_m,
                                               const field::InteriorOptions& options,
                                               mesh::TetMesher mesher = mesh::TetMesher::delaunay);

}  // namespace pneuma::model
