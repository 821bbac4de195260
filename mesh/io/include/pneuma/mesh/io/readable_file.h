#pragma once
// Private to pneuma_mesh: the check every reader makes before it opens an input file, with the
// one-line IoErrors they share ("<file>: cannot read: no such file | is a folder | permission denied").
#include <filesystem>
#include <fstream>
#include <string>

#include "pneuma/core/error.h"

namespace pneuma::mesh::detail {

inline void require_readable_file(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  // A folder on the way without search permission: not "no such file" (#29).
  if (ec == std::errc::permission_denied) throw IoError(name + ": cannot read: permission denied");
  if (ec || !std::filesystem::exists(status)) throw IoError(name + ": cannot read: no such file");
  if (std::filesystem::is_directory(status)) throw IoError(name + ": cannot read: is a folder");
  if (!std::ifstream(path, std::ios::binary)) throw IoError(name + ": cannot read: permission denied");
}

}  // namespace pneuma::mesh::detail
