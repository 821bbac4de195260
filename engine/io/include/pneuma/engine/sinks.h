#pragma once
// The frame sinks engine/io writes (the PNG sink is render's). The runner's sink registry
// (engine/runner/src/sink_registry.cpp) is the one place that knows them all.
#include <filesystem>
#include <memory>
#include <span>
#include <string>

#include "pneuma/engine/frame.h"

namespace pneuma::engine {

struct MeshSequenceSpec {
  std::string format = "ply";  // ply | obj | stl
  bool ascii = false;
  std::size_t every = 1;       // every n-th frame
};

// glTF 2.0 binary (.glb): the rest mesh, the field as one morph target (u * s_ref with
// s_ref = max |s| of the run) and s(t) / s_ref as the animated morph weight, sampled at the
// frame times with LINEAR interpolation. Node rotated so pneuma's z-up becomes glTF's y-up.
std::unique_ptr<FrameSink> make_gltf_sink(const std::filesystem::path& file);

// The bytes that sink writes for a run whose frames are at `time_s` with scales `scale` (the
// report embeds them, also when no breathing.glb is written). Throws ValueError when the sizes
// differ.
std::string make_glb(const BreathingModel& model, const RunInfo& run, std::span<const double> time_s,
                     std::span<const double> scale);

// The stored type of series.h5's per-frame positions (the exact rest + s u is always there in
// float64: /rest/positions, /field/unit_displacement, /frames/scale).
enum class PositionPrecision { float32, float64 };

// HDF5 time series (rest mesh, field, per-frame time, scale, volumes, area and positions) and
// an XDMF file beside it that ParaView and meshio open as a temporal collection
// (docs/formats.md).
std::unique_ptr<FrameSink> make_hdf5_sink(const std::filesystem::path& h5_file, const std::filesystem::path& xdmf_file,
                                          PositionPrecision positions = PositionPrecision::float32);

// One mesh file per frame (every `spec.every`-th), frame_00000.<format>, in metres.
std::unique_ptr<FrameSink> make_mesh_sequence_sink(const std::filesystem::path& dir, const MeshSequenceSpec& spec);

}  // namespace pneuma::engine
