#include "pneuma/outputs/manifest.h"

#include <H5public.h>
#include <openssl/opensslv.h>
#include <sundials/sundials_config.h>
#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/core/sha256.h"
#include "pneuma/voxels/written_digest.h"

namespace pneuma::outputs {

// A voxel file's digest from its writing (voxels/written_digest.h), when it is still that file:
// ten phases at a label map's own grid are 20 GB that would otherwise be read back (#50).
std::string sha256_file(const std::filesystem::path& file) {
  if (std::optional<std::string> written = voxels::written_sha256(file)) return *std::move(written);
  return core::to_hex(core::sha256_of_file(file));
}

std::vector<std::pair<std::string, std::string>> library_versions() {
  auto dotted = [](int a, int b, int c) {
    return std::to_string(a) + "." + std::to_string(b) + "." + std::to_string(c);
  };
  return {
      {"pneuma", PNEUMA_VERSION},
      {"sundials", SUNDIALS_VERSION},
      {"eigen", dotted(EIGEN_WORLD_VERSION, EIGEN_MAJOR_VERSION, EIGEN_MINOR_VERSION)},
      {"hdf5", dotted(H5_VERS_MAJOR, H5_VERS_MINOR, H5_VERS_RELEASE)},
      {"openssl", OPENSSL_VERSION_STR},
  };
}

std::filesystem::path write_manifest(const std::filesystem::path& output_dir, const ManifestInput& input) {
  nlohmann::ordered_json j;
  j["scenario"] = {{"name", input.scenario_name},
                   {"file", input.scenario_file.string()},
                   {"sha256", sha256_file(input.scenario_file)}};
  nlohmann::ordered_json versions = nlohmann::ordered_json::object();
  for (const auto& [name, version] : library_versions()) versions[name] = version;
  j["versions"] = versions;
  nlohmann::ordered_json facts = nlohmann::ordered_json::object();
  for (const auto& [key, value] : input.facts) facts[key] = value;
  j["facts"] = facts;
  nlohmann::ordered_json files = nlohmann::ordered_json::array();
  for (const auto& file : input.files) {
    const auto full = file.is_absolute() ? file : output_dir / file;
    files.push_back({{"path", std::filesystem::relative(full, output_dir).generic_string()},
                     {"bytes", std::filesystem::file_size(full)},
                     {"sha256", sha256_file(full)}});
  }
  j["files"] = files;
  nlohmann::ordered_json timings = nlohmann::ordered_json::object();
  for (const auto& [stage, seconds] : input.timings_s) timings[stage] = seconds;
  j["timings_s"] = timings;
  auto path = output_dir / "manifest.json";
  write_stream_atomically(path, false, [&](std::ostream& out) {
    out << j.dump(2, ' ', false, nlohmann::ordered_json::error_handler_t::replace) << '\n';
  });
  return path;
}

std::vector<std::string> manifest_entries(const std::filesystem::path& output_dir) {
  std::ifstream in(output_dir / "manifest.json");
  if (!in) return {};
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (!j.is_object() || !j.contains("files") || !j["files"].is_array()) return {};
  std::vector<std::string> entries;
  for (const auto& file : j["files"]) {
    if (!file.is_object() || !file.contains("path") || !file["path"].is_string()) continue;
    const std::filesystem::path path(file["path"].get<std::string>());
    if (path.empty() || path.is_absolute()) continue;
    const std::string top = path.begin()->string();
    if (top != ".." && top != "." && std::find(entries.begin(), entries.end(), top) == entries.end()) {
      entries.push_back(top);
    }
  }
  return entries;
}

}  // namespace pneuma::outputs
