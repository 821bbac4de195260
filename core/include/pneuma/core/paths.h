#pragma once
// Questions about paths that answer instead of throwing: std::filesystem's throwing overloads
// raise filesystem_error for a name too long for the file system or a folder without
// permission, which would escape a loader as something other than pneuma::Error.
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <system_error>
#include <vector>

namespace pneuma {

// Whether something exists at `path`; false where the path cannot be examined.
inline bool path_exists(const std::filesystem::path& path) noexcept {
  std::error_code ec;
  return std::filesystem::exists(path, ec) && !ec;
}

// Why nothing usable is at `path`: "no such file", or "permission denied" where a folder on the
// way cannot be searched (so that it is not reported as missing); empty when something is there.
std::string missing_reason(const std::filesystem::path& path);

// The whole file as bytes. Throws IoError ("<path>: cannot open file") for a missing file or a
// folder, ("<path>: cannot open file: permission denied") for one without read permission and
// ("<path>: cannot read file") for a read that fails; InputError for something that is not a
// regular file (a device such as /dev/zero, a pipe: it may never end) and for a file larger than
// `max_bytes`.
std::string read_file_bytes(const std::filesystem::path& path,
                            std::uintmax_t max_bytes = std::numeric_limits<std::uintmax_t>::max());

// The check every reader makes before it opens an input file, with the one-line IoErrors they
// share: "<file>: cannot read: no such file | is a folder | permission denied"; InputError for
// something that is not a regular file (a pipe would block the open, a device never ends).
void require_readable_file(const std::filesystem::path& path);

// The names, without extension and sorted, of the regular files in `folder` whose name ends in
// `extension` (such as ".yaml"); empty where the folder cannot be listed. For messages that
// name what is available (the shipped presets), so that they cannot drift from the folder.
std::vector<std::string> file_stems(const std::filesystem::path& folder, const std::string& extension);

// The file of the program or shared object that holds this function's code, canonical: the
// `pneuma` executable, or the Python module's extension when pneuma runs inside Python. Empty
// where it cannot be found. For the files a binary finds relative to itself (its presets).
std::filesystem::path running_binary();

// "a, b, c" (or "none" for an empty list).
std::string join_names(const std::vector<std::string>& names);

}  // namespace pneuma
