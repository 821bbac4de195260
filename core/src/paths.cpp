#include "pneuma/core/paths.h"

#include <link.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <fstream>
#include <ios>
#include <iterator>

#include "pneuma/core/error.h"

namespace pneuma {

std::string missing_reason(const std::filesystem::path& path) {
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (ec == std::errc::permission_denied) return "permission denied";
  if (ec || !std::filesystem::exists(status)) return "no such file";
  return {};
}

std::string read_file_bytes(const std::filesystem::path& path, std::uintmax_t max_bytes) {
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (ec == std::errc::permission_denied) throw IoError(path.string() + ": cannot open file: permission denied");
  if (!ec && std::filesystem::exists(status) && !std::filesystem::is_regular_file(status) &&
      !std::filesystem::is_directory(status)) {
    // A device (/dev/zero), pipe or socket: it may never end, or block on open.
    throw InputError(path.string() + ": not a regular file (a device, pipe or socket); expected a file");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in && ::access(path.c_str(), R_OK) != 0 && errno == EACCES)
    throw IoError(path.string() + ": cannot open file: permission denied");
  if (!in || std::filesystem::is_directory(path, ec)) throw IoError(path.string() + ": cannot open file");
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (!ec && size > max_bytes) {
    throw InputError(path.string() + ": a file of " + std::to_string(size) + " bytes; expected at most " +
                     std::to_string(max_bytes) + " bytes for this kind of file");
  }
  // libstdc++'s filebuf throws on a read error (EIO from /proc/self/mem, a failing disk); a block
  // read catches it and sets badbit.
  const std::string eio = path.string() + ": cannot read file (an input/output error)";
  std::string bytes;
  if (!ec && size > 0) {
    // The size the file says it has in one read (a character at a time, a 38 MB mesh took 0.2 s);
    // then whatever follows if it grew.
    bytes.resize(static_cast<std::size_t>(size));
    in.read(bytes.data(), static_cast<std::streamsize>(size));
    if (in.bad()) throw IoError(eio);
    bytes.resize(static_cast<std::size_t>(in.gcount()));
    if (!in) return bytes;  // the end came first (the file shrank)
  }
  try {
    bytes.append(std::istreambuf_iterator<char>(in), {});
  } catch (const std::ios_base::failure&) {
    throw IoError(eio);
  }
  if (in.bad()) throw IoError(path.string() + ": cannot read file");
  return bytes;
}

std::vector<std::string> file_stems(const std::filesystem::path& folder, const std::string& extension) {
  std::vector<std::string> stems;
  std::error_code ec;
  for (std::filesystem::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    const std::filesystem::path& file = it->path();
    if (it->is_regular_file(ec) && file.extension() == extension) stems.push_back(file.stem().string());
  }
  std::sort(stems.begin(), stems.end());
  return stems;
}

std::string join_names(const std::vector<std::string>& names) {
  if (names.empty()) return "none";
  std::string joined;
  for (const std::string& name : names) joined += (joined.empty() ? "" : ", ") + name;
  return joined;
}

void require_readable_file(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  // A folder on the way without search permission: not "no such file" (#29).
  if (ec == std::errc::permission_denied) throw IoError(name + ": cannot read: permission denied");
  if (ec || !std::filesystem::exists(status)) throw IoError(name + ": cannot read: no such file");
  if (std::filesystem::is_directory(status)) throw IoError(name + ": cannot read: is a folder");
  // Opening a pipe blocks until a writer comes, and a device may never end (#49).
  if (!std::filesystem::is_regular_file(status))
    throw InputError(name + ": not a regular file (a device, pipe or socket); expected a file");
  if (!std::ifstream(path, std::ios::binary)) throw IoError(name + ": cannot read: permission denied");
}

std::filesystem::path running_binary() {
  // The loaded object whose segments hold this function: the executable itself (dlpi_name "")
  // or a shared object such as the Python extension (dlpi_name its path).
  struct Search {
    std::uintptr_t address = 0;
    bool found = false;
    std::string name;
  } search;
  search.address = reinterpret_cast<std::uintptr_t>(&running_binary);
  dl_iterate_phdr(
      [](dl_phdr_info* info, std::size_t, void* data) -> int {
        auto& s = *static_cast<Search*>(data);
        for (ElfW(Half) i = 0; i < info->dlpi_phnum; ++i) {
          const ElfW(Phdr)& segment = info->dlpi_phdr[i];
          if (segment.p_type != PT_LOAD) continue;
          const std::uintptr_t begin = info->dlpi_addr + segment.p_vaddr;
          if (s.address >= begin && s.address < begin + segment.p_memsz) {
            s.found = true;
            s.name = info->dlpi_name ? info->dlpi_name : "";
            return 1;
          }
        }
        return 0;
      },
      &search);
  const std::filesystem::path file = search.found && !search.name.empty() ? search.name : "/proc/self/exe";
  std::error_code ec;
  std::filesystem::path canonical = std::filesystem::canonical(file, ec);
  return ec ? std::filesystem::path() : canonical;
}

}  // namespace pneuma
