#pragma once
// The compile stage (ARCHITECTURE.md): a scenario and its drive V(t) become the immutable model
// (surface, regions, field, volume -> scale map) and the scale of every frame, checked once.
// `pneuma run`, the Python module and the benchmarks call this one function, so they animate
// the same frames.
//
//   surface   the phantom, a file (read, repaired, remeshed) or a label map (extracted, remeshed)
//   field     field::compute_field with the scenario's tissue, through the HDF5 cache (field_cache.h)
//   model     make_model: normals, rest area, regions, the volume cubic
//   scales    s_k for every V_k of the drive: mesh volume = rest + share * (V_k - reference)
//   interior  where asked: each lung's inside as tetrahedra and its interior field (LungInterior)
//   check     the most deformed frames (lowest and highest s) must not self-intersect, and two
//             lungs must not intersect each other there
// Two lungs (scenario::MeshSpec::lungs) are compiled one after the other, each with its own
// surface, regions, field (its own cache file: lung_cache_path) and scales.
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "pneuma/model/model.h"
#include "pneuma/physiology/simulate.h"
#include "pneuma/scenario/scenario.h"

namespace pneuma::model {

struct CompileOptions {
  std::filesystem::path output_dir;                      // where `field: {cache: auto}` looks for field.h5
  std::optional<double> edge_override_m = std::nullopt;  // a coarser or finer mesh than the scenario's
  bool interior = false;                                 // compute each lung's inside (an output needs it)
  std::filesystem::path stage_dir = {};  // where `cache: auto` writes field.h5 (the run's stage); empty: output_dir
};

// The scales of one lung over the run.
struct LungScales {
  std::vector<double> scales;  // s_k for every sample k of the drive
  double min_scale = 0.0, max_scale = 0.0;
};

struct Compiled {
  Model model;
  std::vector<LungScales> lungs;                          // one per model lung, in its order
  bool field_reused = false;                              // every lung's field came from the cache
  std::vector<std::pair<std::string, double>> timings_s;  // each step, in order
};

// Compiles `scenario` for the volumes of `drive` (its physiology at the frame rate). A cache file
// found damaged is replaced and a warning printed to stderr. Throws pneuma::Error (one line):
// InputError / IoError for bad inputs, UnsupportedError when a frame's volume is out of the
// field's reach or the surface self-intersects at the run's lowest or highest scale.
Compiled compile(const scenario::Scenario& scenario, const physiology::SimulationResult& drive,
                 const CompileOptions& options);

// The scale of every frame for the lung volumes `lung_volume_m3` (physiology, above FRC; the
// lung's compartment's volume where it follows one): mesh volume = rest volume + share * (V -
// reference). Throws UnsupportedError naming the first frame whose volume the field cannot reach.
std::vector<double> frame_scales(const LungModel& lung, const std::vector<double>& time_s,
                                 const std::vector<double>& lung_volume_m3);

// The volumes `lung` follows in `drive`: the total, or its compartment's.
const std::vector<double>& lung_volumes(const LungModel& lung, const physiology::SimulationResult& drive);

// Where `lung`'s field is cached for a cache file `path` (field.h5): the file itself for a
// one-lung model, else field-right.h5 / field-left.h5 beside it (the stem + "-" + side).
std::filesystem::path lung_cache_path(const std::filesystem::path& path, const std::optional<mesh::Lung>& side,
                                      bool two_lungs);

}  // namespace pneuma::model
