// Points and structures that follow the breath (voxels.points, voxels.structures; formats.md,
// "Points and structures"), on the right-lung phantom. Oracles: the surface frames the mesh
// sequence writes (PLY, read back by pneuma's reader) for a fiducial at a surface vertex; the
// forward DVF the voxel output writes (NRRD, its header and gzip data read here) for a fiducial at
// a voxel centre inside the lung; and, for a synthetic spherical target, the warped masks written
// per phase bin, whose union must be the ITV voxel for voxel.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "pneuma/image/label_map.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "pneuma/voxels/voxel_io.h"
#include "runner_fixture.h"
#include "test_support.h"

namespace {
namespace fs = std::filesystem;
using pneuma::test::CommandResult;
using pneuma::test::run_pneuma;
using pneuma::test::TempDir;

constexpr const char* kPhantom = R"(name: tracking
duration: 8 s
frames: {rate: 5 Hz}
mesh: {phantom: right, edge: 8 mm}
field: {tissue: healthy-upright, interior: {edge: 8 mm}, cache: field.h5}
physiology:
  preset: healthy-adult
  driver: {mode: spontaneous, rate: 15 /min, ie_ratio: 1:2, tidal_volume: 800 mL}
outputs:
  gltf: false
  hdf5: false
  report: false
  png: false
)";

std::vector<std::vector<std::string>> read_csv(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::vector<std::string>> rows;
  for (std::string line; std::getline(in, line);) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
    if (!line.empty() && line.back() == ',') cells.emplace_back();
    rows.push_back(cells);
  }
  return rows;
}

// A NRRD DVF: its geometry (mm, LPS) from the header, its components from the gzip data.
struct NrrdField {
  std::array<std::size_t, 3> size{};
  Eigen::Matrix3d directions = Eigen::Matrix3d::Zero();  // columns: i, j, k in mm
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  std::vector<float> values;
};

NrrdField read_nrrd_dvf(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t end = text.find("\n\n");
  NrrdField f;
  std::istringstream header(text.substr(0, end));
  const auto numbers = [](std::string s) {
    for (char& c : s) c = (c == '(' || c == ')' || c == ',') ? ' ' : c;
    std::istringstream words(s);
    std::vector<double> v;
    for (std::string w; words >> w;)
      if (w != "none") v.push_back(std::stod(w));
    return v;
  };
  for (std::string line; std::getline(header, line);) {
    if (line.starts_with("sizes: ")) {
      const auto v = numbers(line.substr(7));
      for (std::size_t a = 0; a < 3; ++a) f.size[a] = static_cast<std::size_t>(v[a + 1]);
    } else if (line.starts_with("space directions: ")) {
      const auto v = numbers(line.substr(18));
      for (int a = 0; a < 3; ++a)
        for (int r = 0; r < 3; ++r)
          f.directions(r, a) = v[3 * static_cast<std::size_t>(a) + static_cast<std::size_t>(r)];
    } else if (line.starts_with("space origin: ")) {
      const auto v = numbers(line.substr(14));
      f.origin = Eigen::Vector3d(v[0], v[1], v[2]);
    }
  }
  const std::string bytes = pneuma::test::gunzip(std::string_view(text).substr(end + 2));
  f.values.resize(bytes.size() / 4);
  std::memcpy(f.values.data(), bytes.data(), f.values.size() * 4);
  return f;
}

// A fiducial at a rest surface vertex moves with that vertex's surface frames (within 0.1 mm); one
// at a voxel centre inside the lung moves with the forward DVF there (within half a voxel); one far
// below the lung with the body.
TEST(Tracking, FiducialsFollowTheSurfaceFramesAndTheForwardDvf) {
  TempDir dir;
  // First run: the rest surface (frame 0, at FRC) and the DVF's grid.
  const std::string outputs = "  mesh_sequence: {format: ply}\n"
                              "  voxels: {at: [end_inspiration], spacing: 3 mm, format: nrrd, jacobian: false";
  const fs::path first = dir.write("first.yaml", std::string(kPhantom) + outputs + "}\n");
  CommandResult r = run_pneuma({"run", first.string(), "-o", (dir / "a").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto rest = pneuma::mesh::read_mesh(dir / "a/frames/frame_00000.ply");
  ASSERT_GT(rest.vertices.size(), 100u);
  const std::size_t vertex = rest.vertices.size() / 3;
  NrrdField dvf = read_nrrd_dvf(dir / "a/voxels/dvf-forward-end_inspiration.nrrd");
  // The voxel nearest the lung's vertex mean (inside the phantom's convex lung).
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& v : rest.vertices) mean += v * 1e3;
  mean /= static_cast<double>(rest.vertices.size());
  const Eigen::Vector3d ijk = dvf.directions.inverse() * (mean - dvf.origin);
  const std::array<std::size_t, 3> voxel{static_cast<std::size_t>(std::lround(ijk.x())),
                                         static_cast<std::size_t>(std::lround(ijk.y())),
                                         static_cast<std::size_t>(std::lround(ijk.z()))};
  const Eigen::Vector3d centre =
      dvf.origin + dvf.directions * Eigen::Vector3d(static_cast<double>(voxel[0]), static_cast<double>(voxel[1]),
                                                    static_cast<double>(voxel[2]));
  const Eigen::Vector3d vertex_mm = rest.vertices[vertex] * 1e3;
  const fs::path csv = dir.write(
      "points.csv", fmt::format("name,x_mm,y_mm,z_mm\nvertex,{:.7f},{:.7f},{:.7f}\ninside,{:.7f},{:.7f},{:.7f}\n"
                                "far,{:.3f},{:.3f},{:.3f}\n",
                                vertex_mm.x(), vertex_mm.y(), vertex_mm.z(), centre.x(), centre.y(), centre.z(),
                                mean.x(), mean.y(), mean.z() - 400.0));
  const fs::path second = dir.write("second.yaml", std::string(kPhantom) + outputs + ", points: points.csv}\n");
  r = run_pneuma({"run", second.string(), "-o", (dir / "b").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto rows = read_csv(dir / "b/voxels/trajectories.csv");
  ASSERT_FALSE(rows.empty());
  EXPECT_EQ(rows[0],
            (std::vector<std::string>{"point", "moves_with", "frame", "time_s", "bin", "x_mm", "y_mm", "z_mm"}));
  const auto voxels_csv = read_csv(dir / "b/voxels/voxels.csv");
  ASSERT_EQ(voxels_csv.size(), 2u);
  const std::string end_inspiration = voxels_csv[1][1];  // its frame
  dvf = read_nrrd_dvf(dir / "b/voxels/dvf-forward-end_inspiration.nrrd");
  const std::size_t index = voxel[0] + dvf.size[0] * (voxel[1] + dvf.size[1] * voxel[2]);
  const Eigen::Vector3d u(dvf.values[3 * index], dvf.values[3 * index + 1], dvf.values[3 * index + 2]);
  EXPECT_GT(u.norm(), 1.0);  // the lung moves there (mm)
  const double half_voxel = 0.5 * dvf.directions.col(0).norm();
  double worst_surface = 0.0;
  std::size_t frames = 0;
  for (std::size_t r2 = 1; r2 < rows.size(); ++r2) {
    const auto& row = rows[r2];
    ASSERT_EQ(row.size(), 8u);
    const Eigen::Vector3d x(std::stod(row[5]), std::stod(row[6]), std::stod(row[7]));
    if (row[0] == "vertex") {
      EXPECT_EQ(row[1], "right surface");
      if (row[2].empty()) continue;
      const auto frame = pneuma::mesh::read_mesh(dir / "b/frames" / fmt::format("frame_{:05}.ply", std::stoul(row[2])));
      worst_surface = std::max(worst_surface, (x - frame.vertices[vertex] * 1e3).norm());
      ++frames;
    } else if (row[0] == "inside") {
      EXPECT_EQ(row[1], "right interior");
      if (row[2] == end_inspiration) {
        EXPECT_LE((x - (centre + u)).norm(), half_voxel) << x.transpose() << " against " << (centre + u).transpose();
        std::printf("inside fiducial at end-inspiration: %.6f mm from the forward DVF's voxel (moved %.2f mm)\n",
                    (x - (centre + u)).norm(), u.norm());
      }
    } else {
      EXPECT_EQ(row[1], "body");
    }
  }
  EXPECT_EQ(frames, 41u);
  EXPECT_LE(worst_surface, 0.1);
  std::printf("surface fiducial: at most %.2e mm from its vertex over %zu frames\n", worst_surface, frames);
}

// A synthetic ball in the lung (its own 1.5 mm grid): each phase bin's warped target lies in the
// ITV, and the ITV is their union voxel for voxel; structures.csv's volumes are the files' counts.
TEST(Tracking, TheItvOfASphericalTargetIsTheUnionOfItsPhases) {
  TempDir dir;
  // The lung's vertex mean, from a first run's rest surface.
  const fs::path first =
      dir.write("first.yaml", std::string(kPhantom) + "  mesh_sequence: {format: ply, every: 100}\n");
  CommandResult r = run_pneuma({"run", first.string(), "-o", (dir / "a").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto rest = pneuma::mesh::read_mesh(dir / "a/frames/frame_00000.ply");
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& v : rest.vertices) mean += v;
  mean /= static_cast<double>(rest.vertices.size());
  pneuma::test::write_ball_mask(dir / "ball.nii.gz", mean);
  const fs::path second =
      dir.write("second.yaml", std::string(kPhantom) +
                                   "  voxels: {at: [phases], spacing: 3 mm, jacobian: false, structures: {gtv: "
                                   "ball.nii.gz}}\n");
  r = run_pneuma({"run", second.string(), "-o", (dir / "b").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const pneuma::image::LabelMap itv = pneuma::image::read_label_map(dir / "b/voxels/itv-gtv.nii.gz");
  std::vector<std::int32_t> unite(itv.labels.size(), 0);
  const auto rows = read_csv(dir / "b/voxels/structures.csv");
  ASSERT_EQ(rows.size(), 11u);  // the header and ten bins
  std::set<std::vector<std::int32_t>> distinct;
  for (int b = 0; b < 10; ++b) {
    const pneuma::image::LabelMap phase =
        pneuma::image::read_label_map(dir / "b/voxels" / fmt::format("structure-gtv-bin_{:02}.nii.gz", b));
    ASSERT_EQ(phase.size, itv.size);
    std::size_t outside = 0, count = 0;
    for (std::size_t v = 0; v < phase.labels.size(); ++v) {
      outside += phase.labels[v] != 0 && itv.labels[v] == 0;
      count += phase.labels[v] != 0;
      unite[v] |= phase.labels[v];
    }
    EXPECT_EQ(outside, 0u) << "bin " << b;
    EXPECT_GT(count, 0u) << "bin " << b;
    distinct.insert(phase.labels);
    EXPECT_EQ(rows[static_cast<std::size_t>(b) + 1][1], fmt::format("bin_{:02}", b));
    EXPECT_NEAR(std::stod(rows[static_cast<std::size_t>(b) + 1][2]),
                static_cast<double>(count) * itv.voxel_volume_m3() * 1e6, 1e-3);
  }
  EXPECT_GT(distinct.size(), 3u);  // the target moves between phases
  EXPECT_EQ(unite, itv.labels);
  std::size_t itv_count = 0;
  for (const auto v : itv.labels) itv_count += v != 0;
  const auto summary = read_csv(dir / "b/voxels/structures-summary.csv");
  ASSERT_EQ(summary.size(), 2u);
  EXPECT_NEAR(std::stod(summary[1][1]), static_cast<double>(itv_count) * itv.voxel_volume_m3() * 1e6, 1e-3);
  EXPECT_TRUE(summary[1][2].starts_with("bin_")) << summary[1][2];
  std::printf("ITV %s mL, mid-ventilation %s\n", summary[1][1].c_str(), summary[1][2].c_str());
}

TEST(Tracking, ABadFiducialsFileIsOneLineNamingItsLine) {
  TempDir dir;
  dir.write("points.csv", "name,x_mm,y_mm,z_mm\na,1,2,3\nb,1,two,3\n");
  const fs::path s = dir.write("s.yaml", std::string(kPhantom) + "  voxels: {points: points.csv}\n");
  const CommandResult r = run_pneuma({"run", s.string(), "-o", (dir / "out").string(), "--quiet"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("points.csv:3: 'two' in column 3; expected a coordinate in mm (within 10 m)"), std::string::npos)
      << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out"));
}

}  // namespace

namespace {

// The shipped example (scenarios/4d-slicer.yaml, coarser surfaces here): ten phases as Slicer
// sequences of ten items each, the NRRD DVFs as Slicer's displacement fields, every fiducial at
// every frame and phase, and the target's ITV holding each phase's target. Its inputs are the
// script's: scripts/make-4d-slicer-inputs.py writes the same bytes.
TEST(Tracking, TheShippedSlicerExampleWritesSequencesTrajectoriesAndTheItv) {
  const auto data = pneuma::test::ct_lobes_dir() / "case004_lobes.nii.gz";
  if (!fs::exists(data)) GTEST_SKIP() << "no CT lobe maps at " << data.parent_path();
  TempDir dir;
  const fs::path scenarios = fs::path(PNEUMA_SOURCE_DIR) / "scenarios";
  const fs::path python = "/usr/bin/python3";
  if (fs::exists(python) && pneuma::test::run_program(python, {"-c", "import nibabel"}).exit_code == 0) {
    const CommandResult made =
        pneuma::test::run_program(python, {(fs::path(PNEUMA_SOURCE_DIR) / "scripts/make-4d-slicer-inputs.py").string(),
                                           data.string(), dir.path().string()});
    ASSERT_EQ(made.exit_code, 0) << made.err;
    for (const char* name : {"4d-slicer-target.nii.gz", "4d-slicer-fiducials.csv"})
      EXPECT_EQ(pneuma::test::read_text(dir / name), pneuma::test::read_text(scenarios / name)) << name;
  }
  const CommandResult r = run_pneuma(
      {"run", (scenarios / "4d-slicer.yaml").string(), "-o", (dir / "out").string(), "--quiet", "--edge", "8mm"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const fs::path voxels = dir / "out/voxels";
  for (const char* kind : {"labels", "jacobian", "dvf-pullback", "dvf-forward"}) {
    std::ifstream in(voxels / (std::string(kind) + ".seq.nrrd"), std::ios::binary);
    std::map<std::string, std::string> fields;
    for (std::string line; std::getline(in, line) && !line.empty();) {
      const std::size_t kv = line.find(":=");
      if (kv != std::string::npos) fields[line.substr(0, kv)] = line.substr(kv + 2);
    }
    EXPECT_EQ(fields["axis 3 index values"], "0 10 20 30 40 50 60 70 80 90") << kind;
    EXPECT_TRUE(fs::exists(voxels / (std::string(kind) + "-4d.nii.gz"))) << kind;
  }
  const auto trajectories = read_csv(voxels / "trajectories.csv");
  EXPECT_EQ(trajectories.size(), 1u + 4u * (241u + 10u));  // 4 points; 24 s at 10 Hz: 241 frames, and 10 bins
  std::set<std::string> moves;
  for (std::size_t i = 1; i < trajectories.size(); ++i) moves.insert(trajectories[i][0] + " " + trajectories[i][1]);
  EXPECT_EQ(moves, (std::set<std::string>{"abdomen body", "left_lower_lobe left interior",
                                          "right_lung_lowest_voxel body", "target_centre right interior"}));
  const pneuma::image::LabelMap itv = pneuma::image::read_label_map(voxels / "itv-target.nrrd");
  for (int b = 0; b < 10; ++b) {
    const auto phase = pneuma::image::read_label_map(voxels / fmt::format("structure-target-bin_{:02}.nrrd", b));
    std::size_t outside = 0;
    for (std::size_t v = 0; v < phase.labels.size(); ++v) outside += phase.labels[v] != 0 && itv.labels[v] == 0;
    EXPECT_EQ(outside, 0u) << b;
  }
  const auto summary = read_csv(voxels / "structures-summary.csv");
  ASSERT_EQ(summary.size(), 2u);
  std::printf("4d-slicer: ITV %s mL, mid-ventilation %s at (%s, %s, %s) mm\n", summary[1][1].c_str(),
              summary[1][2].c_str(), summary[1][3].c_str(), summary[1][4].c_str(), summary[1][5].c_str());
}

}  // namespace
