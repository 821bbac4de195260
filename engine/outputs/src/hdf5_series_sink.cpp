// HDF5 time series of a run, with an XDMF (3.0) description that ParaView (Xdmf3ReaderS, the
// legacy XDMF reader) and meshio read: every frame's geometry is one plain HDF5 dataset.
//
// Layout (format "pneuma-series", version 2; docs/formats.md). Root attributes: format,
// format_version, generator ("pneuma <version>"), coordinate_frame ("LPS"), length_unit ("m").
// Every dataset carries a `units` attribute; SI units throughout.
//   /rest/positions   (N, 3) float64, m        /rest/triangles (M, 3) uint32
//   /field/unit_displacement (N, 3) float64, m per unit scale   (attribute area_unit_m2)
//   /rest/region (N) uint8: 0 apex, 1 costal, 2 diaphragmatic, 3 mediastinal (attribute names);
//   /rest/region_weights (N, 4) float64, the blend weights in that order (docs/realism.md)
//   /frames/time_s, /frames/scale, /frames/lung_volume_m3, /frames/mesh_volume_m3,
//   /frames/area_m2   (F) float64
//   /frames/positions/NNNNNN (N, 3) float32 (or float64: outputs.hdf5.positions), m: frame k's
//     positions, rest + s_k u rounded to the stored type; shuffle + deflate
#include <hdf5.h>

#include <fmt/format.h>

#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/hdf5/hdf5_writer.h"
#include "pneuma/outputs/frame_outputs.h"

namespace pneuma::outputs {
namespace {

constexpr const char* kSeriesFormat = "pneuma-series";
constexpr int kSeriesFormatVersion = 2;  // 2: per-frame /frames/positions/NNNNNN, root attributes, units

class Hdf5Sink final : public Output {
 public:
  Hdf5Sink(std::filesystem::path h5, std::filesystem::path xdmf, PositionPrecision precision)
      : h5_path_(std::move(h5)),
        xdmf_path_(std::move(xdmf)),
        double_(precision == PositionPrecision::float64),
        w_{h5_path_.string()} {}
  std::string name() const override { return "hdf5"; }

  void begin(const model::Model& model, const RunInfo& run) override {
    hdf5::silence_hdf5_errors();
    vertex_count_ = model.rest.vertices.size();
    triangle_count_ = model.rest.triangles.size();
    frame_count_ = run.frame_count;
    pending_ = std::make_unique<PendingFile>(h5_path_);
    hdf5::Hdf5Handle file_properties(H5Pcreate(H5P_FILE_CREATE), H5Pclose);
    w_.check(H5Pset_obj_track_times(file_properties, 0), "file properties");
    file_ = H5Fcreate(pending_->temporary().c_str(), H5F_ACC_TRUNC, file_properties, H5P_DEFAULT);
    if (file_ < 0) throw IoError(h5_path_.string() + ": cannot create the HDF5 file");

    w_.string_attribute(file_, "format", kSeriesFormat);
    w_.number_attribute(file_, "format_version", H5T_STD_I32LE, H5T_NATIVE_INT, kSeriesFormatVersion);
    w_.string_attribute(file_, "generator", std::string("pneuma ") + PNEUMA_VERSION);
    w_.string_attribute(file_, "coordinate_frame", "LPS");
    w_.string_attribute(file_, "length_unit", "m");

    const hdf5::Hdf5Handle rest = w_.group(file_, "rest");
    w_.dataset(rest, "positions", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, model.rest.vertices.data(), vertex_count_, 3, "m",
               true);
    w_.dataset(rest, "triangles", H5T_STD_U32LE, H5T_NATIVE_UINT32, model.rest.triangles.data(), triangle_count_, 3,
               "1", true);
    if (model.regions.label.size() == vertex_count_ && model.regions.weight.size() == vertex_count_) {
      std::vector<std::uint8_t> region(vertex_count_);
      for (std::size_t i = 0; i < vertex_count_; ++i) region[i] = static_cast<std::uint8_t>(model.regions.label[i]);
      w_.dataset(rest, "region", H5T_STD_U8LE, H5T_NATIVE_UINT8, region.data(), vertex_count_, 0, "1", true);
      w_.dataset(rest, "region_weights", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, model.regions.weight.data(), vertex_count_,
                 mesh::kRegionCount, "1", true);
      std::string names;
      for (const mesh::Region r : mesh::kRegions) {
        if (!names.empty()) names += ',';
        names += mesh::region_name(r);
      }
      w_.string_attribute(rest, "region_names", names);
    }
    const hdf5::Hdf5Handle field = w_.group(file_, "field");
    w_.dataset(field, "unit_displacement", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, model.unit_displacement.data(),
               vertex_count_, 3, "m", true);
    w_.number_attribute(field, "area_unit_m2", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, model.area_unit_m2);

    frames_group_ = w_.group(file_, "frames").release();  // closed in close()
    positions_group_ = w_.group(frames_group_, "positions").release();
    digits_ = std::max<std::size_t>(6, std::to_string(frame_count_ > 0 ? frame_count_ - 1 : 0).size());
    for (auto* column : {&time_, &scale_, &lung_volume_, &mesh_volume_, &area_}) column->reserve(frame_count_);
  }

  void frame(const model::Model&, const frame::Frame& f) override {
    time_.push_back(f.time_s);
    scale_.push_back(f.scale);
    lung_volume_.push_back(f.lung_volume_m3);
    mesh_volume_.push_back(f.mesh_volume_m3);
    area_.push_back(f.area_m2);
    const std::string name = frame_name(f.index);
    w_.dataset(positions_group_, name.c_str(), double_ ? H5T_IEEE_F64LE : H5T_IEEE_F32LE, H5T_NATIVE_DOUBLE,
               f.positions.data(), vertex_count_, 3, "m", true);
  }

  std::vector<std::filesystem::path> finish(const model::Model&, const RunRecord&) override {
    const hsize_t n = time_.size();
    w_.dataset(frames_group_, "time_s", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, time_.data(), n, 0, "s");
    w_.dataset(frames_group_, "scale", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, scale_.data(), n, 0, "1");
    w_.dataset(frames_group_, "lung_volume_m3", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, lung_volume_.data(), n, 0, "m3");
    w_.dataset(frames_group_, "mesh_volume_m3", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, mesh_volume_.data(), n, 0, "m3");
    w_.dataset(frames_group_, "area_m2", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, area_.data(), n, 0, "m2");
    close();
    pending_->commit();
    write_stream_atomically(xdmf_path_, false, [&](std::ostream& out) { write_xdmf(out); });
    return {h5_path_, xdmf_path_};
  }

  ~Hdf5Sink() override { close(); }

 private:
  void close() {
    if (positions_group_ >= 0) H5Gclose(positions_group_);
    if (frames_group_ >= 0) H5Gclose(frames_group_);
    if (file_ >= 0) H5Fclose(file_);
    positions_group_ = frames_group_ = file_ = -1;
  }

  std::string frame_name(std::size_t k) const { return fmt::format("{:0{}}", k, digits_); }

  // One uniform grid per frame in a temporal collection, its geometry a plain dataset (no
  // Function or HyperSlab items: ParaView's Xdmf3 readers and meshio do not evaluate those).
  // Per-frame attribute `position` (the same dataset) is what meshio's TimeSeriesReader
  // returns per step (it reads the geometry once); `field_u` is the unit displacement.
  void write_xdmf(std::ostream& out) const {
    const std::string h5 = h5_path_.filename().string();
    const std::string n = std::to_string(vertex_count_), m = std::to_string(triangle_count_);
    out << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n <Domain>\n"
        << "  <Grid Name=\"breathing\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
    std::ostringstream number;
    number.precision(17);
    const std::string vectors = "Dimensions=\"" + n + " 3\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">";
    const std::string frame_vectors =
        "Dimensions=\"" + n + " 3\" NumberType=\"Float\" Precision=\"" + (double_ ? "8" : "4") + "\" Format=\"HDF\">";
    for (std::size_t k = 0; k < time_.size(); ++k) {
      number.str("");
      number << time_[k];
      const std::string positions = h5 + ":/frames/positions/" + frame_name(k);
      out << "   <Grid Name=\"frame_" << k << "\" GridType=\"Uniform\">\n"
          << "    <Time Value=\"" << number.str() << "\"/>\n"
          << "    <Topology TopologyType=\"Triangle\" NumberOfElements=\"" << m << "\">\n"
          << "     <DataItem Dimensions=\"" << m << " 3\" NumberType=\"UInt\" Precision=\"4\" Format=\"HDF\">" << h5
          << ":/rest/triangles</DataItem>\n    </Topology>\n    <Geometry GeometryType=\"XYZ\">\n"
          << "     <DataItem " << frame_vectors << positions << "</DataItem>\n    </Geometry>\n"
          << "    <Attribute Name=\"position\" AttributeType=\"Vector\" Center=\"Node\">\n"
          << "     <DataItem " << frame_vectors << positions << "</DataItem>\n    </Attribute>\n"
          << "    <Attribute Name=\"field_u\" AttributeType=\"Vector\" Center=\"Node\">\n"
          << "     <DataItem " << vectors << h5 << ":/field/unit_displacement</DataItem>\n    </Attribute>\n"
          << "   </Grid>\n";
    }
    out << "  </Grid>\n </Domain>\n</Xdmf>\n";
  }

  std::filesystem::path h5_path_, xdmf_path_;
  bool double_;  // per-frame positions stored as float64 (else float32)
  hdf5::Hdf5Writer w_;
  std::unique_ptr<PendingFile> pending_;
  hid_t file_ = -1, frames_group_ = -1, positions_group_ = -1;
  std::size_t digits_ = 6;
  hsize_t vertex_count_ = 0, triangle_count_ = 0, frame_count_ = 0;
  std::vector<double> time_, scale_, lung_volume_, mesh_volume_, area_;
};

}  // namespace

std::unique_ptr<Output> make_hdf5_output(const std::filesystem::path& h5_file, const std::filesystem::path& xdmf_file,
                                         PositionPrecision positions) {
  return std::make_unique<Hdf5Sink>(h5_file, xdmf_file, positions);
}

OutputPlugin hdf5_output() {
  const auto read = [](const config::Node* options) -> std::any {
    PositionPrecision positions = PositionPrecision::float32;
    if (options && options->has("positions")) {
      const std::string value = options->string("positions");
      if (value == "true" || value == "false")
        options->fail_at("positions", "expected float32 or float64 (the stored type; series.h5 now always stores every "
                                      "frame's positions, the plain geometry ParaView and meshio read), got '" +
                                          value + "'");
      if (options->choice("positions", {"float32", "float64"}) == "float64") positions = PositionPrecision::float64;
    }
    return positions;
  };
  return {{"hdf5", true, read}, {}, [](const std::any& settings, const std::filesystem::path& out) {
            return make_hdf5_output(out / "series.h5", out / "series.xdmf", std::any_cast<PositionPrecision>(settings));
          }};
}

}  // namespace pneuma::outputs
