// HDF5 time series of a run, with an XDMF (3.0) description that ParaView reads.
//
// Layout (datasets in SI units, named with their unit where not obvious):
//   /rest/positions   (N, 3) float64, m        /rest/triangles (M, 3) uint32
//   /field/unit_displacement (N, 3) float64, m per unit scale   (attribute area_unit_m2)
//   /frames/time_s, /frames/scale, /frames/lung_volume_m3, /frames/mesh_volume_m3,
//   /frames/area_m2   (F) float64
//   /frames/positions (F, N, 3) float64, chunked one frame per chunk (optional)
#include <hdf5.h>

#include <fstream>
#include <sstream>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/engine/sinks.h"
#include "hdf5_writer.h"

namespace pneuma::engine {
namespace {

// A handle that must be valid: IoError "HDF5: cannot <what>" otherwise.
Hdf5Handle checked(hid_t id, herr_t (*close)(hid_t), const std::string& what) {
  if (id < 0) throw IoError("HDF5: cannot " + what);
  return Hdf5Handle(id, close);
}

void check(herr_t status, const std::string& what) {
  if (status < 0) throw IoError("HDF5: cannot " + what);
}

class Hdf5Sink final : public FrameSink {
 public:
  Hdf5Sink(std::filesystem::path h5, std::filesystem::path xdmf, bool positions)
      : h5_path_(std::move(h5)), xdmf_path_(std::move(xdmf)), store_positions_(positions), w_{h5_path_.string()} {}
  std::string name() const override { return "hdf5"; }

  void begin(const BreathingModel& model, const RunInfo& run) override {
    silence_hdf5_errors();
    vertex_count_ = model.rest.vertices.size();
    triangle_count_ = model.rest.triangles.size();
    frame_count_ = run.frame_count;
    pending_ = std::make_unique<PendingFile>(h5_path_);
    Hdf5Handle file_properties(H5Pcreate(H5P_FILE_CREATE), H5Pclose);
    w_.check(H5Pset_obj_track_times(file_properties, 0), "file properties");
    file_ = H5Fcreate(pending_->temporary().c_str(), H5F_ACC_TRUNC, file_properties, H5P_DEFAULT);
    if (file_ < 0) throw IoError(h5_path_.string() + ": cannot create the HDF5 file");

    const Hdf5Handle rest = w_.group(file_, "rest");
    w_.dataset(rest, "positions", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, model.rest.vertices.data(), vertex_count_, 3);
    w_.dataset(rest, "triangles", H5T_STD_U32LE, H5T_NATIVE_UINT32, model.rest.triangles.data(), triangle_count_, 3);
    const Hdf5Handle field = w_.group(file_, "field");
    w_.dataset(field, "unit_displacement", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, model.unit_displacement.data(),
               vertex_count_, 3);
    w_.number_attribute(field, "area_unit_m2", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, model.area_unit_m2);

    frames_group_ = w_.group(file_, "frames").release();  // closed in close()
    if (store_positions_ && frame_count_ > 0) {
      const hsize_t dims[3] = {frame_count_, vertex_count_, 3};
      const hsize_t chunk[3] = {1, std::max<hsize_t>(1, vertex_count_), 3};
      const Hdf5Handle space = checked(H5Screate_simple(3, dims, nullptr), H5Sclose, "create a dataspace");
      const Hdf5Handle properties = checked(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, "create properties");
      check(H5Pset_obj_track_times(properties, 0), "create properties");
      check(H5Pset_chunk(properties, 3, chunk), "set chunking");
      positions_ = H5Dcreate2(frames_group_, "positions", H5T_NATIVE_DOUBLE, space, H5P_DEFAULT, properties,
                              H5P_DEFAULT);
      if (positions_ < 0) throw IoError(h5_path_.string() + ": cannot create /frames/positions");
    }
    for (auto* column : {&time_, &scale_, &lung_volume_, &mesh_volume_, &area_}) column->reserve(frame_count_);
  }

  void frame(const BreathingModel&, const Frame& f) override {
    time_.push_back(f.time_s);
    scale_.push_back(f.scale);
    lung_volume_.push_back(f.lung_volume_m3);
    mesh_volume_.push_back(f.mesh_volume_m3);
    area_.push_back(f.area_m2);
    if (positions_ >= 0) {
      const hsize_t start[3] = {f.index, 0, 0}, count[3] = {1, vertex_count_, 3};
      const Hdf5Handle file_space = checked(H5Dget_space(positions_), H5Sclose, "get a dataspace");
      check(H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start, nullptr, count, nullptr), "select a frame");
      const Hdf5Handle memory = checked(H5Screate_simple(3, count, nullptr), H5Sclose, "create a dataspace");
      check(H5Dwrite(positions_, H5T_NATIVE_DOUBLE, memory, file_space, H5P_DEFAULT, f.positions.data()),
            "write frame positions");
    }
  }

  std::vector<std::filesystem::path> end() override {
    const hsize_t n = time_.size();
    w_.dataset(frames_group_, "time_s", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, time_.data(), n, 0);
    w_.dataset(frames_group_, "scale", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, scale_.data(), n, 0);
    w_.dataset(frames_group_, "lung_volume_m3", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, lung_volume_.data(), n, 0);
    w_.dataset(frames_group_, "mesh_volume_m3", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, mesh_volume_.data(), n, 0);
    w_.dataset(frames_group_, "area_m2", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, area_.data(), n, 0);
    close();
    pending_->commit();
    write_stream_atomically(xdmf_path_, false, [&](std::ostream& out) { write_xdmf(out); });
    return {h5_path_, xdmf_path_};
  }

  ~Hdf5Sink() override { close(); }

 private:
  void close() {
    if (positions_ >= 0) H5Dclose(positions_);
    if (frames_group_ >= 0) H5Gclose(frames_group_);
    if (file_ >= 0) H5Fclose(file_);
    positions_ = frames_group_ = file_ = -1;
  }

  // One uniform grid per frame in a temporal collection. Geometry: the stored positions
  // (a hyperslab of /frames/positions) or, without them, rest + s u as an XDMF function.
  void write_xdmf(std::ostream& out) const {
    const std::string h5 = h5_path_.filename().string();
    const std::string n = std::to_string(vertex_count_), m = std::to_string(triangle_count_);
    const std::string f = std::to_string(frame_count_);
    out << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n <Domain>\n"
        << "  <Grid Name=\"breathing\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
    std::ostringstream number;
    number.precision(17);
    for (std::size_t k = 0; k < time_.size(); ++k) {
      number.str("");
      number << time_[k];
      const std::string time = number.str();
      number.str("");
      number << scale_[k];
      const std::string scale = number.str();
      out << "   <Grid Name=\"frame_" << k << "\" GridType=\"Uniform\">\n"
          << "    <Time Value=\"" << time << "\"/>\n"
          << "    <Topology TopologyType=\"Triangle\" NumberOfElements=\"" << m << "\">\n"
          << "     <DataItem Dimensions=\"" << m << " 3\" NumberType=\"UInt\" Precision=\"4\" Format=\"HDF\">" << h5
          << ":/rest/triangles</DataItem>\n    </Topology>\n    <Geometry GeometryType=\"XYZ\">\n";
      if (store_positions_) {
        out << "     <DataItem ItemType=\"HyperSlab\" Dimensions=\"" << n << " 3\" Type=\"HyperSlab\">\n"
            << "      <DataItem Dimensions=\"3 3\" Format=\"XML\">" << k << " 0 0 1 1 1 1 " << n << " 3</DataItem>\n"
            << "      <DataItem Dimensions=\"" << f << " " << n << " 3\" NumberType=\"Float\" Precision=\"8\" "
            << "Format=\"HDF\">" << h5 << ":/frames/positions</DataItem>\n     </DataItem>\n";
      } else {
        out << "     <DataItem ItemType=\"Function\" Function=\"$0 + " << scale << " * $1\" Dimensions=\"" << n
            << " 3\">\n"
            << "      <DataItem Dimensions=\"" << n << " 3\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">"
            << h5 << ":/rest/positions</DataItem>\n"
            << "      <DataItem Dimensions=\"" << n << " 3\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">"
            << h5 << ":/field/unit_displacement</DataItem>\n     </DataItem>\n";
      }
      out << "    </Geometry>\n"
          << "    <Attribute Name=\"field_u\" AttributeType=\"Vector\" Center=\"Node\">\n"
          << "     <DataItem Dimensions=\"" << n << " 3\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">" << h5
          << ":/field/unit_displacement</DataItem>\n    </Attribute>\n   </Grid>\n";
    }
    out << "  </Grid>\n </Domain>\n</Xdmf>\n";
  }

  std::filesystem::path h5_path_, xdmf_path_;
  bool store_positions_;
  Hdf5Writer w_;
  std::unique_ptr<PendingFile> pending_;
  hid_t file_ = -1, frames_group_ = -1, positions_ = -1;
  hsize_t vertex_count_ = 0, triangle_count_ = 0, frame_count_ = 0;
  std::vector<double> time_, scale_, lung_volume_, mesh_volume_, area_;
};

}  // namespace

std::unique_ptr<FrameSink> make_hdf5_sink(const std::filesystem::path& h5_file, const std::filesystem::path& xdmf_file,
                                          bool store_positions) {
  return std::make_unique<Hdf5Sink>(h5_file, xdmf_file, store_positions);
}

}  // namespace pneuma::engine
