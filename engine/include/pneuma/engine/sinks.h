#pragma once
// The shipped frame sinks. Each is registered by name in make_sink() (runner.cpp), the one
// place that knows them all.
#include <filesystem>
#include <memory>
#include <string>

#include "pneuma/engine/frame.h"
#include "pneuma/engine/scenario.h"

namespace pneuma::engine {

// glTF 2.0 binary (.glb): the rest mesh, the field as one morph target (u * s_ref with
// s_ref = max |s| of the run) and s(t) / s_ref as the animated morph weight, sampled at the
// frame times with LINEAR interpolation. Node rotated so pneuma's z-up becomes glTF's y-up.
std::unique_ptr<FrameSink> make_gltf_sink(const std::filesystem::path& file);

// HDF5 time series (rest mesh, field, per-frame time, scale, volumes, area and, optionally,
// positions) and an XDMF file beside it that ParaView opens as a temporal collection.
std::unique_ptr<FrameSink> make_hdf5_sink(const std::filesystem::path& h5_file, const std::filesystem::path& xdmf_file,
                                          bool store_positions);

// One mesh file per frame (every `spec.every`-th), frame_00000.<format>, in metres.
std::unique_ptr<FrameSink> make_mesh_sequence_sink(const std::filesystem::path& dir, const MeshSequenceSpec& spec,
                                                   std::size_t frame_count);

}  // namespace pneuma::engine
