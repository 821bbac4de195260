#include "pneuma/runner/output_registry.h"

#include "pneuma/outputs/frame_outputs.h"
#include "pneuma/outputs/motion_csv.h"
#include "pneuma/outputs/phases.h"
#include "pneuma/outputs/physiology_csv.h"
#include "pneuma/outputs/report.h"
#include "pneuma/outputs/voxels_output.h"
#include "pneuma/render/png_sink.h"

namespace pneuma::runner {

const std::vector<outputs::OutputPlugin>& output_registry() {
  static const std::vector<outputs::OutputPlugin> registry{
      outputs::gltf_output(),            // breathing.glb
      outputs::hdf5_output(),            // series.h5 + series.xdmf
      outputs::mesh_sequence_output(),   // frames/frame_NNNNN.<ply|obj|stl>
      render::png_output(),              // png/frame_NNNNN.png
      outputs::physiology_csv_output(),  // physiology.csv + physiology-breaths.csv
      outputs::motion_csv_output(),      // motion.csv
      outputs::phases_output(),          // phases.csv + phases/bin_NN.ply (4D-CT bins; off by default)
      outputs::voxels_output(),          // voxels/: DVFs, warped label map and CT (off by default)
      outputs::report_output(),          // report.html
  };
  return registry;
}

const std::vector<scenario::OutputKey>& output_keys() {
  static const std::vector<scenario::OutputKey> keys = [] {
    std::vector<scenario::OutputKey> out;
    for (const outputs::OutputPlugin& plugin : output_registry()) out.push_back(plugin.key);
    return out;
  }();
  return keys;
}

scenario::Scenario load_scenario(const std::filesystem::path& file) {
  return scenario::load_scenario(file, output_keys());
}

scenario::Scenario read_scenario(const scenario::Node& root, const std::filesystem::path& file) {
  return scenario::read_scenario(root, file, output_keys());
}

std::vector<const outputs::OutputPlugin*> requested_outputs(const scenario::Scenario& scenario) {
  std::vector<const outputs::OutputPlugin*> plugins;
  for (const outputs::OutputPlugin& plugin : output_registry()) {
    if (scenario.output(plugin.key.key)) plugins.push_back(&plugin);
  }
  return plugins;
}

outputs::OutputNeeds requested_needs(const scenario::Scenario& scenario) {
  outputs::OutputNeeds needs;
  for (const outputs::OutputPlugin* plugin : requested_outputs(scenario)) {
    needs.physiology = needs.physiology || plugin->needs.physiology;
    needs.breath_motion = needs.breath_motion || plugin->needs.breath_motion;
    needs.interior = needs.interior || plugin->needs.interior;
  }
  return needs;
}

}  // namespace pneuma::runner
