#pragma once
// motion.csv: how each anatomical region of the surface moved in each breath (docs/realism.md):
// one row per breath and region, displacements in mm along the body axes (caudal: downward
// positive; anterior; lateral: away from the midline), the region's share of the volume change.
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "pneuma/outputs/breath_motion.h"
#include "pneuma/outputs/output.h"

namespace pneuma::outputs {

// Writes the file atomically. Throws IoError. With `lung_names` (two lungs: {"right", "left"},
// indexed by BreathMotion::lung) each row starts with a `lung` column; without, the one-surface
// columns as they always were.
void write_motion_csv(const std::filesystem::path& path, const std::vector<BreathMotion>& breaths,
                      const std::vector<std::string>& lung_names = {});

// Means over the breaths, as manifest facts ("motion.diaphragmatic.caudal_mean_mm", ...); with
// `lung_names`, per lung ("motion.right.diaphragmatic.caudal_mean_mm", ...).
std::vector<std::pair<std::string, std::string>> motion_facts(const std::vector<BreathMotion>& breaths,
                                                              const std::vector<std::string>& lung_names = {});

// The names of `model`'s lungs for the functions above: empty for one lung, else by side.
std::vector<std::string> motion_lung_names(const model::Model& model);

// `outputs: {motion_csv: true}` (on by default): motion.csv, and motion_facts() in the manifest.
OutputPlugin motion_csv_output();

}  // namespace pneuma::outputs
