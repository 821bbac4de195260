#pragma once
// The per-frame outputs that need no OpenGL (the PNG frames are render's): breathing.glb,
// series.h5 + series.xdmf, and mesh sequences. Each has its plugin (key, options, factory) and a
// direct factory for callers that run outputs themselves (tests, benchmarks).
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "pneuma/outputs/output.h"

namespace pneuma::outputs {

// ---- breathing.glb (`outputs: {gltf: true}`) ------------------------------------------------------
// glTF 2.0 binary: the rest mesh, the field as one morph target (u * s_ref with s_ref = max |s| of
// the run) and s(t) / s_ref as the animated morph weight, sampled at the frame times with LINEAR
// interpolation. The node is rotated so pneuma's z-up becomes glTF's y-up. Two lungs: two meshes
// and nodes ("right lung", "left lung"), each its own morph target and weight track (its own s
// and s_ref), animated together by one animation.
OutputPlugin gltf_output();
std::unique_ptr<Output> make_gltf_output(const std::filesystem::path& file);

// The bytes that output writes for a run whose frames are at `time_s` with scales `scales` (one
// span per lung; the report embeds them, also when no breathing.glb is written). Throws
// ValueError when the sizes differ.
std::string make_glb(const model::Model& model, const RunInfo& run, std::span<const double> time_s,
                     const std::vector<std::span<const double>>& scales);

// ---- series.h5 + series.xdmf (`outputs: {hdf5: {positions: float32, compression: none}}`) ---------
// The stored type of series.h5's per-frame positions (the exact rest + s u is always there in
// float64: /rest/positions, /field/unit_displacement, /frames/scale).
enum class PositionPrecision { float32, float64 };
// The per-frame positions' filter: none (contiguous, the default: about 12x less CPU than gzip
// for 1.2x the bytes, BENCHMARKS.md) or gzip (shuffle + deflate level 1, one chunk per frame).
enum class PositionCompression { none, gzip };

// HDF5 time series (rest mesh, field, per-frame time, scale, volumes, area and positions) and
// an XDMF file beside it that ParaView and meshio open as a temporal collection
// (docs/formats.md).
OutputPlugin hdf5_output();
std::unique_ptr<Output> make_hdf5_output(const std::filesystem::path& h5_file, const std::filesystem::path& xdmf_file,
                                         PositionPrecision positions = PositionPrecision::float32,
                                         PositionCompression compression = PositionCompression::none);

// ---- frames/frame_NNNNN.<format> (`outputs: {mesh_sequence: {format: ply, ascii: false, every: 1, unit: mm}}`)
struct MeshSequenceSpec {
  std::string format = "ply";  // ply | obj | stl
  bool ascii = false;
  std::size_t every = 1;          // every n-th frame
  double metres_per_unit = 1e-3;  // mm (`unit: m` for metres), as the CT and planning tools beside them
};

// The `unit` option of the mesh files pneuma writes for medical tools (`mm`, the default, or `m`),
// in metres per unit.
double read_mesh_file_unit(const scenario::Node& options);

// One mesh file per frame (every `spec.every`-th), frame_00000.<format>, in `spec`'s unit (LPS); two lungs:
// right_00000.<format> and left_00000.<format>. Off by default.
OutputPlugin mesh_sequence_output();
std::unique_ptr<Output> make_mesh_sequence_output(const std::filesystem::path& dir, const MeshSequenceSpec& spec);

}  // namespace pneuma::outputs
