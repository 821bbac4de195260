#pragma once
// manifest.json: every file a run wrote, with its size and SHA-256, the scenario, the
// library versions and the timings. Everything in it is deterministic except the timings.
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace pneuma::outputs {

struct ManifestInput {
  std::filesystem::path scenario_file;
  std::string scenario_name;
  std::vector<std::filesystem::path> files;                // absolute or relative to output_dir
  std::vector<std::pair<std::string, double>> timings_s;   // stage -> seconds, in run order
  std::vector<std::pair<std::string, std::string>> facts;  // e.g. {"vertices", "12345"}
};

// Hex SHA-256 of a file's bytes. Throws IoError when it cannot be read.
std::string sha256_file(const std::filesystem::path& file);

// The versions of the libraries pneuma was built with, by name.
std::vector<std::pair<std::string, std::string>> library_versions();

// Writes <output_dir>/manifest.json atomically and returns its path.
std::filesystem::path write_manifest(const std::filesystem::path& output_dir, const ManifestInput& input);

// The top-level names (files, and folders such as frames/) that <output_dir>/manifest.json
// lists: what a previous run wrote there. Empty when there is no manifest or it cannot be read
// (then nothing is known to be a previous output, and nothing is removed).
std::vector<std::string> manifest_entries(const std::filesystem::path& output_dir);

}  // namespace pneuma::outputs
