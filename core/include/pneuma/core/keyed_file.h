#pragma once
// A cache file of derived data kept in a run's output folder for the next run (#50: the rest
// lungs' mask, the body's field, the fold check's pass): a kind, the key of the inputs it was
// derived from, and a payload checked by its SHA-256 (docs/formats.md, "Keyed caches"):
//   <kind>\n
//   key <key>\n
//   bytes <N> sha256 <64 hex digits>\n
//   <N bytes>
// A file of another kind or key is no error (the inputs changed: the caller derives it again);
// a damaged one is never used.
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace pneuma::core {

// Writes the file atomically (atomic_file.h). Throws IoError when it cannot be written.
void save_keyed_file(const std::filesystem::path& path, std::string_view kind, std::string_view key,
                     std::string_view payload);

// The payload kept at `path` for `key`; none where there is no file or it holds another key.
// None, with `discarded` set to "<path>: not a <kind> file: <why>", where the file is cut,
// edited or of another kind; `discarded` is cleared otherwise. Throws IoError when the file
// exists but cannot be read.
std::optional<std::string> load_keyed_file(const std::filesystem::path& path, std::string_view kind,
                                           std::string_view key, std::string& discarded);

}  // namespace pneuma::core
