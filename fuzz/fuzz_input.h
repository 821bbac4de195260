#pragma once
// libFuzzer targets read their input through pneuma's real entry points, which take paths: the
// bytes go to a file of this process (in $TMPDIR, /dev/shm when there) with the extension
// that selects the reader. A pneuma::Error is the expected answer to bad input; any other
// exception escapes and libFuzzer reports it as a crash, as it does a sanitizer finding.
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace pneuma::fuzz {

inline std::filesystem::path input_file(const std::string& extension) {
  const char* tmp = std::getenv("TMPDIR");
  const std::filesystem::path dir = tmp ? tmp : (std::filesystem::exists("/dev/shm") ? "/dev/shm" : "/tmp");
  return dir / ("pneuma-fuzz-" + std::to_string(::getpid()) + extension);
}

inline const std::filesystem::path& write_input(const std::uint8_t* data, std::size_t size,
                                                const std::string& extension) {
  static const std::filesystem::path path = input_file(extension);
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path;
}

}  // namespace pneuma::fuzz
