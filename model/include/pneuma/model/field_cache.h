#pragma once
// The field cache: the rest mesh, the field and its metadata in one HDF5 file, keyed by a hash
// of everything that determines the field (mesh, per-vertex shear modulus, tissue name,
// solver options, pneuma version). Written atomically; same inputs give the same bytes.
//
// Layout (format "pneuma-field", version 3; the same names as series.h5, docs/formats.md):
//   /            attributes: format, format_version, generator ("pneuma <version>"),
//                coordinate_frame ("LPS"), length_unit ("m"), pneuma_version, key, checksum,
//                tissue, solver, tolerance, clique_hops, path_rule, shots, iterations, residual
//   /rest/positions            V x 3 float64 (m)
//   /rest/triangles            T x 3 uint32
//   /field                     attribute area_unit_m2
//   /field/unit_displacement   V x 3 float64 (m per unit scale: one area unit of area increase)
//   /field/force               V float64 (F for a unit load)
//   /field/shear_modulus_pa    V float64 (Pa)
//   /interior                  (where a run needed the lung's inside; model.h, LungInterior)
//                              attributes key, model, edge_m, poisson_ratio, tolerance, iterations,
//                              residual
//   /interior/nodes            N x 3 float64 (m)
//   /interior/tets             T x 4 uint32 (positively oriented)
//   /interior/boundary_nodes   B uint32
//   /interior/unit_displacement N x 3 float64 (m per unit scale)
// Every dataset has a `units` attribute; nothing is compressed (the file is small).
// `checksum` covers every dataset and attribute, so an edited file is refused.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "pneuma/field/field.h"
#include "pneuma/field/interior.h"
#include "pneuma/field/tissue.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"
#include "pneuma/model/model.h"

namespace pneuma::model {

struct FieldMetadata {
  std::string key;             // field_key() of the inputs
  std::string pneuma_version;  // that wrote the file
  std::string tissue;
  std::string solver;
  double tolerance = 0.0;
  int clique_hops = 1;
  std::string path_rule;
  double area_unit_m2 = 0.0;
  std::uint64_t shots = 0, iterations = 0;
  double residual = 0.0;
};

// What the cache file holds: the rest mesh, the field and its metadata (a cache record, not the
// model: compile() makes the model from it), and the inside where a run needed it.
struct FieldRecord {
  mesh::TriangleMesh rest;
  std::vector<Eigen::Vector3d> unit_displacement;  // per vertex, for one area unit
  std::vector<double> force;
  std::vector<double> shear_modulus_pa;
  FieldMetadata metadata;
  std::shared_ptr<const LungInterior> interior;  // with its key (LungInterior::key); may be null
};

// The key of the inside of a field's surface (`field_key`: the record's key) for `edge_m`,
// `options` and `mesher` (delaunay adds nothing: the keys of files written before the lattice).
std::string interior_key(const std::string& field_key, double edge_m, const field::InteriorOptions& options,
                         mesh::TetMesher mesher = mesh::TetMesher::delaunay);

// A 128-bit hex digest of the inputs that determine the field.
std::string field_key(const mesh::TriangleMesh& rest, std::span<const double> shear_modulus_pa,
                      const std::string& tissue_name, const field::FieldOptions& options);
std::string field_key(const mesh::TriangleMesh& rest, const field::TissueFieldInputs& inputs);

// The record of `field`, computed on `rest` for `inputs` (its metadata from both).
FieldRecord field_record(const mesh::TriangleMesh& rest, const field::TissueFieldInputs& inputs,
                         const field::ElastostaticField& field);

// The field of `rest` for `inputs`, computed (field::compute_field) and made a record.
FieldRecord compute_field_record(const mesh::TriangleMesh& rest, const field::TissueFieldInputs& inputs);
// The same for `tissue` applied to `rest` with `options` (field::tissue_field_inputs).
FieldRecord compute_field_record(const mesh::TriangleMesh& rest, const field::Tissue& tissue,
                                 const field::FieldOptions& options = field::default_field_options);

// Writes the file atomically. Throws IoError when it cannot be written.
void save_field(const std::filesystem::path& path, const FieldRecord& record);

// Reads a file. Throws IoError when it does not exist or cannot be read, and InputError
// "<file>: not a pneuma field file: <why>" when it is not HDF5, not ours, truncated, of
// another format version, or edited (checksum mismatch).
FieldRecord load_field(const std::filesystem::path& path);

struct CacheLookup {
  FieldRecord record;
  bool reused = false;    // true: read from the cache; false: computed (and written)
  std::string discarded;  // why a file found at the cache path was not usable (else empty)
  // The regions of record.rest in the tissue's body axes, where they were found on the way (null
  // where the tissue did not need them, or the record came from a cache keyed by its source).
  std::shared_ptr<const mesh::SurfaceRegions> regions;
};

// Reuses `path` when it holds a field whose key is `key`; otherwise runs `compute`, stores `key`
// in the record it returns and writes it to `path`. A damaged or foreign file there (truncated,
// edited, not a pneuma field file) is never used: it is recomputed and replaced, and `discarded`
// holds the one-line reason for a warning. Throws IoError when the file exists but cannot be read.
// With `save_to` (a run's stage), the field is written there instead, and a reused file copied
// there: `path` itself is left as it was.
CacheLookup load_or_compute(const std::filesystem::path& path, const std::string& key,
                            const std::function<FieldRecord()>& compute, const std::filesystem::path& save_to = {});

// load_or_compute() for a surface at hand: keyed by field_key() of `tissue` applied to `rest`
// (its regions found once, and handed back in `regions` where the tissue needed them).
CacheLookup load_or_compute(const std::filesystem::path& path, const mesh::TriangleMesh& rest,
                            const field::Tissue& tissue,
                            const field::FieldOptions& options = field::default_field_options,
                            const std::filesystem::path& save_to = {});

// A digest of the bytes of `files` and of `options_text` (whatever else shapes a surface made
// from them: unit, repair, remeshing target). Throws IoError when a file cannot be read.
std::string source_key(const std::vector<std::filesystem::path>& files, const std::string& options_text);

// The key of a field whose surface is expensive to make (a file read, repaired and remeshed):
// from source_key() of its inputs (the tissue file among them), the tissue and the options, so
// the cache is looked up before the surface is made, and a hit pays for neither the repair nor
// the remeshing.
std::string source_field_key(const std::string& source, const std::string& tissue_name,
                             const field::FieldOptions& options);

}  // namespace pneuma::model
