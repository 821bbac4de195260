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
//     positions, rest + s_k u rounded to the stored type; contiguous, or shuffle + deflate 1 in
//     one chunk (outputs.hdf5.compression: gzip)
// Two lungs: the root attribute lungs = "right,left", and each lung's rest/, field/ and frames/
// as above under /right and /left (each with its own scale, mesh volume and area columns).
#include <hdf5.h>

#include <fmt/format.h>

#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/model/hdf5_writer.h"
#include "pneuma/outputs/frame_outputs.h"

namespace pneuma::outputs {
namespace {

constexpr const char* kSeriesFormat = "pneuma-series";
constexpr int kSeriesFormatVersion = 2;  // 2: per-frame /frames/positions/NNNNNN, root attributes, units

class Hdf5Sink final : public Output {
 public:
  Hdf5Sink(std::filesystem::path h5, std::filesystem::path xdmf, PositionPrecision precision,
           PositionCompression compression)
      : h5_path_(std::move(h5)),
        xdmf_path_(std::move(xdmf)),
        double_(precision == PositionPrecision::float64),
        gzip_(compression == PositionCompression::gzip),
        w_{h5_path_.string()} {}
  std::string name() const override { return "hdf5"; }

  void begin(const model::Model& model, const RunInfo& run) override {
    model::silence_hdf5_errors();
    frame_count_ = run.frame_count;
    pending_ = std::make_unique<PendingFile>(h5_path_);
    model::Hdf5Handle file_properties(H5Pcreate(H5P_FILE_CREATE), H5Pclose);
    w_.check(H5Pset_obj_track_times(file_properties, 0), "file properties");
    file_ = H5Fcreate(pending_->temporary().c_str(), H5F_ACC_TRUNC, file_properties, H5P_DEFAULT);
    if (file_ < 0) throw IoError(h5_path_.string() + ": cannot create the HDF5 file");

    w_.string_attribute(file_, "format", kSeriesFormat);
    w_.number_attribute(file_, "format_version", H5T_STD_I32LE, H5T_NATIVE_INT, kSeriesFormatVersion);
    w_.string_attribute(file_, "generator", std::string("pneuma ") + PNEUMA_VERSION);
    w_.string_attribute(file_, "coordinate_frame", "LPS");
    w_.string_attribute(file_, "length_unit", "m");
    digits_ = std::max<std::size_t>(6, std::to_string(frame_count_ > 0 ? frame_count_ - 1 : 0).size());
    if (model.two_lungs()) w_.string_attribute(file_, "lungs", "right,left");
    lungs_.clear();
    lungs_.resize(model.lungs.size());
    for (std::size_t i = 0; i < model.lungs.size(); ++i) {
      Lung& lung = lungs_[i];
      // One lung: at the root, as always. Two: the same layout under /right and /left.
      if (model.two_lungs()) {
        lung.prefix = std::string("/") + scenario::lung_name(model.lungs[i].side);
        lung.group = w_.group(file_, lung.prefix.c_str() + 1).release();
      }
      begin_lung(model.lungs[i], lung.group >= 0 ? lung.group : file_, lung);
    }
  }

  void frame(const model::Model&, const model::Frame& f) override {
    time_.push_back(f.time_s);
    lung_volume_.push_back(f.lung_volume_m3);
    for (std::size_t i = 0; i < lungs_.size(); ++i) {
      Lung& lung = lungs_[i];
      const model::LungFrame& lf = f.lungs[i];
      lung.scale.push_back(lf.scale);
      lung.mesh_volume.push_back(lf.mesh_volume_m3);
      lung.area.push_back(lf.area_m2);
      const std::string name = frame_name(f.index);
      w_.dataset(lung.positions_group, name.c_str(), double_ ? H5T_IEEE_F64LE : H5T_IEEE_F32LE, H5T_NATIVE_DOUBLE,
                 lf.positions.data(), lung.vertex_count, 3, "m", gzip_, kPositionsDeflateLevel);
    }
  }

  std::vector<std::filesystem::path> finish(const model::Model&, const RunRecord&) override {
    const hsize_t n = time_.size();
    for (Lung& lung : lungs_) {
      w_.dataset(lung.frames_group, "time_s", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, time_.data(), n, 0, "s");
      w_.dataset(lung.frames_group, "scale", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, lung.scale.data(), n, 0, "1");
      w_.dataset(lung.frames_group, "lung_volume_m3", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, lung_volume_.data(), n, 0,
                 "m3");
      w_.dataset(lung.frames_group, "mesh_volume_m3", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, lung.mesh_volume.data(), n, 0,
                 "m3");
      w_.dataset(lung.frames_group, "area_m2", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, lung.area.data(), n, 0, "m2");
    }
    close();
    pending_->commit();
    std::vector<const Lung*> all;
    for (const Lung& lung : lungs_) all.push_back(&lung);
    write_stream_atomically(xdmf_path_, false, [&](std::ostream& out) { write_xdmf(out, all); });
    std::vector<std::filesystem::path> files{h5_path_, xdmf_path_};
    if (lungs_.size() == 2) {
      // Each lung alone as well (series-right.xdmf, series-left.xdmf): plain temporal collections,
      // for readers that do not open nested collections (meshio's TimeSeriesReader).
      for (const Lung& lung : lungs_) {
        std::filesystem::path alone = xdmf_path_;
        alone.replace_filename(xdmf_path_.stem().string() + "-" + lung.prefix.substr(1) +
                               xdmf_path_.extension().string());
        write_stream_atomically(alone, false, [&](std::ostream& out) { write_xdmf(out, {&lung}); });
        files.push_back(alone);
      }
    }
    return files;
  }

  ~Hdf5Sink() override { close(); }

 private:
  // One lung's part of the file: its group (the root for one lung), its frames and columns.
  struct Lung {
    std::string prefix;  // "" (one lung) or "/right", "/left"
    hid_t group = -1, frames_group = -1, positions_group = -1;
    hsize_t vertex_count = 0, triangle_count = 0;
    std::vector<double> scale, mesh_volume, area;
  };

  void begin_lung(const model::LungModel& model, hid_t base, Lung& lung) {
    lung.vertex_count = model.rest.vertices.size();
    lung.triangle_count = model.rest.triangles.size();
    const hsize_t vertex_count_ = lung.vertex_count;
    const model::Hdf5Handle rest = w_.group(base, "rest");
    w_.dataset(rest, "positions", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, model.rest.vertices.data(), vertex_count_, 3, "m",
               true);
    w_.dataset(rest, "triangles", H5T_STD_U32LE, H5T_NATIVE_UINT32, model.rest.triangles.data(), lung.triangle_count, 3,
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
    const model::Hdf5Handle field = w_.group(base, "field");
    w_.dataset(field, "unit_displacement", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, model.unit_displacement.data(),
               vertex_count_, 3, "m", true);
    w_.number_attribute(field, "area_unit_m2", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, model.area_unit_m2);

    lung.frames_group = w_.group(base, "frames").release();  // closed in close()
    lung.positions_group = w_.group(lung.frames_group, "positions").release();
    for (auto* column : {&time_, &lung_volume_}) column->reserve(frame_count_);
    for (auto* column : {&lung.scale, &lung.mesh_volume, &lung.area}) column->reserve(frame_count_);
  }

  void close() {
    for (Lung& lung : lungs_) {
      if (lung.positions_group >= 0) H5Gclose(lung.positions_group);
      if (lung.frames_group >= 0) H5Gclose(lung.frames_group);
      if (lung.group >= 0) H5Gclose(lung.group);
      lung.positions_group = lung.frames_group = lung.group = -1;
    }
    if (file_ >= 0) H5Fclose(file_);
    file_ = -1;
  }

  std::string frame_name(std::size_t k) const { return fmt::format("{:0{}}", k, digits_); }

  // One uniform grid per frame in a temporal collection, its geometry a plain dataset (no
  // Function or HyperSlab items: ParaView's Xdmf3 readers and meshio do not evaluate those).
  // Per-frame attribute `position` (the same dataset) is what meshio's TimeSeriesReader
  // returns per step (it reads the geometry once); `field_u` is the unit displacement. Two
  // lungs: each frame a spatial collection of two uniform grids (`right`, `left`), which
  // ParaView shows as one multiblock dataset; `lungs` one of them: that lung alone.
  void write_xdmf(std::ostream& out, const std::vector<const Lung*>& lungs) const {
    const std::string h5 = h5_path_.filename().string();
    out << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n <Domain>\n"
        << "  <Grid Name=\"breathing\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
    std::ostringstream number;
    number.precision(17);
    const bool two = lungs.size() == 2;
    for (std::size_t k = 0; k < time_.size(); ++k) {
      number.str("");
      number << time_[k];
      if (two) {
        out << "   <Grid Name=\"frame_" << k << "\" GridType=\"Collection\" CollectionType=\"Spatial\">\n"
            << "    <Time Value=\"" << number.str() << "\"/>\n";
      }
      for (const Lung* one : lungs) {
        const Lung& lung = *one;
        const std::string n = std::to_string(lung.vertex_count), m = std::to_string(lung.triangle_count);
        const std::string vectors = "Dimensions=\"" + n + " 3\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">";
        const std::string frame_vectors = "Dimensions=\"" + n + " 3\" NumberType=\"Float\" Precision=\"" +
                                          (double_ ? "8" : "4") + "\" Format=\"HDF\">";
        const std::string positions = h5 + ":" + lung.prefix + "/frames/positions/" + frame_name(k);
        const std::string name =
            two ? lung.prefix.substr(1)
                : (lung.prefix.empty() ? "" : lung.prefix.substr(1) + "_") + "frame_" + std::to_string(k);
        const std::string pad = two ? " " : "";
        out << pad << "   <Grid Name=\"" << name << "\" GridType=\"Uniform\">\n";
        if (!two) out << "    <Time Value=\"" << number.str() << "\"/>\n";
        out << pad << "    <Topology TopologyType=\"Triangle\" NumberOfElements=\"" << m << "\">\n"
            << pad << "     <DataItem Dimensions=\"" << m << " 3\" NumberType=\"UInt\" Precision=\"4\" Format=\"HDF\">"
            << h5 << ":" << lung.prefix << "/rest/triangles</DataItem>\n"
            << pad << "    </Topology>\n"
            << pad << "    <Geometry GeometryType=\"XYZ\">\n"
            << pad << "     <DataItem " << frame_vectors << positions << "</DataItem>\n"
            << pad << "    </Geometry>\n"
            << pad << "    <Attribute Name=\"position\" AttributeType=\"Vector\" Center=\"Node\">\n"
            << pad << "     <DataItem " << frame_vectors << positions << "</DataItem>\n"
            << pad << "    </Attribute>\n"
            << pad << "    <Attribute Name=\"field_u\" AttributeType=\"Vector\" Center=\"Node\">\n"
            << pad << "     <DataItem " << vectors << h5 << ":" << lung.prefix
            << "/field/unit_displacement</DataItem>\n"
            << pad << "    </Attribute>\n"
            << pad << "   </Grid>\n";
      }
      if (two) out << "   </Grid>\n";
    }
    out << "  </Grid>\n </Domain>\n</Xdmf>\n";
  }

  std::filesystem::path h5_path_, xdmf_path_;
  bool double_;  // per-frame positions stored as float64 (else float32)
  bool gzip_;    // per-frame positions shuffled and deflated (else contiguous)
  // Level 1: within 1 % of level 4's size on the demo's frames, 8 % less CPU (BENCHMARKS.md).
  static constexpr unsigned kPositionsDeflateLevel = 1;
  model::Hdf5Writer w_;
  std::unique_ptr<PendingFile> pending_;
  hid_t file_ = -1;
  std::size_t digits_ = 6;
  hsize_t frame_count_ = 0;
  std::vector<Lung> lungs_;
  std::vector<double> time_, lung_volume_;
};

}  // namespace

std::unique_ptr<Output> make_hdf5_output(const std::filesystem::path& h5_file, const std::filesystem::path& xdmf_file,
                                         PositionPrecision positions, PositionCompression compression) {
  return std::make_unique<Hdf5Sink>(h5_file, xdmf_file, positions, compression);
}

OutputPlugin hdf5_output() {
  struct Settings {
    PositionPrecision positions = PositionPrecision::float32;
    PositionCompression compression = PositionCompression::none;
  };
  const auto read = [](const scenario::Node* options, const scenario::Scenario& /*run*/) -> std::any {
    Settings settings;
    PositionPrecision& positions = settings.positions;
    if (options && options->has("compression") && options->choice("compression", {"none", "gzip"}) == "gzip")
      settings.compression = PositionCompression::gzip;
    if (options && options->has("positions")) {
      const std::string value = options->string("positions");
      if (value == "true" || value == "false")
        options->fail_at("positions", "expected float32 or float64 (the stored type; series.h5 now always stores every "
                                      "frame's positions, the plain geometry ParaView and meshio read), got '" +
                                          value + "'");
      if (options->choice("positions", {"float32", "float64"}) == "float64") positions = PositionPrecision::float64;
    }
    return settings;
  };
  return {{"hdf5", true, read}, {}, [](const std::any& any, const std::filesystem::path& out) {
            const auto& settings = std::any_cast<const Settings&>(any);
            return make_hdf5_output(out / "series.h5", out / "series.xdmf", settings.positions, settings.compression);
          }};
}

}  // namespace pneuma::outputs
