// Voxel files by measurement (BENCHMARKS.md, "Voxel outputs", "Files"): a real run's plain .nii
// files (bench/voxel_files.sh makes them: a pull-back DVF and the warped label map) written again
// in every kind pneuma could write, timed, each file then read back by ITK (its ImageIO, as
// plastimatch and pneuma read) and checked voxel for voxel against the original. The script
// times nibabel and plastimatch on the same files. Baseline: zlib level 6 in one member, what
// pneuma wrote before (gzopen "wb6"). Input: PNEUMA_VOXEL_FILES_DIR with dvf.nii and labels.nii;
// the files are left in its out/ for the script.
// clang-format off
#include "itk_clang.h"  // first: Debian's ITK headers under clang
// clang-format on
#include <benchmark/benchmark.h>
#include <itkMetaImageIO.h>
#include <itkNiftiImageIO.h>
#include <itkNrrdImageIO.h>
#include <tbb/global_control.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "pneuma/core/paths.h"
#include "pneuma/voxels/gzip.h"

using namespace pneuma;
using namespace pneuma::voxels;
namespace fs = std::filesystem;

namespace {

fs::path input_dir() {
  const char* dir = std::getenv("PNEUMA_VOXEL_FILES_DIR");
  return dir == nullptr ? fs::path() : fs::path(dir);
}

// An image as ITK reads it: the IO object with its header, and the voxels.
struct ItkImage {
  itk::ImageIOBase::Pointer io;
  std::vector<char> voxels;
};

itk::ImageIOBase::Pointer io_for(const fs::path& file) {
  const std::string name = file.filename().string();
  if (name.ends_with(".mha")) return itk::MetaImageIO::New().GetPointer();
  if (name.ends_with(".nrrd")) return itk::NrrdImageIO::New().GetPointer();
  return itk::NiftiImageIO::New().GetPointer();
}

ItkImage read_itk(const fs::path& file) {
  ItkImage image{io_for(file), {}};
  image.io->SetFileName(file.string());
  image.io->ReadImageInformation();
  itk::ImageIORegion region(3);
  for (unsigned a = 0; a < 3; ++a) {
    region.SetIndex(a, 0);
    region.SetSize(a, image.io->GetDimensions(a));
  }
  image.io->SetIORegion(region);
  image.voxels.resize(image.io->GetImageSizeInBytes());
  image.io->Read(image.voxels.data());
  return image;
}

void write_itk(const ItkImage& from, const fs::path& file, bool compress) {
  const itk::ImageIOBase::Pointer io = io_for(file);
  io->SetNumberOfDimensions(3);
  for (unsigned a = 0; a < 3; ++a) {
    io->SetDimensions(a, from.io->GetDimensions(a));
    io->SetSpacing(a, from.io->GetSpacing(a));
    io->SetOrigin(a, from.io->GetOrigin(a));
    io->SetDirection(a, from.io->GetDirection(a));
  }
  io->SetIORegion(from.io->GetIORegion());
  io->SetPixelType(from.io->GetPixelType());
  io->SetComponentType(from.io->GetComponentType());
  io->SetNumberOfComponents(from.io->GetNumberOfComponents());
  io->SetUseCompression(compress);
  io->SetFileName(file.string());
  io->WriteImageInformation();
  io->Write(from.voxels.data());
}

// The original plain .nii (pneuma's own, header patched) and its voxels as ITK reads them.
struct Input {
  std::string bytes;
  ItkImage image;
};

const Input& input(const std::string& name) {
  static std::map<std::string, Input> inputs;
  auto it = inputs.find(name);
  if (it == inputs.end()) {
    const fs::path file = input_dir() / (name + ".nii");
    it = inputs.emplace(name, Input{read_file_bytes(file), read_itk(file)}).first;
  }
  return it->second;
}

struct Kind {
  std::string suffix;  // the file name after "<input>-"
  enum { gzip, nii, mha, nrrd } format;
  GzipSettings gzip_settings{};
  bool compress = false;  // .mha / .nrrd
};

const std::vector<Kind>& kinds() {
  static const std::vector<Kind> all = [] {
    std::vector<Kind> k;
    for (const int level : {1, 3, 6, 9})
      k.push_back({"zlib" + std::to_string(level) + ".nii.gz", Kind::gzip, {GzipLibrary::zlib, level, 0}});
    for (const int level : {1, 6})
      k.push_back(
          {"zlib" + std::to_string(level) + "-members.nii.gz", Kind::gzip, {GzipLibrary::zlib, level, 4 << 20}});
    for (const int level : {1, 6}) {
      k.push_back({"deflate" + std::to_string(level) + ".nii.gz", Kind::gzip, {GzipLibrary::libdeflate, level, 0}});
      k.push_back({"deflate" + std::to_string(level) + "-members.nii.gz",
                   Kind::gzip,
                   {GzipLibrary::libdeflate, level, 4 << 20}});
    }
    k.push_back({"plain.nii", Kind::nii});
    k.push_back({"raw.mha", Kind::mha, {}, false});
    k.push_back({"zlib.mha", Kind::mha, {}, true});
    k.push_back({"raw.nrrd", Kind::nrrd, {}, false});
    k.push_back({"gzip.nrrd", Kind::nrrd, {}, true});
    return k;
  }();
  return all;
}

fs::path output(const std::string& name, const Kind& kind) {
  fs::create_directories(input_dir() / "out");
  return input_dir() / "out" / (name + "-" + kind.suffix);
}

// range(0): the input (0 dvf, 1 labels), range(1): the kind, range(2): TBB's threads.
void BM_Write(benchmark::State& state) {
  if (input_dir().empty()) {
    state.SkipWithError("PNEUMA_VOXEL_FILES_DIR is not set (bench/voxel_files.sh sets it)");
    return;
  }
  const std::string name = state.range(0) == 0 ? "dvf" : "labels";
  const Kind& kind = kinds()[static_cast<std::size_t>(state.range(1))];
  const tbb::global_control threads(tbb::global_control::max_allowed_parallelism,
                                    static_cast<std::size_t>(state.range(2)));
  const Input& in = input(name);
  const fs::path file = output(name, kind);
  state.SetLabel(file.filename().string());
  for (auto _ : state) {
    if (kind.format == Kind::gzip) {
      const auto gz = gzip_bytes(std::span(reinterpret_cast<const std::uint8_t*>(in.bytes.data()), in.bytes.size()),
                                 kind.gzip_settings);
      std::ofstream(file, std::ios::binary)
          .write(reinterpret_cast<const char*>(gz.data()), static_cast<long>(gz.size()));
    } else if (kind.format == Kind::nii) {
      std::ofstream(file, std::ios::binary).write(in.bytes.data(), static_cast<long>(in.bytes.size()));
    } else {
      write_itk(in.image, file, kind.compress);
    }
  }
  state.counters["MB"] = static_cast<double>(fs::file_size(file)) / 1e6;
  state.counters["of_plain"] = static_cast<double>(fs::file_size(file)) / static_cast<double>(in.bytes.size());
}

// ITK reads the file written by BM_Write; its voxels must be the original's, byte for byte.
void BM_ReadItk(benchmark::State& state) {
  if (input_dir().empty()) {
    state.SkipWithError("PNEUMA_VOXEL_FILES_DIR is not set (bench/voxel_files.sh sets it)");
    return;
  }
  const std::string name = state.range(0) == 0 ? "dvf" : "labels";
  const Kind& kind = kinds()[static_cast<std::size_t>(state.range(1))];
  const Input& in = input(name);
  const fs::path file = output(name, kind);
  state.SetLabel(file.filename().string());
  bool same = true;
  for (auto _ : state) {
    const ItkImage read = read_itk(file);
    same = same && read.voxels == in.image.voxels;
  }
  if (!same) state.SkipWithError("ITK read other voxels than the original's");
}

void kinds_args(benchmark::internal::Benchmark* b, bool threads) {
  for (int input = 0; input < 2; ++input)
    for (int k = 0; k < static_cast<int>(kinds().size()); ++k) {
      const bool members = kinds()[static_cast<std::size_t>(k)].gzip_settings.member_bytes != 0 &&
                           kinds()[static_cast<std::size_t>(k)].format == Kind::gzip;
      if (threads && members) b->Args({input, k, 1});
      b->Args({input, k, 2});
    }
}

}  // namespace

BENCHMARK(BM_Write)
    ->Apply([](benchmark::internal::Benchmark* b) { kinds_args(b, true); })
    ->Iterations(1)
    ->Repetitions(3)
    ->ReportAggregatesOnly(true)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_ReadItk)
    ->Apply([](benchmark::internal::Benchmark* b) { kinds_args(b, false); })
    ->Iterations(1)
    ->Repetitions(3)
    ->ReportAggregatesOnly(true)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

BENCHMARK_MAIN();
