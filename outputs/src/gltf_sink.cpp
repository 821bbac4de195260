// glTF 2.0 morph-target animation of a breathing run, written with tinygltf.
#define TINYGLTF_IMPLEMENTATION
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/outputs/frame_outputs.h"

namespace pneuma::outputs {
namespace {

// Appends raw bytes to the single buffer, 4-byte aligned as glTF requires; returns a view.
int add_view(tinygltf::Model& m, const void* data, std::size_t bytes, int target) {
  auto& buffer = m.buffers[0].data;
  while (buffer.size() % 4 != 0) buffer.push_back(0);
  const std::size_t offset = buffer.size();
  buffer.resize(offset + bytes);
  std::memcpy(buffer.data() + offset, data, bytes);
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteOffset = offset;
  view.byteLength = bytes;
  if (target != 0) view.target = target;
  m.bufferViews.push_back(view);
  return static_cast<int>(m.bufferViews.size() - 1);
}

int add_accessor(tinygltf::Model& m, int view, int component, std::size_t count, int type, std::vector<double> min = {},
                 std::vector<double> max = {}) {
  tinygltf::Accessor a;
  a.bufferView = view;
  a.componentType = component;
  a.count = count;
  a.type = type;
  a.minValues = std::move(min);
  a.maxValues = std::move(max);
  m.accessors.push_back(a);
  return static_cast<int>(m.accessors.size() - 1);
}

// float32 xyz triples and their per-axis bounds (glTF requires min/max on POSITION).
int add_vec3(tinygltf::Model& m, const std::vector<Eigen::Vector3d>& v, double factor, bool bounds) {
  std::vector<float> data(v.size() * 3);
  std::vector<double> lo(3, std::numeric_limits<double>::infinity()), hi(3, -std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < v.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      const float x = static_cast<float>(v[i][k] * factor);
      data[3 * i + static_cast<std::size_t>(k)] = x;
      lo[static_cast<std::size_t>(k)] = std::min(lo[static_cast<std::size_t>(k)], static_cast<double>(x));
      hi[static_cast<std::size_t>(k)] = std::max(hi[static_cast<std::size_t>(k)], static_cast<double>(x));
    }
  }
  const int view = add_view(m, data.data(), data.size() * sizeof(float), TINYGLTF_TARGET_ARRAY_BUFFER);
  if (!bounds) return add_accessor(m, view, TINYGLTF_COMPONENT_TYPE_FLOAT, v.size(), TINYGLTF_TYPE_VEC3);
  return add_accessor(m, view, TINYGLTF_COMPONENT_TYPE_FLOAT, v.size(), TINYGLTF_TYPE_VEC3, lo, hi);
}

// One lung's mesh in the glb: its buffers (indices, rest positions, normals, the morph target
// u * s_ref, the regions) and its glTF mesh, appended to `m`; returns the mesh's index.
int add_lung_mesh(tinygltf::Model& m, const model::LungModel& lung, double reference_scale, const std::string& name) {
  std::vector<std::uint32_t> indices;
  indices.reserve(lung.rest.triangles.size() * 3);
  for (const auto& t : lung.rest.triangles) indices.insert(indices.end(), t.begin(), t.end());
  const int index_view =
      add_view(m, indices.data(), indices.size() * sizeof(std::uint32_t), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
  const int index_accessor =
      add_accessor(m, index_view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, indices.size(), TINYGLTF_TYPE_SCALAR);
  const int positions = add_vec3(m, lung.rest.vertices, 1.0, true);
  const int normals = add_vec3(m, lung.normals, 1.0, false);
  const int morph = add_vec3(m, lung.unit_displacement, reference_scale, true);
  // The anatomical regions (docs/realism.md) as application-specific vertex attributes: the
  // label (0 apex, 1 costal, 2 diaphragmatic, 3 mediastinal) and the blend weights. Floats:
  // glTF wants vertex attributes aligned to 4 bytes.
  std::vector<float> labels, weights;
  for (const mesh::Region r : lung.regions.label) labels.push_back(static_cast<float>(r));
  for (const auto& w : lung.regions.weight) {
    for (double x : w) weights.push_back(static_cast<float>(x));
  }
  const int region_label =
      labels.empty()
          ? -1
          : add_accessor(m, add_view(m, labels.data(), labels.size() * sizeof(float), TINYGLTF_TARGET_ARRAY_BUFFER),
                         TINYGLTF_COMPONENT_TYPE_FLOAT, labels.size(), TINYGLTF_TYPE_SCALAR);
  const int region_weight =
      weights.empty()
          ? -1
          : add_accessor(m, add_view(m, weights.data(), weights.size() * sizeof(float), TINYGLTF_TARGET_ARRAY_BUFFER),
                         TINYGLTF_COMPONENT_TYPE_FLOAT, weights.size() / 4, TINYGLTF_TYPE_VEC4);

  tinygltf::Primitive primitive;
  primitive.attributes["POSITION"] = positions;
  primitive.attributes["NORMAL"] = normals;
  if (region_label >= 0) primitive.attributes["_REGION"] = region_label;
  if (region_weight >= 0) primitive.attributes["_REGION_WEIGHTS"] = region_weight;
  primitive.indices = index_accessor;
  primitive.material = 0;
  primitive.mode = TINYGLTF_MODE_TRIANGLES;
  primitive.targets.push_back({{"POSITION", morph}});
  tinygltf::Mesh mesh;
  mesh.name = name;
  mesh.primitives.push_back(primitive);
  mesh.weights = {0.0};
  // Names of the morph targets, read by Blender and three.js.
  tinygltf::Value::Array region_names;
  for (const mesh::Region r : mesh::kRegions) region_names.emplace_back(std::string(mesh::region_name(r)));
  mesh.extras = tinygltf::Value(tinygltf::Value::Object{
      {"targetNames", tinygltf::Value(tinygltf::Value::Array{tinygltf::Value(std::string("breath"))})},
      {"regionNames", tinygltf::Value(std::move(region_names))}});
  m.meshes.push_back(mesh);
  return static_cast<int>(m.meshes.size() - 1);
}

// The whole glb, built in memory: the sink writes it, the report embeds it. One mesh and node per
// lung ("lung"; two lungs: "right lung", "left lung"), each with its own morph weight track
// (`morph_weights[i]`, s_i / s_ref,i) in the one animation, all at the same `times`.
std::string glb_bytes(const model::Model& model, const std::vector<double>& reference_scales, double frame_rate_hz,
                      const std::vector<float>& times, const std::vector<std::vector<float>>& morph_weights) {
  tinygltf::Model m;
  m.asset.version = "2.0";
  m.asset.generator = "pneuma " PNEUMA_VERSION;
  m.buffers.resize(1);

  std::vector<std::string> names;
  for (const model::LungModel& lung : model.lungs)
    names.push_back(model.two_lungs() ? std::string(scenario::lung_name(lung.side)) + " lung" : std::string("lung"));
  for (std::size_t i = 0; i < model.lungs.size(); ++i) add_lung_mesh(m, model.lungs[i], reference_scales[i], names[i]);

  const auto [t_min, t_max] = std::minmax_element(times.begin(), times.end());
  const int time_view = add_view(m, times.data(), times.size() * sizeof(float), 0);
  const int time_accessor =
      add_accessor(m, time_view, TINYGLTF_COMPONENT_TYPE_FLOAT, times.size(), TINYGLTF_TYPE_SCALAR, {*t_min}, {*t_max});
  std::vector<int> weight_accessors;
  for (const std::vector<float>& weights : morph_weights) {
    const int weight_view = add_view(m, weights.data(), weights.size() * sizeof(float), 0);
    weight_accessors.push_back(
        add_accessor(m, weight_view, TINYGLTF_COMPONENT_TYPE_FLOAT, weights.size(), TINYGLTF_TYPE_SCALAR));
  }
  m.buffers[0].data.resize((m.buffers[0].data.size() + 3) / 4 * 4, 0);

  tinygltf::Material lung;
  lung.name = "lung";
  lung.pbrMetallicRoughness.baseColorFactor = {0.86, 0.52, 0.50, 1.0};
  lung.pbrMetallicRoughness.metallicFactor = 0.0;
  lung.pbrMetallicRoughness.roughnessFactor = 0.55;
  lung.doubleSided = false;
  m.materials.push_back(lung);

  tinygltf::Scene scene;
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    tinygltf::Node node;
    node.name = names[i];
    node.mesh = static_cast<int>(i);
    node.rotation = {-std::sqrt(0.5), 0.0, 0.0, std::sqrt(0.5)};  // z-up (pneuma) to y-up (glTF)
    m.nodes.push_back(node);
    scene.nodes.push_back(static_cast<int>(i));
  }
  // glTF has no frame range: the animation's extent, for players that keep their own
  // (Blender's scene end); importers keep extras as custom properties (docs/formats.md).
  const double duration_s = times.empty() ? 0.0 : static_cast<double>(times.back());
  scene.extras =
      tinygltf::Value(tinygltf::Value::Object{{"animation_duration_s", tinygltf::Value(duration_s)},
                                              {"frame_rate_hz", tinygltf::Value(frame_rate_hz)},
                                              {"frame_count", tinygltf::Value(static_cast<int>(times.size()))}});
  m.scenes.push_back(scene);
  m.defaultScene = 0;

  tinygltf::Animation animation;
  animation.name = "breathing";
  for (std::size_t i = 0; i < model.lungs.size(); ++i) {
    tinygltf::AnimationSampler sampler;
    sampler.input = time_accessor;
    sampler.output = weight_accessors[i];
    sampler.interpolation = "LINEAR";
    animation.samplers.push_back(sampler);
    tinygltf::AnimationChannel channel;
    channel.sampler = static_cast<int>(i);
    channel.target_node = static_cast<int>(i);
    channel.target_path = "weights";
    animation.channels.push_back(channel);
  }
  m.animations.push_back(animation);

  std::ostringstream out(std::ios::binary);
  tinygltf::TinyGLTF writer;
  if (!writer.WriteGltfSceneToStream(&m, out, false, true)) throw IoError("cannot serialize the glTF model");
  return std::move(out).str();
}

// The largest |s| of each lung's run: its morph target is u * s_ref, its weights s / s_ref.
std::vector<double> reference_scales_of(const RunInfo& run) {
  std::vector<double> out;
  for (std::size_t i = 0; i < run.min_scale.size(); ++i) {
    const double s = std::max(std::abs(run.min_scale[i]), std::abs(run.max_scale[i]));
    out.push_back(s == 0.0 ? 1.0 : s);
  }
  return out;
}

class GltfSink final : public Output {
 public:
  explicit GltfSink(std::filesystem::path file) : file_(std::move(file)) {}
  std::string name() const override { return "gltf"; }

  void begin(const model::Model& model, const RunInfo& run) override {
    model_ = &model;  // the glb is written in one go at end(), when every weight is known
    reference_scales_ = reference_scales_of(run);
    frame_rate_hz_ = run.frame_rate_hz;
    times_.reserve(run.frame_count);
    weights_.assign(model.lungs.size(), {});
    for (auto& w : weights_) w.reserve(run.frame_count);
  }

  void frame(const model::Model&, const model::Frame& f) override {
    times_.push_back(static_cast<float>(f.time_s));
    for (std::size_t i = 0; i < weights_.size(); ++i)
      weights_[i].push_back(static_cast<float>(f.lungs[i].scale / reference_scales_[i]));
  }

  std::vector<std::filesystem::path> finish(const model::Model&, const RunRecord&) override {
    const std::string bytes = glb_bytes(*model_, reference_scales_, frame_rate_hz_, times_, weights_);
    write_stream_atomically(
        file_, true, [&](std::ostream& out) { out.write(bytes.data(), static_cast<std::streamsize>(bytes.size())); });
    return {file_};
  }

 private:
  std::filesystem::path file_;
  const model::Model* model_ = nullptr;
  std::vector<double> reference_scales_;
  double frame_rate_hz_ = 0.0;
  std::vector<float> times_;
  std::vector<std::vector<float>> weights_;  // per lung
};

}  // namespace

std::unique_ptr<Output> make_gltf_output(const std::filesystem::path& file) { return std::make_unique<GltfSink>(file); }

OutputPlugin gltf_output() {
  return {{"gltf", true, no_settings}, {}, [](const std::any&, const std::filesystem::path& out) {
            return make_gltf_output(out / "breathing.glb");
          }};
}

std::string make_glb(const model::Model& model, const RunInfo& run, std::span<const double> time_s,
                     const std::vector<std::span<const double>>& scales) {
  if (scales.size() != model.lungs.size() || run.min_scale.size() != model.lungs.size())
    throw ValueError("make_glb: one scale series and range per lung expected");
  const std::vector<double> reference_scales = reference_scales_of(run);
  std::vector<float> times;
  times.reserve(time_s.size());
  for (const double t : time_s) times.push_back(static_cast<float>(t));
  std::vector<std::vector<float>> weights(scales.size());
  for (std::size_t i = 0; i < scales.size(); ++i) {
    if (time_s.size() != scales[i].size()) throw ValueError("make_glb: as many times as scales expected");
    weights[i].reserve(scales[i].size());
    for (const double s : scales[i]) weights[i].push_back(static_cast<float>(s / reference_scales[i]));
  }
  return glb_bytes(model, reference_scales, run.frame_rate_hz, times, weights);
}

}  // namespace pneuma::outputs
