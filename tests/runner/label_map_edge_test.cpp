// A lung that reaches the label map's edge was cut flat by the scan there, not by anatomy (#49):
// the run says so in one warning line and in the manifest. Oracle: the synthetic map's ellipsoid
// is built cut by a known face, and the face's name follows the map's direction (a flipped k axis
// turns "inferior" into "superior").
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "test_support.h"

using pneuma::test::read_text;
using pneuma::test::run_pneuma;
using pneuma::test::TempDir;

namespace {

// An ellipsoid of label 3 (semi-axes 21, 27 and 33 mm) on a 3 mm raw NRRD, its centre `centre_k`
// voxels up the k axis (whose direction is `k_direction`: 3 or -3 mm along z).
std::filesystem::path write_blob(const TempDir& dir, const std::string& name, double centre_k, int k_direction) {
  constexpr int nx = 20, ny = 24, nz = 28;
  std::vector<std::int16_t> labels(static_cast<std::size_t>(nx) * ny * nz, 0);
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        const double x = (i - nx / 2.0) / 7.0, y = (j - ny / 2.0) / 9.0, z = (k - centre_k) / 11.0;
        if (x * x + y * y + z * z < 1.0)
          labels[static_cast<std::size_t>(i) + nx * (static_cast<std::size_t>(j) + ny * static_cast<std::size_t>(k))] =
              3;
      }
    }
  }
  const std::string header = "NRRD0004\ntype: short\ndimension: 3\nsizes: 20 24 28\nspace: left-posterior-superior\n"
                             "space directions: (3,0,0) (0,3,0) (0,0," +
                             std::to_string(k_direction) +
                             ")\nkinds: domain domain domain\nendian: little\nencoding: raw\nspace origin: (0,0,0)\n\n";
  auto path = dir / name;
  std::ofstream out(path, std::ios::binary);
  out << header;
  out.write(reinterpret_cast<const char*>(labels.data()), static_cast<std::streamsize>(labels.size() * 2));
  return path;
}

// Runs the blob in `map` and returns {stderr, the manifest's fact}.
std::pair<std::string, std::string> run_blob(const TempDir& dir, const std::filesystem::path& map,
                                             const std::string& out) {
  const auto scenario =
      dir.write(out + ".yaml", "duration: 2 s\nframes: {rate: 5 Hz}\nmesh: {labels: " + map.filename().string() +
                                   ", values: [3], share: 2 %, edge: 6 mm}\n"
                                   "field: {cache: off}\nphysiology: {preset: healthy-adult}\n"
                                   "outputs: {gltf: false, hdf5: false, report: false}\n");
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / out).string(), "-q"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  const auto manifest = nlohmann::json::parse(read_text(dir / out / "manifest.json"));
  return {r.err, manifest.at("facts").at("touches_label_map_edge").get<std::string>()};
}

}  // namespace

TEST(LabelMapEdge, ALungCutByTheMapsEdgeIsOneWarningLineAndAManifestFact) {
  TempDir dir;
  // Centred 3 voxels up: 8 of its 11 voxels of half-height lie below the first slice.
  for (const int k_direction : {3, -3}) {
    const auto map = write_blob(dir, "cut" + std::to_string(k_direction) + ".nrrd", 3.0, k_direction);
    const std::string face = k_direction > 0 ? "inferior face (k = 0)" : "superior face (k = 0)";
    const auto [err, fact] = run_blob(dir, map, "cut" + std::to_string(k_direction));
    EXPECT_EQ(err, "pneuma: warning: " + map.string() + ": the lung touches the label map's edge at its " + face +
                       " (the scan cuts it flat there, not anatomy)\n");
    EXPECT_EQ(fact, face);
  }
}

TEST(LabelMapEdge, ALungInsideTheMapGivesNoWarning) {
  TempDir dir;
  const auto map = write_blob(dir, "inside.nrrd", 13.5, 3);  // 2.5 voxels of background above and below
  const auto [err, fact] = run_blob(dir, map, "inside");
  EXPECT_EQ(err, "");
  EXPECT_EQ(fact, "no");
}
