// `pneuma run` end to end: exported frames measured independently against the physiology.
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <hdf5.h>
#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <iostream>

#include <nlohmann/json.hpp>

#include "pneuma/field/tissue.h"
#include "pneuma/mesh/anatomy/regions.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "pneuma/mesh/labels/labels.h"
#include "pneuma/model/compile.h"
#include "pneuma/physiology/simulate.h"
#include "pneuma/runner/output_registry.h"
#include "pneuma/runner/runner.h"
#include "pneuma/scenario/scenario.h"
#include "runner_fixture.h"
#include "test_support.h"

using pneuma::test::file_volume;
using pneuma::test::run_pneuma;
using pneuma::test::TempDir;

namespace {

// A short, coarse scenario: 4 s of quiet breathing at 10 frames/s on a 12 mm phantom.
constexpr const char* kSmall = R"(name: small
duration: 4 s
frames: {rate: 10 Hz}
mesh: {phantom: right, edge: 12 mm, share: 55 %}
field: {tissue: healthy-upright}
physiology:
  preset: healthy-adult
  driver: {mode: spontaneous, rate: 15 /min, ie_ratio: 1:2, tidal_volume: 500 mL}
outputs:
  mesh_sequence: {format: ply}
  hdf5: {positions: float64}
)";

// The paper's reading: a linear apex-to-base gradient, uniform load, vertex normals.
constexpr const char* kPaperUpright = R"(name: paper-upright
posture: upright
stiffness: {model: gradient, profile: linear, nondependent: 2.4 kPa, dependent: 0.6 kPa}
)";

std::filesystem::path frame_file(const std::filesystem::path& dir, std::size_t k) {
  char name[32];
  std::snprintf(name, sizeof name, "frame_%05zu.ply", k);
  return dir / name;
}

}  // namespace

TEST(Runner, ExportedFrameVolumesFollowTheSimulatedVolumeTimesTheShare) {
  TempDir dir;
  const auto scenario = dir.write("small.yaml", kSmall);
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;

  // The physiology again, independently of the runner, at the frame times.
  const auto s = pneuma::runner::load_scenario(scenario);
  auto options = s.physiology.options;
  options.output_rate_hz = 10.0;
  const auto phys = pneuma::physiology::simulate(s.physiology.protocol, options);
  ASSERT_EQ(phys.series.size(), 41u);
  const double rest = file_volume(dir / "out/frames/frame_00000.ply");  // V(0) = 0: the rest mesh
  EXPECT_EQ(phys.series.volume_m3[0], 0.0);
  double largest = 0.0;
  for (std::size_t k = 0; k < phys.series.size(); ++k) {
    const double expected_change = 0.55 * phys.series.volume_m3[k];
    const double measured_change = file_volume(frame_file(dir / "out/frames", k)) - rest;
    largest = std::max(largest, expected_change);
    // 0.1 % of the breath, plus the float32 rounding of the PLY coordinates.
    EXPECT_NEAR(measured_change, expected_change, 1e-3 * 0.55 * 0.5e-3 + 1e-7 * rest) << "frame " << k;
  }
  EXPECT_GT(largest, 0.2e-3);  // a real breath happened
  for (const char* f : {"manifest.json", "breathing.glb", "series.h5", "series.xdmf", "physiology.csv",
                        "physiology-breaths.csv", "field.h5"}) {
    EXPECT_TRUE(std::filesystem::exists(dir / "out" / f)) << f;
  }
}

TEST(Runner, GltfKeyframeEqualsTheExportedMeshAtTheSameTime) {
  TempDir dir;
  const auto scenario = dir.write("small.yaml", kSmall);
  ASSERT_EQ(run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"}).exit_code, 0);
  tinygltf::Model m;
  tinygltf::TinyGLTF loader;
  std::string error, warning;
  ASSERT_TRUE(loader.LoadBinaryFromFile(&m, &error, &warning, (dir / "out/breathing.glb").string())) << error;
  const auto& primitive = m.meshes.at(0).primitives.at(0);
  auto floats = [&](int accessor) {
    const auto& a = m.accessors.at(static_cast<std::size_t>(accessor));
    const auto& v = m.bufferViews.at(static_cast<std::size_t>(a.bufferView));
    return reinterpret_cast<const float*>(m.buffers[0].data.data() + v.byteOffset + a.byteOffset);
  };
  const float* rest = floats(primitive.attributes.at("POSITION"));
  const float* delta = floats(primitive.targets.at(0).at("POSITION"));
  const float* weights = floats(m.animations.at(0).samplers.at(0).output);
  const pneuma::mesh::ReadOptions o;  // the unit each frame records (mm)
  for (std::size_t k : {5u, 17u, 33u}) {
    const auto frame = pneuma::mesh::read_mesh(frame_file(dir / "out/frames", k), o);
    ASSERT_EQ(frame.vertex_count(),
              m.accessors.at(static_cast<std::size_t>(primitive.attributes.at("POSITION"))).count);
    for (std::size_t i = 0; i < frame.vertex_count(); i += 11) {
      for (int c = 0; c < 3; ++c) {
        const std::size_t j = 3 * i + static_cast<std::size_t>(c);
        EXPECT_NEAR(rest[j] + weights[k] * delta[j], frame.vertices[i][c], 2e-6) << "frame " << k << " vertex " << i;
      }
    }
  }
}

TEST(Runner, ShippedScenariosRunAtASmallResolution) {
  for (const char* name :
       {"quiet-breathing", "ventilated-patient", "ventilator-vc-ac", "ventilator-pc-ac", "ventilator-cpap-psv"}) {
    TempDir dir;
    const auto scenario = pneuma::test::source_dir() / "scenarios" / (std::string(name) + ".yaml");
    const auto r = run_pneuma({"run", scenario.string(), "-o", dir.path().string(), "--edge", "15mm", "--quiet"});
    ASSERT_EQ(r.exit_code, 0) << name << ": " << r.err;
    EXPECT_TRUE(std::filesystem::exists(dir / "manifest.json")) << name;
  }
}

TEST(Runner, ASecondRunReusesTheCachedField) {
  TempDir dir;
  const auto scenario = dir.write("small.yaml", kSmall);
  const auto first = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string()});
  ASSERT_EQ(first.exit_code, 0) << first.err;
  EXPECT_NE(first.out.find("field computed"), std::string::npos) << first.out;
  const std::string glb = pneuma::test::read_text(dir / "out/breathing.glb");
  const std::string h5 = pneuma::test::read_text(dir / "out/series.h5");
  const auto second = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string()});
  ASSERT_EQ(second.exit_code, 0) << second.err;
  EXPECT_NE(second.out.find("field reused from cache"), std::string::npos) << second.out;
  // Deterministic: the same inputs give the same bytes, whether the field was cached or not.
  EXPECT_TRUE(pneuma::test::read_text(dir / "out/breathing.glb") == glb);
  EXPECT_TRUE(pneuma::test::read_text(dir / "out/series.h5") == h5);
}

// A file mesh is looked up in the cache by its bytes and the options that shape it (unit, repair,
// remeshing target, tissue), before it is repaired and remeshed: the same inputs reuse the field;
// another target edge, or another file, computes it again.
TEST(Runner, AFileMeshIsLookedUpByItsBytesAndOptions) {
  TempDir dir;
  ASSERT_EQ(run_pneuma({"phantom", "--lung", "left", "--edge", "10mm", "-o", (dir / "lung.ply").string()}).exit_code,
            0);
  const std::string small(kSmall);
  const std::string phantom_line = "mesh: {phantom: right, edge: 12 mm, share: 55 %}";
  auto with_mesh = [&](const std::string& mesh) {
    return std::string(small).replace(small.find(phantom_line), phantom_line.size(), mesh);
  };
  const auto at_14 = dir.write("a.yaml", with_mesh("mesh: {file: lung.ply, unit: mm, edge: 14 mm, share: 45 %}"));
  const auto at_16 = dir.write("b.yaml", with_mesh("mesh: {file: lung.ply, unit: mm, edge: 16 mm, share: 45 %}"));
  auto run = [&](const std::filesystem::path& scenario) {
    const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string()});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return r.out.find("field reused from cache") != std::string::npos;
  };
  EXPECT_FALSE(run(at_14));
  const std::string first = pneuma::test::read_text(dir / "out/series.h5");
  EXPECT_TRUE(run(at_14));
  EXPECT_TRUE(pneuma::test::read_text(dir / "out/series.h5") == first) << "a cached field gives the same bytes";
  EXPECT_FALSE(run(at_16)) << "another remeshing target";
  ASSERT_EQ(run_pneuma({"phantom", "--lung", "left", "--edge", "11mm", "-o", (dir / "lung.ply").string()}).exit_code,
            0);
  EXPECT_FALSE(run(at_16)) << "another file";
}

struct BadRun {
  const char* name;
  const char* yaml;
  const char* message;  // after "<file>:"
  int exit_code;
};

class RunBadScenario : public ::testing::TestWithParam<BadRun> {};

TEST_P(RunBadScenario, OneLineAndNoOutput) {
  TempDir dir;
  const auto file = dir.write("s.yaml", GetParam().yaml);
  const auto r = run_pneuma({"run", file.string(), "-o", (dir / "out").string(), "--quiet"});
  EXPECT_EQ(r.exit_code, GetParam().exit_code);
  std::string message = GetParam().message;
  if (auto at = message.find("{dir}"); at != std::string::npos) message.replace(at, 5, dir.path().string());
  EXPECT_EQ(r.err, file.string() + ":" + message + "\n");
  EXPECT_FALSE(std::filesystem::exists(dir / "out")) << "no output folder for a scenario refused up front";
}

INSTANTIATE_TEST_SUITE_P(
    Cases, RunBadScenario,
    ::testing::Values(
        BadRun{"wrong_unit", "duration: 4 s\nframes: {rate: 30 mL}\nphysiology: {preset: healthy-adult}\n",
               "2:16: frames.rate: expected a rate such as '12 /min', got '30 mL'", 3},
        BadRun{
            "unknown_key", "duration: 4 s\nmesh: {phantom: right, egde: 4 mm}\nphysiology: {preset: healthy-adult}\n",
            "2:24: mesh.egde: unknown key; expected one of: breath, edge, file, labels, lungs, phantom, reference_volume, share",
            3},
        BadRun{"missing_mesh", "duration: 4 s\nmesh: {file: lungs.stl}\nphysiology: {preset: healthy-adult}\n",
               "2:14: mesh.file: no such file: {dir}/lungs.stl", 3},
        BadRun{"negative_duration", "duration: -4 s\nphysiology: {preset: healthy-adult}\n",
               "1:11: duration: expected a positive duration, got '-4 s'", 3},
        BadRun{"missing_label_map",
               "duration: 4 s\nmesh: {labels: lungs.nii.gz, values: [3]}\nphysiology: {preset: healthy-adult}\n",
               "2:16: mesh.labels: no such file: {dir}/lungs.nii.gz", 3},
        BadRun{"label_value_out_of_range",  // (a word is a segment name: tests/runner/segment_names_test.cpp)
               "duration: 4 s\nmesh: {labels: s.yaml, values: [3, 0]}\nphysiology: {preset: healthy-adult}\n",
               "2:36: mesh.values[1]: expected a whole number from 1 to 1000000, got '0'", 3},
        BadRun{
            "two_mesh_sources",
            "duration: 4 s\nmesh: {phantom: right, labels: s.yaml, values: [3]}\nphysiology: {preset: healthy-adult}\n",
            "2:32: mesh.labels: give one of phantom, file or labels", 3},
        BadRun{"unknown_gl_backend",
               "duration: 4 s\nphysiology: {preset: healthy-adult}\noutputs: {png: {gl: vulkan}}\n",
               "3:21: outputs.png.gl: expected one of: auto, egl, osmesa; got 'vulkan'", 3},
        BadRun{"clique_without_solver", "duration: 4 s\nfield: {clique: 2}\nphysiology: {preset: healthy-adult}\n",
               "2:17: field.clique: the cg solver (the default) takes clique 1 only; add 'solver: shot' (or sweep, "
               "direct) for a clique of 2 hops",
               3},
        BadRun{"clique_too_large",
               "duration: 4 s\nfield: {solver: shot, clique: 5}\nphysiology: {preset: healthy-adult}\n",
               "2:31: field.clique: expected a clique size from 1 to 4 hops, got '5'", 3}),
    [](const auto& test_case) { return std::string(test_case.param.name); });

TEST(Runner, AreaGrowsByOneAreaUnitPerUnitScaleAtFirstOrder) {
  // The field is normalised so that dA/ds = 1 cm^2 at s = 0: the per-frame CGAL area in the
  // HDF5 series must follow A(0) + s * 1e-4 m^2 up to the (small, positive) second-order term.
  // With the paper's direction (vertex normals; the anatomical direction of the healthy
  // presets is normalised the same way, tests/field/realism_test.cpp, but stretches more at
  // second order, where the diaphragm pulls away from the ribs).
  TempDir dir;
  std::string yaml = kSmall;
  yaml.replace(yaml.find("tissue: healthy-upright"), 23, "tissue: paper-upright.yaml");
  dir.write("paper-upright.yaml", kPaperUpright);
  const auto scenario = dir.write("small.yaml", yaml);
  ASSERT_EQ(run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"}).exit_code, 0);
  const hid_t file = H5Fopen((dir / "out/series.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  auto read = [&](const char* name) {
    std::vector<double> v(41);
    const hid_t set = H5Dopen2(file, name, H5P_DEFAULT);
    H5Dread(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
    H5Dclose(set);
    return v;
  };
  const auto area = read("/frames/area_m2"), scale = read("/frames/scale");
  H5Fclose(file);
  int checked = 0;
  for (std::size_t k = 1; k < area.size(); ++k) {
    if (scale[k] < 1.0) continue;
    const double ratio = (area[k] - area[0]) / (scale[k] * 1e-4);
    EXPECT_GT(ratio, 0.97) << "frame " << k << ", s = " << scale[k];
    EXPECT_LT(ratio, 1.05) << "frame " << k << ", s = " << scale[k];
    ++checked;
  }
  EXPECT_GT(checked, 10);
}

// The area in series.h5 against the oracle of the file's own float64 frame: the sum of its
// triangles' areas (Heron-free: half the cross product's length), summed here. A run of 300
// frames takes its areas from a table (within 1e-12 of the sum); one of 40 frames sums each
// frame exactly (model::Frame's ranges are given from 256 frames on).
TEST(Runner, SeriesAreaIsTheSumOfTheFramesTrianglesWithOrWithoutATable) {
  TempDir dir;
  for (const int seconds : {30, 4}) {
    std::string yaml = kSmall;
    yaml.replace(yaml.find("duration: 4 s"), 13, fmt::format("duration: {} s", seconds));
    yaml.replace(yaml.find("  mesh_sequence: {format: ply}\n"), 31, "");
    const auto out = dir / fmt::format("out{}", seconds);
    ASSERT_EQ(run_pneuma({"run", dir.write("s.yaml", yaml).string(), "-o", out.string(), "--quiet"}).exit_code, 0);
    const hid_t file = H5Fopen((out / "series.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    const auto read = [&](const std::string& name, std::size_t count, hid_t type, void* data) {
      const hid_t set = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
      ASSERT_GE(set, 0) << name;
      const hid_t space = H5Dget_space(set);
      EXPECT_EQ(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space)), count) << name;
      H5Sclose(space);
      EXPECT_GE(H5Dread(set, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), 0) << name;
      H5Dclose(set);
    };
    const std::size_t frames = static_cast<std::size_t>(seconds) * 10 + 1;
    std::vector<double> area(frames);
    read("/frames/area_m2", frames, H5T_NATIVE_DOUBLE, area.data());
    const hid_t tri_set = H5Dopen2(file, "/rest/triangles", H5P_DEFAULT);
    const hid_t tri_space = H5Dget_space(tri_set);
    const auto triangle_count = static_cast<std::size_t>(H5Sget_simple_extent_npoints(tri_space)) / 3;
    H5Sclose(tri_space);
    H5Dclose(tri_set);
    std::vector<std::uint32_t> triangles(3 * triangle_count);
    read("/rest/triangles", triangles.size(), H5T_NATIVE_UINT32, triangles.data());
    const std::size_t vertices = (triangle_count + 4) / 2;  // a closed genus-0 surface: V = F / 2 + 2
    double worst = 0.0;
    for (std::size_t k = 0; k < frames; k += 7) {
      std::vector<double> p(3 * vertices);
      read(fmt::format("/frames/positions/{:06}", k), p.size(), H5T_NATIVE_DOUBLE, p.data());
      double sum = 0.0;
      const auto corner = [&](std::size_t t, std::size_t j) {
        return Eigen::Vector3d(&p[3 * std::size_t{triangles[3 * t + j]}]);
      };
      for (std::size_t t = 0; t < triangle_count; ++t) {
        const Eigen::Vector3d a = corner(t, 0), b = corner(t, 1), c = corner(t, 2);
        sum += 0.5 * (b - a).cross(c - a).norm();
      }
      worst = std::max(worst, std::abs(area[k] - sum) / sum);
    }
    H5Fclose(file);
    std::cout << frames << " frames: largest relative difference " << worst << "\n";
    EXPECT_LT(worst, 1e-12) << seconds << " s";
  }
}

// field.h5 and series.h5 of one run call the same data by the same names, describe themselves
// (root attributes, `units` on every dataset) and hold the same values: read with h5py.
TEST(Runner, FieldAndSeriesFilesShareNamesAttributesAndValues) {
  if (std::system("/usr/bin/python3 -c 'import h5py' >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "h5py is not importable by /usr/bin/python3 (scripts/install-deps installs python3-h5py)";
  TempDir dir;
  const auto scenario = dir.write("small.yaml", kSmall);
  ASSERT_EQ(run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"}).exit_code, 0);
  const auto script = dir.write("check.py", R"(import sys, h5py, numpy as np
f = h5py.File(sys.argv[1] + "/field.h5", "r")
s = h5py.File(sys.argv[1] + "/series.h5", "r")
for h, fmt in ((f, "pneuma-field"), (s, "pneuma-series")):
    a = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in h.attrs.items()}
    assert a["format"] == fmt and a["coordinate_frame"] == "LPS" and a["length_unit"] == "m", a
    assert a["generator"].startswith("pneuma "), a
    def units(name, obj):
        if isinstance(obj, h5py.Dataset):
            assert "units" in obj.attrs, (fmt, name)
    h.visititems(units)
for name in ("rest/positions", "rest/triangles", "field/unit_displacement"):
    assert np.array_equal(f[name][()], s[name][()]), name
    assert f[name].attrs["units"] == s[name].attrs["units"], name
assert f["field"].attrs["area_unit_m2"] == s["field"].attrs["area_unit_m2"] == 1e-4
print("ok", len(s["frames/positions"]), s["frames/positions/000040"].attrs["units"].decode())
)");
  const std::string out = (dir / "check.txt").string();
  const int status = std::system(
      ("/usr/bin/python3 " + script.string() + " " + (dir / "out").string() + " >" + out + " 2>&1").c_str());
  const std::string text = pneuma::test::read_text(out);
  ASSERT_EQ(status, 0) << text;
  EXPECT_EQ(text, "ok 41 m\n");
}

// `pneuma mesh info` on a frame of the sequence (written in millimetres, saying so) reports the
// lung at its real size without --unit; an explicit --unit still wins.
TEST(Runner, MeshInfoReadsTheUnitAFrameRecords) {
  TempDir dir;
  const auto scenario = dir.write("small.yaml", kSmall);
  ASSERT_EQ(run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"}).exit_code, 0);
  const std::string frame = frame_file(dir / "out/frames", 0).string();
  auto bounding_box = [](const std::string& out) {
    const auto at = out.find("bounding box:");
    return out.substr(at, out.find('\n', at) - at);
  };
  const auto recorded = run_pneuma({"mesh", "info", frame, "--no-self-intersections"});
  const auto forced_mm = run_pneuma({"mesh", "info", frame, "--no-self-intersections", "--unit", "mm"});
  const auto forced_m = run_pneuma({"mesh", "info", frame, "--no-self-intersections", "--unit", "m"});
  ASSERT_EQ(recorded.exit_code, 0) << recorded.err;
  EXPECT_EQ(bounding_box(recorded.out), bounding_box(forced_mm.out));
  EXPECT_NE(bounding_box(recorded.out), bounding_box(forced_m.out));
  // The oracle for the size: the frame read with an explicit unit of 1 mm.
  pneuma::mesh::ReadOptions m;
  m.metres_per_unit = 1e-3;
  m.unit_from_file = false;
  const auto mesh = pneuma::mesh::read_mesh(frame, m);
  double z_min = 1e9, z_max = -1e9;
  for (const auto& v : mesh.vertices) z_min = std::min(z_min, v.z()), z_max = std::max(z_max, v.z());
  EXPECT_NE(bounding_box(recorded.out).find(fmt::format("z {:.2f} to {:.2f} mm", z_min * 1e3, z_max * 1e3)),
            std::string::npos)
      << bounding_box(recorded.out);
}

// The run summary lists top-level files one by one and a folder of frames as one counted line.
TEST(Runner, SummaryCountsTheFilesOfEachFolder) {
  TempDir dir;
  const auto scenario = dir.write("small.yaml", kSmall);
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::size_t frames = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir / "out/frames")) frames += entry.is_regular_file();
  EXPECT_EQ(frames, 42u) << "41 frames and their index, frame.ply.series";
  EXPECT_NE(r.out.find("  " + (dir / "out/frames").string() + "/ 42 files\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("  " + (dir / "out/series.h5").string() + "\n"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("frame_00000"), std::string::npos) << r.out;
}

TEST(Runner, OriginalMeshIsExportedWithTheFieldOfItsRemeshedSurface) {
  // A file mesh (the phantom at 8 mm, in mm) remeshed to 14 mm for the field, exported at its
  // own resolution: frames keep the file's vertices and still follow the volume exactly.
  TempDir dir;
  ASSERT_EQ(run_pneuma({"phantom", "--lung", "left", "--edge", "8mm", "-o", (dir / "lung.ply").string()}).exit_code, 0);
  const std::string yaml =
      std::string(kSmall).replace(std::string(kSmall).find("mesh: {phantom: right, edge: 12 mm, share: 55 %}"),
                                  std::strlen("mesh: {phantom: right, edge: 12 mm, share: 55 %}"),
                                  "mesh: {file: lung.ply, unit: mm, edge: 14 mm, export: original, share: 45 %}");
  const auto scenario = dir.write("file.yaml", yaml);
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  pneuma::mesh::ReadOptions mm;
  const auto original = pneuma::mesh::read_mesh(dir / "lung.ply", mm);
  const auto frame = pneuma::mesh::read_mesh(frame_file(dir / "out/frames", 20));  // its recorded unit (mm)
  EXPECT_EQ(frame.vertex_count(), original.vertex_count());
  const auto s = pneuma::runner::load_scenario(scenario);
  auto options = s.physiology.options;
  options.output_rate_hz = 10.0;
  const auto phys = pneuma::physiology::simulate(s.physiology.protocol, options);
  const double change =
      file_volume(frame_file(dir / "out/frames", 20)) - file_volume(frame_file(dir / "out/frames", 0));
  EXPECT_NEAR(change, 0.45 * phys.series.volume_m3[20], 1e-3 * 0.45 * 0.5e-3 + 1e-7 * 1.3e-3);
}

// The regions are found once per run and handed from the field to the breathing model; on every
// path (no cache, a cache miss, a cache hit, a phantom and a file source, the original mesh
// exported) they must be those of the model's own rest surface in the tissue's axes.
TEST(Runner, TheModelsRegionsAreThoseOfItsRestSurfaceOnEveryPath) {
  TempDir dir;
  ASSERT_EQ(run_pneuma({"phantom", "--lung", "left", "--edge", "8mm", "-o", (dir / "lung.ply").string()}).exit_code, 0);
  const std::string small(kSmall);
  auto with = [&](const std::string& from, const std::string& to) {
    return std::string(small).replace(small.find(from), from.size(), to);
  };
  const std::string phantom = "mesh: {phantom: right, edge: 12 mm, share: 55 %}";
  const std::vector<std::pair<std::string, std::string>> scenarios{
      {"phantom, no cache", with("field: {tissue: healthy-upright}", "field: {tissue: healthy-upright, cache: off}")},
      {"phantom", small},
      {"file", with(phantom, "mesh: {file: lung.ply, unit: mm, edge: 14 mm, share: 45 %}")},
      {"file, original exported",
       with(phantom, "mesh: {file: lung.ply, unit: mm, edge: 14 mm, export: original, share: 45 %}")}};
  for (const auto& [name, yaml] : scenarios) {
    const auto s = pneuma::runner::load_scenario(dir.write("s.yaml", yaml));
    pneuma::mesh::RegionOptions axes;
    axes.axes = pneuma::field::body_axes(s.field.tissue);
    const auto out = dir / ("out-" + std::to_string(name.size()));
    for (const char* pass : {"first", "second"}) {
      SCOPED_TRACE(name + ", " + pass + " run");
      const auto drive = pneuma::scenario::simulate_physiology(s, s.frame_rate_hz);
      const auto compiled = pneuma::runner::prepare(s, drive, {.auto_cache_file = out / "field.h5"});
      const auto& model = compiled.model.lungs.front();
      EXPECT_EQ(compiled.model.report.field_reused, std::string(pass) == "second" && name != "phantom, no cache");
      const auto direct = pneuma::mesh::find_regions(model.rest, axes);
      EXPECT_EQ(model.regions.label, direct.label);
      EXPECT_EQ(model.regions.weight, direct.weight);
    }
  }
}

TEST(Runner, AVolumeBeyondWhatTheSurfaceCanTakeIsRefused) {
  // 4 L into one lung of ~1.3 L: refused before any frame is written, with what to change.
  // (The paper's direction: along the anatomical one the diaphragm can keep descending.)
  TempDir dir;
  std::string yaml = kSmall;
  yaml.replace(yaml.find("tissue: healthy-upright"), 23, "tissue: paper-upright.yaml");
  dir.write("paper-upright.yaml", kPaperUpright);
  yaml.replace(yaml.find("share: 55 %"), 11, "share: 100 %");
  yaml.replace(yaml.find("driver: {mode: spontaneous, rate: 15 /min, ie_ratio: 1:2, tidal_volume: 500 mL}"),
               std::strlen("driver: {mode: spontaneous, rate: 15 /min, ie_ratio: 1:2, tidal_volume: 500 mL}"),
               "driver: {mode: volume_control, rate: 15 /min, ie_ratio: 1:2, tidal_volume: 4 L}");
  const auto scenario = dir.write("big.yaml", yaml);
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
  EXPECT_EQ(r.exit_code, 5);
  EXPECT_NE(r.err.find("lower the tidal volume"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "out/frames")) << "no frame before the check";
  EXPECT_FALSE(std::filesystem::exists(dir / "out/field.h5")) << "the field cache is staged like every output";
}

TEST(Runner, CtrlCLeavesNoHalfWrittenFile) {
  // A long run (20 min of breathing on a 2 mm phantom: several seconds of frames) interrupted
  // while the HDF5 series is being written: that file must not appear, and no temporary may
  // be left behind. Whatever phase the signal hits, the same must hold.
  TempDir dir;
  std::string yaml = kSmall;
  yaml.replace(yaml.find("duration: 4 s"), 13, "duration: 1200 s");
  yaml.replace(yaml.find("edge: 12 mm"), 11, "edge: 2 mm");
  yaml.replace(yaml.find("mesh_sequence: {format: ply}"), 28, "mesh_sequence: false");
  const auto scenario = dir.write("long.yaml", yaml);
  const int status = pneuma::test::interrupt_pneuma({"run", scenario.string(), "-o", (dir / "out").string()}, 1500);
  EXPECT_EQ(status, 130);  // 128 + SIGINT, from the CLI's handler
  EXPECT_FALSE(std::filesystem::exists(dir / "out/series.h5"));
  for (const auto& name : dir.files()) EXPECT_EQ(name.find(".tmp-"), std::string::npos) << name;
}

// A whole `pneuma run` on each real CT label map, both lungs (labels 3+4+5 right, 1+2 left):
// the surface is extracted, repaired, remeshed to 4 mm and animated. Oracles: the rest volume
// against the voxel count of the labels (independent of the surface extraction), and the motion
// summary's anatomy (the diaphragm carries most of the volume change, the mediastinum barely
// moves, the apex moves less than the diaphragm).
class CtLobeRuns : public ::testing::TestWithParam<const char*> {};

TEST_P(CtLobeRuns, BothLungsBreathe) {
  const auto file = pneuma::test::ct_lobes_dir() / (std::string(GetParam()) + "_lobes.nii.gz");
  if (!std::filesystem::exists(file)) {
    GTEST_SKIP() << "no CT lobe maps at " << file.parent_path()
                 << " (set PNEUMA_CT_LOBES to the folder of case00N_lobes.nii.gz)";
  }
  const pneuma::image::LabelMap map = pneuma::image::read_label_map(file);
  struct Lung {
    const char* values;
    std::vector<int> labels;
    const char* share;
  };
  for (const Lung& lung : {Lung{"[3, 4, 5]", {3, 4, 5}, "55 %"}, Lung{"[1, 2]", {1, 2}, "45 %"}}) {
    TempDir dir;
    const auto scenario =
        dir.write("ct.yaml", std::string("duration: 5 s\nframes: {rate: 10 Hz}\n") + "mesh: {labels: " + file.string() +
                                 ", values: " + lung.values + ", edge: 4 mm, share: " + lung.share + "}\n" +
                                 "physiology: {preset: healthy-adult}\n"
                                 "outputs: {gltf: false, hdf5: false}\n");
    const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
    ASSERT_EQ(r.exit_code, 0) << GetParam() << " " << lung.values << ": " << r.err;
    std::size_t voxels = 0;
    for (std::int32_t label : map.labels) {
      voxels += std::find(lung.labels.begin(), lung.labels.end(), label) != lung.labels.end();
    }
    const auto manifest = nlohmann::json::parse(pneuma::test::read_text(dir / "out/manifest.json"));
    const auto& facts = manifest.at("facts");
    const double rest_volume = std::stod(facts.at("rest_volume_m3").get<std::string>());
    EXPECT_NEAR(rest_volume / (static_cast<double>(voxels) * map.voxel_volume_m3()), 1.0, 0.05) << lung.values;
    const double diaphragm_share = std::stod(facts.at("motion.diaphragmatic.volume_share_pct").get<std::string>());
    const double mediastinum = std::stod(facts.at("motion.mediastinal.magnitude_mean_mm").get<std::string>());
    const double apex = std::stod(facts.at("motion.apex.caudal_mean_mm").get<std::string>());
    const double diaphragm = std::stod(facts.at("motion.diaphragmatic.caudal_mean_mm").get<std::string>());
    EXPECT_GT(diaphragm_share, 50.0) << lung.values;
    EXPECT_LT(mediastinum, 1.0) << lung.values;
    EXPECT_LT(apex, diaphragm) << lung.values;
    std::cout << GetParam() << " " << lung.values << ": rest volume " << rest_volume * 1e3 << " L, diaphragm "
              << diaphragm << " mm (share " << diaphragm_share << " %), apex " << apex << " mm, mediastinum "
              << mediastinum << " mm\n";
  }
}

INSTANTIATE_TEST_SUITE_P(RealAnatomy, CtLobeRuns,
                         ::testing::Values("case004", "case005", "case006", "case007", "case008", "case009"));

// The ventilator's facts in manifest.json on a passive VC-AC run with a pause and an expiratory
// hold, against the closed forms of the RC lung (C = 0.05 L/cmH2O, R = 10 cmH2O*s/L, tau = 0.5 s):
// with r = e^(-Te/tau) kept of each breath's volume, breath n starts x_(n-1) = VT r (1 - r^(n-1)) /
// (1 - r) above the PEEP volume, its plateau is PEEP + (x_(n-1) + VT) / C and its peak adds R q.
TEST(Runner, ManifestSummarisesTheVentilatorAgainstTheClosedForms) {
  TempDir dir;
  const auto scenario = dir.write("vent.yaml", R"(name: vent
duration: 14 s
frames: {rate: 10 Hz}
mesh: {phantom: right, edge: 12 mm, share: 55 %}
field: {tissue: healthy-upright}
physiology:
  compliance: 0.05 L/cmH2O
  resistance: 10 cmH2O*s/L
  driver: {mode: vc_ac, rate: 15 /min, tidal_volume: 500 mL, inspiratory_time: 1.2 s, pause: 0.3 s, peep: 5 cmH2O}
  actions:
    - {at: 5 s, expiratory_hold: 1 s}
outputs: {gltf: false, hdf5: false}
)");
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto manifest = nlohmann::json::parse(pneuma::test::read_text(dir / "out/manifest.json"));
  const auto& facts = manifest.at("facts");
  const auto text = [&](const char* key) { return facts.at(key).get<std::string>(); };
  const auto value = [&](const char* key) { return std::stod(text(key)); };
  EXPECT_EQ(text("ventilator.settings[0].mode"), "vc_ac");
  EXPECT_EQ(text("ventilator.settings[0].rate_per_min"), "15");
  EXPECT_EQ(text("ventilator.settings[0].tidal_volume_mL"), "500");
  EXPECT_EQ(text("ventilator.settings[0].trigger"), "flow 2 L/min");
  EXPECT_EQ(text("ventilator.expiratory_holds"), "at 5 s for 1 s");
  // Breaths [0, 4], [4, 9] (held at 8 s for 1 s), [9, 13]: all on the backup timer.
  EXPECT_EQ(text("ventilator.breaths"), "3");
  EXPECT_EQ(text("ventilator.breaths.mandatory"), "3");
  EXPECT_EQ(text("ventilator.triggers.time"), "3");
  EXPECT_EQ(text("ventilator.triggers.patient_flow"), "0");
  EXPECT_EQ(text("ventilator.missed_triggers"), "0");
  const double cmh2o = 1.0, C = 0.05, R = 10.0, vt = 0.5, q = vt / 0.9, peep = 5 * cmh2o;
  const double ratio = std::exp(-2.8 / 0.5);
  const auto x = [&](int n) { return vt * ratio * (1 - std::pow(ratio, n)) / (1 - ratio); };  // litres
  double plateau_sum = 0.0;
  for (int n = 1; n <= 3; ++n) plateau_sum += peep + (x(n - 1) + vt) / C;
  const auto near = [](double actual, double expected) { return std::abs(actual - expected) <= 1e-5 * expected; };
  EXPECT_PRED2(near, value("ventilator.plateau_pressure_cmH2O.mean"), plateau_sum / 3);
  EXPECT_PRED2(near, value("ventilator.plateau_pressure_cmH2O.min"), peep + vt / C);
  EXPECT_PRED2(near, value("ventilator.plateau_pressure_cmH2O.max"), peep + (x(2) + vt) / C);
  EXPECT_PRED2(near, value("ventilator.peak_pressure_cmH2O.max"), peep + R * q + (x(2) + vt) / C);
  EXPECT_PRED2(near, value("ventilator.delivered_tidal_volume_mL.mean"), 500.0);
  EXPECT_PRED2(near, value("ventilator.intrinsic_peep_cmH2O.max"), x(3) / C);
  // The held breath: total PEEP = PEEP + x_2 / C, the only one.
  EXPECT_PRED2(near, value("ventilator.total_peep_cmH2O.mean"), peep + x(2) / C);
  EXPECT_EQ(text("ventilator.total_peep_cmH2O.min"), text("ventilator.total_peep_cmH2O.max"));
  // The CSV row of that breath carries the hold.
  const std::string breaths = pneuma::test::read_text(dir / "out/physiology-breaths.csv");
  EXPECT_NE(breaths.find(",mandatory,1,"), std::string::npos) << breaths;
}

TEST(Runner, ManifestHasNoVentilatorFactsForSpontaneousBreathing) {
  TempDir dir;
  const auto scenario = dir.write("small.yaml", kSmall);
  ASSERT_EQ(run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"}).exit_code, 0);
  const auto manifest = nlohmann::json::parse(pneuma::test::read_text(dir / "out/manifest.json"));
  for (const auto& [key, value] : manifest.at("facts").items())
    EXPECT_EQ(key.rfind("ventilator.", 0), std::string::npos) << key;
}
