// One mesh file per frame (PLY, OBJ or STL), named frame_00000.ply, ... so that any viewer
// that plays numbered sequences (ParaView, Blender's importers, MeshLab) can load them. Two
// lungs: one file per lung per frame, right_00000.ply and left_00000.ply (two sequences).
// Beside each sequence, ParaView's file-series index (frame.ply.series: every file with its time
// in seconds), so that ParaView plays it in seconds rather than by file index (a .pvd collection
// would not do: ParaView's PVD reader takes VTK XML files only). In LPS millimetres by default, as
// the CT, 3D Slicer and planning systems beside them; the unit is recorded in every file's header.
#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "pneuma/core/atomic_file.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "pneuma/outputs/frame_outputs.h"

namespace pneuma::outputs {
namespace {

class MeshSequenceSink final : public Output {
 public:
  MeshSequenceSink(std::filesystem::path dir, MeshSequenceSpec spec) : dir_(std::move(dir)), spec_(std::move(spec)) {}
  std::string name() const override { return "mesh_sequence"; }

  void begin(const model::Model& model, const RunInfo& run) override {
    digits_ = std::max<std::size_t>(5, std::to_string(run.frame_count).size());  // every index, at least 5 digits
    frame_meshes_.clear();
    prefixes_.clear();
    for (const model::LungModel& lung : model.lungs) {
      frame_meshes_.push_back(lung.rest);  // triangles once; vertices overwritten per frame, same size
      prefixes_.push_back(model.two_lungs() ? scenario::lung_name(lung.side) : "frame");
    }
    series_.assign(model.lungs.size(), nlohmann::ordered_json::array());
  }

  void frame(const model::Model&, const model::Frame& f) override {
    if (f.index % spec_.every != 0) return;
    for (std::size_t i = 0; i < frame_meshes_.size(); ++i) {
      frame_meshes_[i].vertices = f.lungs[i].positions;  // same size: no reallocation
      const auto path = dir_ / fmt::format("{}_{:0{}}.{}", prefixes_[i], f.index, digits_, spec_.format);
      mesh::WriteOptions options;
      options.metres_per_unit = spec_.metres_per_unit;
      options.ascii = spec_.ascii;
      mesh::write_mesh(path, frame_meshes_[i], options);
      files_.push_back(path);
      series_[i].push_back({{"name", path.filename().string()}, {"time", f.time_s}});
    }
  }

  std::vector<std::filesystem::path> finish(const model::Model&, const RunRecord&) override {
    for (std::size_t i = 0; i < prefixes_.size(); ++i) {
      const nlohmann::ordered_json index{{"file-series-version", "1.0"}, {"files", series_[i]}};
      const auto path = dir_ / fmt::format("{}.{}.series", prefixes_[i], spec_.format);
      write_stream_atomically(path, false, [&](std::ostream& out) { out << index.dump(2) << '\n'; });
      files_.push_back(path);
    }
    return files_;
  }

 private:
  std::filesystem::path dir_;
  MeshSequenceSpec spec_;
  std::size_t digits_ = 5;
  std::vector<mesh::TriangleMesh> frame_meshes_;  // one per lung
  std::vector<std::string> prefixes_;             // "frame" (one lung), else the lung's side
  std::vector<std::filesystem::path> files_;
  std::vector<nlohmann::ordered_json> series_;  // per lung: {"name", "time"} of every file written
};

}  // namespace

double read_mesh_file_unit(const scenario::Node& options) {
  if (!options.has("unit")) return mesh::kMetresPerMillimetre;
  return options.choice("unit", {"mm", "m"}) == "m" ? 1.0 : mesh::kMetresPerMillimetre;
}

std::unique_ptr<Output> make_mesh_sequence_output(const std::filesystem::path& dir, const MeshSequenceSpec& spec) {
  return std::make_unique<MeshSequenceSink>(dir, spec);
}

OutputPlugin mesh_sequence_output() {
  const auto read = [](const scenario::Node* options, const scenario::Scenario& /*run*/) -> std::any {
    MeshSequenceSpec spec;
    if (options) {
      if (options->has("format")) spec.format = options->choice("format", {"ply", "obj", "stl"});
      spec.ascii = options->boolean("ascii", false);
      spec.every = static_cast<std::size_t>(options->integer("every", 1, 1, 1000000));
      spec.metres_per_unit = read_mesh_file_unit(*options);
    }
    return spec;
  };
  return {{"mesh_sequence", false, read}, {}, [](const std::any& settings, const std::filesystem::path& out) {
            return make_mesh_sequence_output(out / "frames", std::any_cast<const MeshSequenceSpec&>(settings));
          }};
}

}  // namespace pneuma::outputs
