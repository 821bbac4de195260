// Keyed cache files (keyed_file.h).
#include "pneuma/core/keyed_file.h"

#include <charconv>
#include <fstream>
#include <system_error>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/paths.h"
#include "pneuma/core/sha256.h"

namespace pneuma::core {
namespace {

std::string digest_of(std::string_view bytes) { return to_hex(Sha256().update(bytes.data(), bytes.size()).finish()); }

// The next line of `text` from `at` (without its '\n'); none where no '\n' follows.
std::optional<std::string_view> next_line(std::string_view text, std::size_t& at) {
  const std::size_t end = text.find('\n', at);
  if (end == std::string_view::npos) return std::nullopt;
  const std::string_view line = text.substr(at, end - at);
  at = end + 1;
  return line;
}

}  // namespace

void save_keyed_file(const std::filesystem::path& path, std::string_view kind, std::string_view key,
                     std::string_view payload) {
  const std::string digest = digest_of(payload);
  write_stream_atomically(path, true, [&](std::ostream& out) {
    out << kind << "\nkey " << key << "\nbytes " << payload.size() << " sha256 " << digest << '\n';
    out.write(payload.data(), static_cast<std::streamsize>(payload.size()));
  });
}

std::optional<std::string> load_keyed_file(const std::filesystem::path& path, std::string_view kind,
                                           std::string_view key, std::string& discarded) {
  discarded.clear();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return std::nullopt;
  std::string bytes = read_file_bytes(path);
  const auto refuse = [&](std::string_view why) {
    discarded = path.string() + ": not a " + std::string(kind) + " file: " + std::string(why);
    return std::nullopt;
  };
  const std::string_view text(bytes);
  std::size_t at = 0;
  const auto first = next_line(text, at);
  if (!first || *first != kind) return refuse("expected '" + std::string(kind) + "' on its first line");
  const auto key_line = next_line(text, at);
  if (!key_line || !key_line->starts_with("key ")) return refuse("expected 'key <key>' on its second line");
  if (key_line->substr(4) != key) return std::nullopt;  // derived from other inputs: not an error
  const auto sizes = next_line(text, at);
  constexpr std::string_view kBytes = "bytes ", kSha = " sha256 ";
  const std::size_t sha_at = sizes ? sizes->find(kSha) : std::string_view::npos;
  std::size_t size = 0;
  if (!sizes || !sizes->starts_with(kBytes) || sha_at == std::string_view::npos ||
      std::from_chars(sizes->data() + kBytes.size(), sizes->data() + sha_at, size).ptr != sizes->data() + sha_at)
    return refuse("expected 'bytes <N> sha256 <digest>' on its third line");
  if (text.size() - at != size)
    return refuse(std::to_string(text.size() - at) + " bytes after its header, expected " + std::to_string(size));
  if (digest_of(text.substr(at)) != sizes->substr(sha_at + kSha.size()))
    return refuse("its bytes do not match their SHA-256 (a damaged or edited file)");
  bytes.erase(0, at);
  return bytes;
}

}  // namespace pneuma::core
