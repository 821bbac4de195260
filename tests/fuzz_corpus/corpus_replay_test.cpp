// The fuzzers' inputs replayed in every test run (fuzz/corpus/<target>/: the seeds and every
// past finding, kept as `regression-*` files): each goes through the loader its
// fuzzer drives and must load or fail with a pneuma::Error of one line. The findings were
// crashes, undefined behaviour or impossible allocations before their fixes; here any other
// exception fails the test, and a crash fails the run.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "nifti_gz_input.h"  // fuzz/: the harness's own compression of its input
#include "pneuma/core/error.h"
#include "pneuma/field/tissue.h"
#include "pneuma/mesh/geometry/validate.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "pneuma/mesh/labels/labels.h"
#include "pneuma/model/field_cache.h"
#include "pneuma/runner/output_registry.h"
#include "pneuma/scenario/scenario.h"
#include "pneuma/scenario/tissue_config.h"
#include "test_support.h"

namespace {

namespace fs = std::filesystem;
using pneuma::test::TempDir;

struct Target {
  const char* corpus;     // fuzz/corpus/<corpus>
  const char* extension;  // the one its fuzzer gives the bytes
  std::function<void(const fs::path&)> load;
  // The input as its fuzzer gives it to the loader (none: the file's bytes as they are).
  std::function<std::string(const std::string&)> prepare = nullptr;
};

void read_and_validate(const fs::path& file) { (void)pneuma::mesh::validate(pneuma::mesh::read_mesh(file)); }

const std::vector<Target>& targets() {
  static const std::vector<Target> all = {
      {"scenario", ".yaml", [](const fs::path& f) { (void)pneuma::runner::load_scenario(f); }},
      {"tissue", ".yaml", [](const fs::path& f) { (void)pneuma::scenario::load_tissue(f); }},
      {"field_cache", ".h5", [](const fs::path& f) { (void)pneuma::model::load_field(f); }},
      {"nifti", ".nii", [](const fs::path& f) { (void)pneuma::image::read_label_map(f); }},
      {"nifti_gz", ".nii.gz", [](const fs::path& f) { (void)pneuma::image::read_label_map(f); },
       [](const std::string& bytes) {
         return pneuma::fuzz::nifti_gz_bytes(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
       }},
      {"labels_nrrd", ".nrrd", [](const fs::path& f) { (void)pneuma::image::read_label_map(f); }},
      {"labels_mha", ".mha", [](const fs::path& f) { (void)pneuma::image::read_label_map(f); }},
      {"mesh_stl", ".stl", read_and_validate},
      {"mesh_ply", ".ply", read_and_validate},
      {"mesh_obj", ".obj", read_and_validate},
      {"mesh_vtk", ".vtk", read_and_validate},
      {"mesh_vtp", ".vtp", read_and_validate},
  };
  return all;
}

}  // namespace

TEST(FuzzCorpus, EveryInputLoadsOrFailsWithOneLine) {
  TempDir dir;
  std::size_t regressions = 0;
  for (const Target& target : targets()) {
    const fs::path corpus = pneuma::test::source_dir() / "fuzz" / "corpus" / target.corpus;
    std::vector<fs::path> files;
    for (const auto& entry : fs::directory_iterator(corpus)) files.push_back(entry.path());
    std::sort(files.begin(), files.end());
    EXPECT_FALSE(files.empty()) << corpus;
    for (const fs::path& file : files) {
      const std::string name = file.filename().string();
      regressions += name.starts_with("regression-");
      const fs::path input = dir / (std::string(target.corpus) + target.extension);
      if (target.prepare) {
        std::ofstream(input, std::ios::binary | std::ios::trunc) << target.prepare(pneuma::test::read_text(file));
      } else {
        fs::copy_file(file, input, fs::copy_options::overwrite_existing);
      }
      try {
        target.load(input);
      } catch (const pneuma::Error& e) {
        const std::string what = e.what();
        EXPECT_FALSE(what.empty()) << file;
        EXPECT_EQ(what.find('\n'), std::string::npos) << file << ": " << what;
      }
    }
  }
  EXPECT_GE(regressions, 10u) << "the findings so far are all replayed";
}
