#pragma once
// Tissue files (configs/tissue/*.yaml, the keys in field/tissue.h) read into field::Tissue.
// Read when the scenario is loaded, so that a bad tissue file fails before any work.
#include <filesystem>
#include <string>

#include "pneuma/field/tissue.h"
#include "pneuma/scenario/config.h"

namespace pneuma::scenario {

// Reads a tissue file. Throws IoError / InputError ("<file>:<line>:<col>: <key>: <expected>").
field::Tissue load_tissue(const std::filesystem::path& path);
field::Tissue read_tissue(const scenario::Node& root);
// A shipped preset by name (configs/tissue/<name>.yaml) or a path.
std::filesystem::path tissue_file(const std::string& name_or_path, const std::filesystem::path& config_dir);

}  // namespace pneuma::scenario
