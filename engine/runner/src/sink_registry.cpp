#include "pneuma/engine/sink_registry.h"

#include "pneuma/engine/sinks.h"
#include "pneuma/render/png_sink.h"

namespace pneuma::engine {

const std::vector<SinkEntry>& sink_registry() {
  static const std::vector<SinkEntry> registry{
      {"gltf",
       [](const Scenario& s, const std::filesystem::path& out) -> std::unique_ptr<FrameSink> {
         return s.outputs.gltf ? make_gltf_sink(out / "breathing.glb") : nullptr;
       }},
      {"hdf5",
       [](const Scenario& s, const std::filesystem::path& out) -> std::unique_ptr<FrameSink> {
         return s.outputs.hdf5 ? make_hdf5_sink(out / "series.h5", out / "series.xdmf", s.outputs.hdf5_positions)
                               : nullptr;
       }},
      {"mesh_sequence",
       [](const Scenario& s, const std::filesystem::path& out) -> std::unique_ptr<FrameSink> {
         return s.outputs.mesh_sequence ? make_mesh_sequence_sink(out / "frames", *s.outputs.mesh_sequence) : nullptr;
       }},
      {"png",
       [](const Scenario& s, const std::filesystem::path& out) -> std::unique_ptr<FrameSink> {
         return s.outputs.png ? std::make_unique<render::PngFrameSink>(out / "png", *s.outputs.png) : nullptr;
       }},
  };
  return registry;
}

std::vector<std::unique_ptr<FrameSink>> make_sinks(const Scenario& scenario, const std::filesystem::path& output_dir) {
  std::vector<std::unique_ptr<FrameSink>> sinks;
  for (const SinkEntry& entry : sink_registry()) {
    if (auto sink = entry.make(scenario, output_dir)) sinks.push_back(std::move(sink));
  }
  return sinks;
}

}  // namespace pneuma::engine
