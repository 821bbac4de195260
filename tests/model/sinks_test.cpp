// Sinks checked by reading their files back with independent readers (tinygltf, HDF5, pugixml).
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <gtest/gtest-spi.h>
#include <gtest/gtest.h>
#include <hdf5.h>
#include <tiny_gltf.h>

#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fmt/format.h>
#include <optional>
#include <pugixml.hpp>
#include <tuple>

#include "pneuma/mesh/io/mesh_io.h"
#include "pneuma/outputs/frame_outputs.h"
#include "test_support.h"

using namespace pneuma;
using namespace pneuma::outputs;
using pneuma::model::advance;
using pneuma::model::Frame;
using pneuma::test::TempDir;

namespace {

model::Model sphere_model() {
  const auto rest = pneuma::mesh::make_icosphere(0.1, 2);
  std::vector<Eigen::Vector3d> u(rest.vertex_count());
  const auto n = pneuma::mesh::vertex_normals(rest);
  for (std::size_t i = 0; i < u.size(); ++i) u[i] = (1.0 + rest.vertices[i].z() * 5.0) * 1e-4 * n[i];
  return model::Model(model::make_model(rest, u, 1e-4));
}

// Drives a sink over a sinusoidal breath, as the runner does.
std::vector<double> drive(outputs::Output& sink, const model::Model& model, std::size_t frames, double rate) {
  std::vector<double> scales(frames);
  for (std::size_t k = 0; k < frames; ++k) scales[k] = 20.0 * std::sin(static_cast<double>(k) * 0.3) + 5.0;
  outputs::RunInfo run{frames,
                       rate,
                       {*std::min_element(scales.begin(), scales.end())},
                       {*std::max_element(scales.begin(), scales.end())},
                       {}};
  sink.begin(model, run);
  Frame f(model);
  for (std::size_t k = 0; k < frames; ++k) {
    const double lung_volume = model.lungs[0].volume_map.volume(scales[k]) - model.lungs[0].volume_map.volume(0.0);
    advance(model, {k, static_cast<double>(k) / rate, lung_volume, {scales[k]}}, f);
    sink.frame(model, f);
  }
  sink.finish(model, {});
  return scales;
}

const float* accessor_floats(const tinygltf::Model& m, int index) {
  const auto& a = m.accessors[static_cast<std::size_t>(index)];
  const auto& v = m.bufferViews[static_cast<std::size_t>(a.bufferView)];
  return reinterpret_cast<const float*>(m.buffers[0].data.data() + v.byteOffset + a.byteOffset);
}

std::vector<hsize_t> shape(hid_t file, const char* path) {
  const hid_t set = H5Dopen2(file, path, H5P_DEFAULT);
  const hid_t space = H5Dget_space(set);
  std::vector<hsize_t> dims(static_cast<std::size_t>(H5Sget_simple_extent_ndims(space)));
  H5Sget_simple_extent_dims(space, dims.data(), nullptr);
  H5Sclose(space);
  H5Dclose(set);
  return dims;
}

std::vector<hsize_t> parse_dims(const char* text) {
  std::vector<hsize_t> dims;
  std::istringstream in(text);
  for (hsize_t d; in >> d;) dims.push_back(d);
  return dims;
}

}  // namespace

TEST(GltfSink, StructureIsValidAndEachKeyframeEqualsTheDisplacedMesh) {
  TempDir dir;
  const model::Model model = sphere_model();
  auto sink = make_gltf_output(dir / "breathing.glb");
  const auto scales = drive(*sink, model, 40, 10.0);
  EXPECT_EQ(dir.files(), std::vector<std::string>{"breathing.glb"});

  tinygltf::Model m;
  tinygltf::TinyGLTF loader;
  std::string error, warning;
  ASSERT_TRUE(loader.LoadBinaryFromFile(&m, &error, &warning, (dir / "breathing.glb").string())) << error;
  ASSERT_EQ(m.meshes.size(), 1u);
  const auto& primitive = m.meshes[0].primitives[0];
  ASSERT_EQ(primitive.targets.size(), 1u);
  const int position = primitive.attributes.at("POSITION"), target = primitive.targets[0].at("POSITION");
  const std::size_t n = model.lungs[0].rest.vertex_count();
  EXPECT_EQ(m.accessors[static_cast<std::size_t>(position)].count, n);
  EXPECT_EQ(m.accessors[static_cast<std::size_t>(target)].count, n);
  EXPECT_EQ(m.accessors[static_cast<std::size_t>(primitive.indices)].count, model.lungs[0].rest.triangle_count() * 3);
  // Every view lies inside the buffer; accessors fit in their views.
  for (const auto& a : m.accessors) {
    const auto& v = m.bufferViews[static_cast<std::size_t>(a.bufferView)];
    EXPECT_LE(v.byteOffset + v.byteLength, m.buffers[0].data.size());
    const std::size_t width = a.type == TINYGLTF_TYPE_VEC4 ? 4 : a.type == TINYGLTF_TYPE_VEC3 ? 3 : 1;
    EXPECT_LE(a.byteOffset + a.count * 4 * width, v.byteLength);  // float32 and uint32 alike
  }
  // The regions travel as vertex attributes: one label and four weights (summing to 1) per vertex.
  const float* label = accessor_floats(m, primitive.attributes.at("_REGION"));
  const float* weight = accessor_floats(m, primitive.attributes.at("_REGION_WEIGHTS"));
  for (std::size_t i = 0; i < n; ++i) {
    ASSERT_EQ(label[i], static_cast<float>(model.lungs[0].regions.label[i])) << i;
    EXPECT_NEAR(weight[4 * i] + weight[4 * i + 1] + weight[4 * i + 2] + weight[4 * i + 3], 1.0, 1e-6) << i;
  }
  ASSERT_EQ(m.animations.size(), 1u);
  const auto& sampler = m.animations[0].samplers[0];
  EXPECT_EQ(m.animations[0].channels[0].target_path, "weights");
  EXPECT_EQ(sampler.interpolation, "LINEAR");
  // The animation's whole extent in the scene's extras (glTF has no frame range): 40 frames at
  // 10 Hz end at 3.9 s, the sampler's last key.
  ASSERT_EQ(m.scenes.size(), 1u);
  const auto& extras = m.scenes[0].extras;
  ASSERT_TRUE(extras.Has("animation_duration_s") && extras.Has("frame_rate_hz") && extras.Has("frame_count"));
  EXPECT_NEAR(extras.Get("animation_duration_s").GetNumberAsDouble(), 3.9, 1e-6);
  EXPECT_NEAR(extras.Get("animation_duration_s").GetNumberAsDouble(),
              m.accessors[static_cast<std::size_t>(sampler.input)].maxValues.at(0), 1e-12);
  EXPECT_EQ(extras.Get("frame_rate_hz").GetNumberAsDouble(), 10.0);
  EXPECT_EQ(extras.Get("frame_count").GetNumberAsInt(), 40);
  EXPECT_EQ(m.accessors[static_cast<std::size_t>(sampler.input)].count, scales.size());

  // The glTF frame at keyframe k: rest + w_k * target, against rest + s_k u in double.
  const float* rest = accessor_floats(m, position);
  const float* delta = accessor_floats(m, target);
  const float* times = accessor_floats(m, sampler.input);
  const float* weights = accessor_floats(m, sampler.output);
  for (std::size_t k = 0; k < scales.size(); k += 7) {
    EXPECT_FLOAT_EQ(times[k], static_cast<float>(static_cast<double>(k) / 10.0));
    for (std::size_t i = 0; i < n; i += 13) {
      for (int c = 0; c < 3; ++c) {
        const double expected = model.lungs[0].rest.vertices[i][c] + scales[k] * model.lungs[0].unit_displacement[i][c];
        EXPECT_NEAR(rest[3 * i + static_cast<std::size_t>(c)] + weights[k] * delta[3 * i + static_cast<std::size_t>(c)],
                    expected, 1e-6);
      }
    }
  }
}

namespace {

// Sets (or with nullptr unsets) an environment variable for one scope, then restores it.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    set(value);
  }
  ~ScopedEnv() { set(old_ ? old_->c_str() : nullptr); }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  void set(const char* value) const {
    if (value) {
      setenv(name_, value, 1);
    } else {
      unsetenv(name_);
    }
  }
  const char* name_;
  std::optional<std::string> old_;
};

void require_a_missing_client() { PNEUMA_REQUIRE_CLIENT(std::filesystem::path(), "no-such-client"); }

}  // namespace

// The client tests below (Blender, ParaView) skip a missing client outside CI only: in CI it is a
// failure unless PNEUMA_ALLOW_MISSING_CLIENTS=1. The oracle is that rule, case by case.
TEST(ClientTests, AMissingClientFailsInCiUnlessAllowed) {
  const ScopedEnv no_allow("PNEUMA_ALLOW_MISSING_CLIENTS", nullptr);
  for (const auto& [ci, may_skip] : {std::pair<const char*, bool>{nullptr, true},
                                     {"", true},
                                     {"0", true},
                                     {"false", true},
                                     {"true", false},
                                     {"1", false}}) {
    const ScopedEnv env("CI", ci);
    EXPECT_EQ(pneuma::test::missing_client_may_skip(), may_skip) << "CI=" << (ci ? ci : "(unset)");
  }
  const ScopedEnv ci("CI", "true");
  EXPECT_FATAL_FAILURE(require_a_missing_client(), "no-such-client not found, and CI requires it");
  const ScopedEnv allow("PNEUMA_ALLOW_MISSING_CLIENTS", "1");
  EXPECT_TRUE(pneuma::test::missing_client_may_skip());
}

// Blender (Debian's, from scripts/install-deps; a missing one fails in CI) opens the glb with
// scripts/blender-open.py: the timeline is the whole animation at the run's rate, and the shape
// key's value at Blender frame k is the glb's morph weight k, read by tinygltf (negative weights,
// a breath below the rest shape, included).
TEST(GltfSink, BlenderOpensTheWholeAnimationWithBlenderOpenWhenInstalled) {
  const auto program = pneuma::test::find_program({"blender"});
  PNEUMA_REQUIRE_CLIENT(program, "blender (Debian: apt-get install blender)");
  TempDir dir;
  const model::Model model = sphere_model();
  auto sink = make_gltf_output(dir / "breathing.glb");
  const auto scales = drive(*sink, model, 40, 10.0);
  tinygltf::Model m;
  tinygltf::TinyGLTF loader;
  std::string error, warning;
  ASSERT_TRUE(loader.LoadBinaryFromFile(&m, &error, &warning, (dir / "breathing.glb").string())) << error;
  const float* weights = accessor_floats(m, m.animations[0].samplers[0].output);

  const auto check = dir.write("check.py", R"(import bpy
s = bpy.context.scene
key = [o for o in bpy.data.objects if o.type == 'MESH'][0].data.shape_keys.key_blocks[-1]
print('range', s.frame_start, s.frame_end, s.render.fps)
for k in range(s.frame_start, s.frame_end + 1):
    s.frame_set(k)
    print('weight', k, repr(key.value))
)");
  const std::string out = (dir / "out.txt").string();
  const std::string blender = program.string() + " -b --factory-startup --python-exit-code 1 ";
  const int status = std::system((blender + "--python " + PNEUMA_SOURCE_DIR + "/scripts/blender-open.py -- " +
                                  (dir / "breathing.glb").string() + " --save " + (dir / "b.blend").string() + " >" +
                                  out + " 2>&1 && " + blender + (dir / "b.blend").string() + " --python " +
                                  check.string() + " >>" + out + " 2>&1")
                                     .c_str());
  const std::string text = pneuma::test::read_text(out);
  ASSERT_EQ(status, 0) << text;
  EXPECT_NE(text.find("range 0 39 10\n"), std::string::npos) << text;
  std::size_t seen = 0;
  bool negative = false;
  for (std::size_t at = text.find("weight "); at != std::string::npos; at = text.find("weight ", at + 1)) {
    std::size_t k = 0;
    double value = 0.0;
    ASSERT_EQ(std::sscanf(text.c_str() + at, "weight %zu %lf", &k, &value), 2);
    ASSERT_LT(k, scales.size());
    EXPECT_NEAR(value, weights[k], 1e-6) << "frame " << k;
    negative = negative || weights[k] < 0.0f;
    ++seen;
  }
  EXPECT_EQ(seen, scales.size()) << text;
  EXPECT_TRUE(negative) << "the drive reaches below the rest shape";
}

std::string h5_string_attribute(hid_t object, const char* name) {
  const hid_t attr = H5Aopen(object, name, H5P_DEFAULT);
  if (attr < 0) return "<missing>";
  const hid_t type = H5Aget_type(attr);
  std::string value(H5Tget_size(type), '\0');
  H5Aread(attr, type, value.data());
  H5Tclose(type);
  H5Aclose(attr);
  return value.substr(0, value.find('\0'));
}

std::vector<double> h5_doubles(hid_t file, const std::string& path) {
  const hid_t set = H5Dopen2(file, path.c_str(), H5P_DEFAULT);
  if (set < 0) return {};
  const hid_t space = H5Dget_space(set);
  std::vector<double> values(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space)));
  H5Dread(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data());
  H5Sclose(space);
  H5Dclose(set);
  return values;
}

TEST(Hdf5Sink, XdmfParsesAndItsShapesMatchTheDatasets) {
  for (const PositionPrecision precision : {PositionPrecision::float32, PositionPrecision::float64}) {
    const bool is_double = precision == PositionPrecision::float64;
    TempDir dir;
    const model::Model model = sphere_model();
    auto sink = make_hdf5_output(dir / "series.h5", dir / "series.xdmf", precision);
    const auto scales = drive(*sink, model, 12, 30.0);

    pugi::xml_document xml;
    ASSERT_TRUE(xml.load_file((dir / "series.xdmf").c_str()));
    const hid_t file = H5Fopen((dir / "series.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    const auto grids = xml.select_nodes("/Xdmf/Domain/Grid/Grid");
    ASSERT_EQ(grids.size(), scales.size());
    // Plain data items only: no Function or HyperSlab (ParaView's default reader and meshio).
    EXPECT_TRUE(xml.select_nodes("//DataItem[@ItemType]").empty());
    EXPECT_TRUE(xml.select_nodes("//DataItem[@Function]").empty());
    int checked = 0;
    for (const auto& item : xml.select_nodes("//DataItem[@Format='HDF']")) {
      const std::string ref = item.node().text().get();
      const std::string dataset = ref.substr(ref.find(':') + 1);
      EXPECT_EQ(parse_dims(item.node().attribute("Dimensions").value()), shape(file, dataset.c_str())) << dataset;
      ++checked;
    }
    EXPECT_EQ(checked, static_cast<int>(4 * scales.size()));
    // The stored scales are the frames' scales.
    EXPECT_EQ(h5_doubles(file, "/frames/scale"), scales);
    // Frame k's geometry (as the XDMF names it) is rest + s_k u rounded to the stored type, exactly.
    const std::size_t n = model.lungs[0].rest.vertex_count();
    for (std::size_t k = 0; k < scales.size(); ++k) {
      const auto item = grids[k].node().select_node("Geometry/DataItem").node();
      EXPECT_STREQ(item.attribute("Precision").value(), is_double ? "8" : "4");
      const std::string ref = item.text().get();
      const auto positions = h5_doubles(file, ref.substr(ref.find(':') + 1));
      ASSERT_EQ(positions.size(), 3 * n) << ref;
      for (std::size_t i = 0; i < n; ++i) {
        const Eigen::Vector3d exact = model.lungs[0].rest.vertices[i] + scales[k] * model.lungs[0].unit_displacement[i];
        for (int c = 0; c < 3; ++c) {
          const double expected = is_double ? exact[c] : static_cast<double>(static_cast<float>(exact[c]));
          ASSERT_EQ(positions[3 * i + static_cast<std::size_t>(c)], expected) << "frame " << k << " vertex " << i;
        }
      }
    }
    H5Fclose(file);
  }
}

// The per-frame positions' storage as HDF5 itself reports it: `none` is one contiguous block of
// exactly 3 N floats with no filter; `gzip` one chunk per frame through shuffle, then deflate
// level 1. Either way the values read back are rest + s_k u rounded to float32.
TEST(Hdf5Sink, PositionsAreContiguousOrShuffledAndDeflatedAsAsked) {
  for (const PositionCompression compression : {PositionCompression::none, PositionCompression::gzip}) {
    const bool gzip = compression == PositionCompression::gzip;
    TempDir dir;
    const model::Model model = sphere_model();
    auto sink = make_hdf5_output(dir / "series.h5", dir / "series.xdmf", PositionPrecision::float32, compression);
    const auto scales = drive(*sink, model, 4, 30.0);
    const hid_t file = H5Fopen((dir / "series.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    const std::size_t n = model.lungs[0].rest.vertex_count();
    for (std::size_t k = 0; k < scales.size(); ++k) {
      const std::string path = fmt::format("/frames/positions/{:06d}", k);
      const hid_t set = H5Dopen2(file, path.c_str(), H5P_DEFAULT);
      ASSERT_GE(set, 0) << path;
      const hid_t dcpl = H5Dget_create_plist(set);
      EXPECT_EQ(H5Pget_layout(dcpl), gzip ? H5D_CHUNKED : H5D_CONTIGUOUS) << path;
      ASSERT_EQ(H5Pget_nfilters(dcpl), gzip ? 2 : 0) << path;
      if (gzip) {
        std::array<hsize_t, 2> chunk{};
        ASSERT_EQ(H5Pget_chunk(dcpl, 2, chunk.data()), 2);
        EXPECT_EQ(chunk, (std::array<hsize_t, 2>{n, 3})) << path;
        unsigned flags = 0;
        std::size_t count = 1;
        unsigned level = 0;
        EXPECT_EQ(H5Pget_filter2(dcpl, 0, &flags, &count, &level, 0, nullptr, nullptr), H5Z_FILTER_SHUFFLE);
        count = 1;
        EXPECT_EQ(H5Pget_filter2(dcpl, 1, &flags, &count, &level, 0, nullptr, nullptr), H5Z_FILTER_DEFLATE);
        EXPECT_EQ(level, 1u) << path;
      } else {
        EXPECT_EQ(H5Dget_storage_size(set), 3 * n * sizeof(float)) << path;
      }
      H5Pclose(dcpl);
      H5Dclose(set);
      const auto positions = h5_doubles(file, path);
      ASSERT_EQ(positions.size(), 3 * n);
      for (std::size_t i = 0; i < n; ++i) {
        const Eigen::Vector3d exact = model.lungs[0].rest.vertices[i] + scales[k] * model.lungs[0].unit_displacement[i];
        for (int c = 0; c < 3; ++c)
          ASSERT_EQ(positions[3 * i + static_cast<std::size_t>(c)], static_cast<double>(static_cast<float>(exact[c])))
              << path << " vertex " << i;
      }
    }
    H5Fclose(file);
  }
}

TEST(Hdf5Sink, DescribesItselfWithRootAttributesAndUnits) {
  TempDir dir;
  const model::Model model = sphere_model();
  auto sink = make_hdf5_output(dir / "series.h5", dir / "series.xdmf");
  drive(*sink, model, 3, 30.0);
  const hid_t file = H5Fopen((dir / "series.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  EXPECT_EQ(h5_string_attribute(file, "format"), "pneuma-series");
  EXPECT_EQ(h5_string_attribute(file, "generator"), std::string("pneuma ") + PNEUMA_VERSION);
  EXPECT_EQ(h5_string_attribute(file, "coordinate_frame"), "LPS");
  EXPECT_EQ(h5_string_attribute(file, "length_unit"), "m");
  const std::vector<std::pair<const char*, const char*>> units{{"/rest/positions", "m"},
                                                               {"/rest/triangles", "1"},
                                                               {"/field/unit_displacement", "m"},
                                                               {"/frames/time_s", "s"},
                                                               {"/frames/scale", "1"},
                                                               {"/frames/lung_volume_m3", "m3"},
                                                               {"/frames/mesh_volume_m3", "m3"},
                                                               {"/frames/area_m2", "m2"},
                                                               {"/frames/positions/000002", "m"},
                                                               {"/rest/region", "1"},
                                                               {"/rest/region_weights", "1"}};
  for (const auto& [path, unit] : units) {
    const hid_t set = H5Dopen2(file, path, H5P_DEFAULT);
    ASSERT_GE(set, 0) << path;
    EXPECT_EQ(h5_string_attribute(set, "units"), unit) << path;
    H5Dclose(set);
  }
  // The regions are the model's, vertex by vertex (read back as doubles).
  const std::vector<double> region = h5_doubles(file, "/rest/region");
  const std::vector<double> weights = h5_doubles(file, "/rest/region_weights");
  ASSERT_EQ(region.size(), model.lungs[0].rest.vertex_count());
  ASSERT_EQ(weights.size(), 4 * model.lungs[0].rest.vertex_count());
  for (std::size_t i = 0; i < region.size(); ++i) {
    EXPECT_EQ(region[i], static_cast<double>(model.lungs[0].regions.label[i])) << i;
    for (std::size_t k = 0; k < 4; ++k) EXPECT_EQ(weights[4 * i + k], model.lungs[0].regions.weight[i][k]) << i;
  }
  const hid_t rest = H5Gopen2(file, "/rest", H5P_DEFAULT);
  EXPECT_EQ(h5_string_attribute(rest, "region_names"), "apex,costal,diaphragmatic,mediastinal");
  H5Gclose(rest);
  H5Fclose(file);
}

// Same inputs, same bytes, with compression on (no timestamps; zlib is deterministic).
TEST(Hdf5Sink, SameInputsSameBytes) {
  TempDir a, b;
  const model::Model model = sphere_model();
  for (TempDir* dir : {&a, &b}) {
    auto sink = make_hdf5_output(*dir / "series.h5", *dir / "series.xdmf");
    drive(*sink, model, 5, 30.0);
  }
  EXPECT_TRUE(pneuma::test::read_text(a / "series.h5") == pneuma::test::read_text(b / "series.h5"));
}

// meshio (Debian's python3-meshio, with h5py) reads series.xdmf as a time series: the oracle is
// rest + s_k u computed in Python (numpy, float64, rounded to the stored float32) from series.h5's
// own float64 datasets.
TEST(Hdf5Sink, MeshioReadsEveryFrame) {
  if (std::system("/usr/bin/python3 -c 'import meshio, h5py' >/dev/null 2>&1") != 0)
    GTEST_SKIP()
        << "meshio or h5py is not importable by /usr/bin/python3 (scripts/install-deps installs python3-meshio python3-h5py)";
  TempDir dir;
  const model::Model model = sphere_model();
  auto sink = make_hdf5_output(dir / "series.h5", dir / "series.xdmf");
  const auto scales = drive(*sink, model, 9, 30.0);
  const auto script = dir.write("check.py", R"(import sys, meshio, h5py, numpy as np
d = sys.argv[1]
h = h5py.File(d + "/series.h5", "r")
rest, u, s, t = h["rest/positions"][()], h["field/unit_displacement"][()], h["frames/scale"][()], h["frames/time_s"][()]
tri = h["rest/triangles"][()]
worst = 0.0
with meshio.xdmf.TimeSeriesReader(d + "/series.xdmf") as r:
    points, cells = r.read_points_cells()
    assert np.array_equal(cells[0].data, tri), "triangles"
    assert points.dtype == np.float32, points.dtype
    assert np.array_equal(points, (rest + s[0] * u).astype(np.float32)), "frame 0 points"
    for k in range(r.num_steps):
        tk, pd, _ = r.read_data(k)
        assert tk == t[k], (k, tk, t[k])
        worst = max(worst, float(np.abs(pd["position"] - (rest + s[k] * u).astype(np.float32)).max()))
print("steps", r.num_steps, "points", len(points), "worst", worst)
)");
  const std::string out = (dir / "out.txt").string();
  const int status =
      std::system(("/usr/bin/python3 " + script.string() + " " + dir.path().string() + " >" + out + " 2>&1").c_str());
  const std::string text = pneuma::test::read_text(out);
  ASSERT_EQ(status, 0) << text;
  const std::string expected = "steps " + std::to_string(scales.size()) + " points " +
                               std::to_string(model.lungs[0].rest.vertex_count()) + " worst 0.0\n";
  EXPECT_EQ(text, expected);
}

// ParaView (Debian's paraview + python3-paraview, from scripts/install-deps; a missing one fails
// in CI): its default reader for .xdmf (Xdmf3ReaderS) and the legacy XDMFReader see every frame
// with all its points, and print nothing else (the Function items of old made them show 0 points
// or log "Cannot find DataItem element in geometry xml").
TEST(Hdf5Sink, ParaViewReadsEveryFrameWhenInstalled) {
  const auto pvbatch = pneuma::test::find_program({"pvbatch"});
  PNEUMA_REQUIRE_CLIENT(pvbatch, "pvbatch (Debian: apt-get install paraview python3-paraview)");
  TempDir dir;
  const model::Model model = sphere_model();
  auto sink = make_hdf5_output(dir / "series.h5", dir / "series.xdmf");
  const auto scales = drive(*sink, model, 7, 30.0);
  const auto script = dir.write("check.py", R"(import sys
from paraview.simple import *
r = OpenDataFile(sys.argv[1])
for k in (0, len(r.TimestepValues) - 1):
    r.UpdatePipeline(r.TimestepValues[k])
    print(r.GetXMLName(), len(r.TimestepValues), r.GetDataInformation().GetNumberOfPoints())
l = XDMFReader(FileNames=[sys.argv[1]])
l.UpdatePipeline(l.TimestepValues[-1])
print("XDMFReader", len(l.TimestepValues), l.GetDataInformation().GetNumberOfPoints())
)");
  const std::string out = (dir / "out.txt").string();
  const int status = std::system(("env -u DISPLAY " + pvbatch.string() + " " + script.string() + " " +
                                  (dir / "series.xdmf").string() + " >" + out + " 2>&1")
                                     .c_str());
  const std::string text = pneuma::test::read_text(out);
  ASSERT_EQ(status, 0) << text;
  std::string expected;
  for (const char* reader : {"Xdmf3ReaderS", "Xdmf3ReaderS", "XDMFReader"})
    expected += fmt::format("{} {} {}\n", reader, scales.size(), model.lungs[0].rest.vertex_count());
  EXPECT_EQ(text, expected);
}

// Mesh sequences are in millimetres by default (`unit: m` for metres) and record their unit in
// every format; read_mesh() reads the recorded unit: the oracle is the frame's positions in the
// run, in metres; an explicit unit (unit_from_file = false) still wins.
TEST(MeshSequenceSink, RecordsTheUnitAndReadMeshUsesIt) {
  const model::Model model = sphere_model();
  struct Case {
    const char* format;
    bool ascii;
    double metres_per_unit;
    const char* header;
  };
  for (const Case& c : {Case{"ply", false, 1e-3, "comment unit mm\n"},
                        {"ply", true, 1e-3, "comment unit mm\n"},
                        {"obj", false, 1e-3, "# unit mm\n"},
                        {"stl", false, 1e-3, "binary STL written by pneuma, unit mm"},
                        {"stl", true, 1e-3, "solid pneuma unit mm\n"},
                        {"ply", false, 1.0, "comment unit m\n"},
                        {"obj", false, 1.0, "# unit m\n"},
                        {"stl", true, 1.0, "solid pneuma unit m\n"}}) {
    const std::string what = fmt::format("{}{} in {} m", c.format, c.ascii ? " ascii" : "", c.metres_per_unit);
    TempDir dir;
    auto sink = make_mesh_sequence_output(dir / "frames", MeshSequenceSpec{c.format, c.ascii, 2, c.metres_per_unit});
    const auto scales = drive(*sink, model, 3, 30.0);
    const auto file = dir / "frames" / (std::string("frame_00002.") + c.format);
    const std::string bytes = pneuma::test::read_text(file);
    EXPECT_NE(bytes.substr(0, 200).find(c.header), std::string::npos) << what;
    EXPECT_EQ(pneuma::mesh::recorded_unit(file), c.metres_per_unit) << what;
    const auto frame = pneuma::mesh::read_mesh(file);  // the recorded unit
    // The frame in metres, numbered as read_mesh() numbers OBJ and STL (by first use).
    pneuma::mesh::TriangleMesh expected = model.lungs[0].rest;
    for (std::size_t i = 0; i < expected.vertices.size(); ++i)
      expected.vertices[i] += scales[2] * model.lungs[0].unit_displacement[i];
    if (std::string(c.format) != "ply") pneuma::mesh::renumber_vertices_by_first_use(expected);
    ASSERT_EQ(frame.vertex_count(), expected.vertex_count());
    double worst = 0.0;
    for (std::size_t i = 0; i < frame.vertex_count(); ++i)
      worst = std::max(worst, (frame.vertices[i] - expected.vertices[i]).cwiseAbs().maxCoeff());
    EXPECT_LT(worst, 1e-7) << what << ": float32 of coordinates around 0.1 m";
    // The file's numbers are the positions in its unit: read as plain numbers (1 unit = 1 m).
    const auto numbers = pneuma::mesh::read_mesh(file, {.metres_per_unit = 1.0, .unit_from_file = false});
    EXPECT_NEAR(numbers.vertices[0].norm(), frame.vertices[0].norm() / c.metres_per_unit,
                1e-6 * numbers.vertices[0].norm())
        << what << ": explicit unit wins";
  }
}

// advance() is one step of the run: the oracle is each quantity computed directly from the
// positions (the plain per-vertex expression, the divergence-theorem volume, the triangle sum).
TEST(Advance, FillsTheFrameFromTheModelAlone) {
  const model::Model model = sphere_model();
  Frame frame(model);
  const double* before = frame.lungs[0].positions.data()->data();
  for (double s : {0.0, 3.5, -2.0}) {
    advance(model, {7, 1.25, 2e-4, {s}}, frame);
    EXPECT_EQ(frame.index, 7u);
    EXPECT_EQ(frame.time_s, 1.25);
    EXPECT_EQ(frame.lung_volume_m3, 2e-4);
    EXPECT_EQ(frame.lungs[0].scale, s);
    pneuma::mesh::TriangleMesh moved = model.lungs[0].rest;
    for (std::size_t i = 0; i < moved.vertices.size(); ++i)
      moved.vertices[i] += s * model.lungs[0].unit_displacement[i];
    EXPECT_EQ(frame.lungs[0].positions, moved.vertices);
    EXPECT_NEAR(frame.lungs[0].mesh_volume_m3, pneuma::mesh::enclosed_volume(moved),
                1e-12 * std::abs(frame.lungs[0].mesh_volume_m3));
    EXPECT_NEAR(frame.lungs[0].area_m2, pneuma::mesh::surface_area(moved), 1e-12 * frame.lungs[0].area_m2);
  }
  EXPECT_EQ(frame.lungs[0].positions.data()->data(), before) << "advance() must not reallocate the positions";
}
