#include "pneuma/core/paths.h"

#include <algorithm>
#include <fstream>
#include <iterator>

#include "pneuma/core/error.h"

namespace pneuma {

std::string read_file_bytes(const std::filesystem::path& path) {
  std::error_code ec;
  std::ifstream in(path, std::ios::binary);
  if (!in || std::filesystem::is_directory(path, ec)) throw IoError(path.string() + ": cannot open file");
  std::string bytes(std::istreambuf_iterator<char>(in), {});
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

}  // namespace pneuma
