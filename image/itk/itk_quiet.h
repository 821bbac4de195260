#pragma once
// ITK calls, one at a time and silent, for the translation units that link pneuma_itk
// (image/src/itk_read.cpp, voxels/src/voxels_itk.cpp): MetaIO writes its complaints to std::cerr and ITK keeps a
// process-wide warning switch, so every ITK read or write holds itk_quiet::lock() and a
// SilenceStdErr while it runs; the caller turns failures into pneuma's one line.
#include <iostream>
#include <mutex>
#include <streambuf>

namespace pneuma::itk_quiet {

// The one mutex of every ITK call in the process (an inline function: one object in all units).
inline std::mutex& mutex() {
  static std::mutex m;
  return m;
}

// std::cerr goes nowhere while this lives.
class SilenceStdErr {
 public:
  SilenceStdErr() : saved_(std::cerr.rdbuf(&null_)) {}
  ~SilenceStdErr() { std::cerr.rdbuf(saved_); }
  SilenceStdErr(const SilenceStdErr&) = delete;
  SilenceStdErr& operator=(const SilenceStdErr&) = delete;

 private:
  struct NullBuffer : std::streambuf {
    int overflow(int c) override { return c; }
  } null_;
  std::streambuf* saved_;
};

}  // namespace pneuma::itk_quiet
