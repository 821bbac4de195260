#pragma once
// Questions about paths that answer instead of throwing: std::filesystem's throwing overloads
// raise filesystem_error for a name too long for the file system or a folder without
// permission, which would escape a loader as something other than pneuma::Error.
#include <filesystem>
#include <system_error>

namespace pneuma {

// Whether something exists at `path`; false where the path cannot be examined.
inline bool path_exists(const std::filesystem::path& path) noexcept {
  std::error_code ec;
  return std::filesystem::exists(path, ec) && !ec;
}

}  // namespace pneuma
