#pragma once
// The compile stage (ARCHITECTURE.md): a scenario becomes the immutable model (surface, regions,
// field, volume -> scale map), with no breath, no folders and no printing. `pneuma run`, the
// Python module, the cohort and the benchmarks call this one function, so they animate the same
// frames; the breath is mapped onto the model afterwards (Model::scales, check_no_fold).
//
//   surfaces  mesh::SurfaceSource: the phantom, a file (read, repaired, remeshed) or a label map
//             (extracted, remeshed; read once)
//   field     field::compute_field with the scenario's tissue, through the HDF5 cache (field_cache.h)
//   model     make_model: normals, rest area, regions, the volume cubic
//   interior  where asked: each lung's inside as tetrahedra and its interior field (LungInterior),
//             and the body around the lungs
// Two lungs (scenario::MeshSpec::lungs) are compiled side by side (two TBB tasks: their largest
// steps, Mesh_3 on a label map and the tetrahedra, are sequential), each with its own surface,
// regions, field (its own cache file: lung_cache_path) and inside; the model, its messages and
// files are those of one lung after the other, at any thread count.
#include <filesystem>
#include <optional>

#include "pneuma/model/model.h"
#include "pneuma/scenario/scenario.h"

namespace pneuma::model {

struct CompileOptions {
  // `field: {cache: auto}`: the file the field is looked up in (a run's output folder's field.h5),
  // and the file a new one is written to (the run's stage, so that a failed run leaves the folder
  // as it was; empty: the same file). Empty `auto_cache_file`: not cached. `cache: <file>` names
  // its own file, read and written in place.
  std::filesystem::path auto_cache_file = {};
  std::filesystem::path auto_cache_write_file = {};
  std::optional<double> edge_override_m = std::nullopt;  // a coarser or finer mesh than the scenario's
  bool interior = false;  // compute each lung's inside and the body around them (an output needs it)
  // The breath the model will follow (runner::prepare's drive): places the scan on it
  // (`mesh.breath: end_inspiration` is each lung's peak volume) and tells how far below the scan
  // each lung deflates (field_for_deflation). Null (a cohort's field job): the scan at the volume
  // given, and a deflation down to FRC.
  const physiology::SimulationResult* drive = nullptr;
};

// With `cache: auto` and the lungs' inside, the body's field (body_motion_cached) is kept in this
// file beside auto_cache_file (written beside auto_cache_write_file).
inline constexpr const char* kBodyFieldCacheFile = "body-field.cache";

// Compiles `scenario`. A cache file found damaged is replaced (Model::report.warnings says so).
// Throws pneuma::Error (one line): InputError / IoError for bad inputs, UnsupportedError for a
// surface the field cannot take.
Model compile(const scenario::Scenario& scenario, const CompileOptions& options = {});

// Where `lung`'s field is cached for a cache file `path` (field.h5): the file itself for a
// one-lung model, else field-right.h5 / field-left.h5 beside it (the stem + "-" + side).
std::filesystem::path lung_cache_path(const std::filesystem::path& path, const std::optional<mesh::Lung>& side,
                                      bool two_lungs);

}  // namespace pneuma::model
