// One mesh file per frame (PLY, OBJ or STL), named frame_00000.ply, ... so that any viewer
// that plays numbered sequences (ParaView, Blender's importers, MeshLab) can load them.
#include <fmt/format.h>

#include "pneuma/engine/scenario.h"
#include "pneuma/engine/sinks.h"
#include "pneuma/mesh/io.h"

namespace pneuma::engine {
namespace {

class MeshSequenceSink final : public FrameSink {
 public:
  MeshSequenceSink(std::filesystem::path dir, MeshSequenceSpec spec, std::size_t frame_count)
      : dir_(std::move(dir)), spec_(std::move(spec)) {
    // Wide enough for every index, at least 5 digits.
    digits_ = std::max<std::size_t>(5, std::to_string(frame_count).size());
  }
  std::string name() const override { return "mesh_sequence"; }

  void begin(const BreathingModel& model, const RunInfo&) override {
    frame_mesh_ = model.rest;  // triangles once; vertices overwritten per frame, same size
  }

  void frame(const BreathingModel&, const Frame& f) override {
    if (f.index % spec_.every != 0) return;
    frame_mesh_.vertices = f.positions;  // same size: no reallocation
    const auto path = dir_ / fmt::format("frame_{:0{}}.{}", f.index, digits_, spec_.format);
    mesh::WriteOptions options;
    options.metres_per_unit = 1.0;  // frames in metres, as everything pneuma writes
    options.ascii = spec_.ascii;
    mesh::write_mesh(path, frame_mesh_, options);
    files_.push_back(path);
  }

  std::vector<std::filesystem::path> end() override { return files_; }

 private:
  std::filesystem::path dir_;
  MeshSequenceSpec spec_;
  std::size_t digits_ = 5;
  mesh::TriangleMesh frame_mesh_;
  std::vector<std::filesystem::path> files_;
};

}  // namespace

std::unique_ptr<FrameSink> make_mesh_sequence_sink(const std::filesystem::path& dir, const MeshSequenceSpec& spec,
                                                   std::size_t frame_count) {
  return std::make_unique<MeshSequenceSink>(dir, spec, frame_count);
}

}  // namespace pneuma::engine
