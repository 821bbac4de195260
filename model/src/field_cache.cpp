// The HDF5 field cache. HDF5 (C API) stays inside this file.
#include "pneuma/model/field_cache.h"

#include <algorithm>
#include <hdf5.h>

#include <array>
#include <cstring>
#include <fmt/format.h>
#include <fstream>
#include <iterator>
#include <limits>
#include <mutex>
#include <optional>
#include <string_view>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/core/paths.h"
#include "pneuma/model/hdf5_writer.h"

namespace pneuma::model {
namespace {

constexpr const char* kFormat = "pneuma-field";
// 2: /field/displacement renamed /field/unit_displacement
// 3: the names of series.h5 (/rest/positions, /field/shear_modulus_pa, /field attribute
//    area_unit_m2), root generator / coordinate_frame / length_unit, `units` per dataset
//    (uncompressed: small, and a damaged value must reach the checksum, not the decompressor)
// 4: sealed: the HDF5 user block (the first 512 bytes, which HDF5 skips) holds the length and
//    hash of the bytes after it, checked before HDF5 reads anything
constexpr int kFormatVersion = 4;

// ---- A deterministic 128-bit hash (two independent 64-bit multiply-xorshift lanes) --------
class Hasher {
 public:
  void bytes(const void* data, std::size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    std::uint64_t word = 0;
    std::size_t i = 0;
    for (; i + 8 <= n; i += 8) {
      std::memcpy(&word, p + i, 8);
      mix(word);
    }
    word = 0;
    if (n > i) std::memcpy(&word, p + i, n - i);
    mix(word ^ (static_cast<std::uint64_t>(n - i) << 56));
    mix(n);
  }
  void text(const std::string& s) { bytes(s.data(), s.size()); }
  template <typename T>
  void value(const T& v) {
    bytes(&v, sizeof v);
  }
  std::string hex() const { return fmt::format("{:016x}{:016x}", finish(a_), finish(b_)); }

 private:
  static std::uint64_t finish(std::uint64_t x) {
    x ^= x >> 33;
    x *= 0xff51afd7ed558ccdULL;
    x ^= x >> 33;
    x *= 0xc4ceb9fe1a85ec53ULL;
    x ^= x >> 33;
    return x;
  }
  void mix(std::uint64_t w) {
    a_ = (a_ ^ w) * 0x100000001b3ULL;
    a_ ^= a_ >> 29;
    b_ = (b_ + w) * 0x9e3779b97f4a7c15ULL;
    b_ ^= b_ >> 31;
  }
  std::uint64_t a_ = 0xcbf29ce484222325ULL, b_ = 0x6a09e667f3bcc909ULL;
};

const char* rule_name(field::CliquePathRule r) {
  return r == field::CliquePathRule::sum_of_shortest_paths ? "sum_of_shortest_paths" : "strongest_path";
}

// Every array and attribute of the model, in a fixed order.
std::string checksum(const FieldRecord& m) {
  Hasher h;
  h.text(kFormat);
  h.bytes(m.rest.vertices.data(), m.rest.vertices.size() * sizeof(Eigen::Vector3d));
  h.bytes(m.rest.triangles.data(), m.rest.triangles.size() * sizeof(mesh::Triangle));
  h.bytes(m.unit_displacement.data(), m.unit_displacement.size() * sizeof(Eigen::Vector3d));
  h.bytes(m.force.data(), m.force.size() * sizeof(double));
  h.bytes(m.shear_modulus_pa.data(), m.shear_modulus_pa.size() * sizeof(double));
  const FieldMetadata& d = m.metadata;
  for (const std::string* s : {&d.key, &d.pneuma_version, &d.tissue, &d.solver, &d.path_rule}) h.text(*s);
  h.value(d.tolerance);
  h.value(static_cast<std::int64_t>(d.clique_hops));
  h.value(d.area_unit_m2);
  h.value(d.shots);
  h.value(d.iterations);
  h.value(d.residual);
  if (m.interior) {  // absent: the checksum of a file written before the interior existed
    const LungInterior& i = *m.interior;
    h.text("interior");
    h.text(i.key);
    h.text(field::interior_model_name(i.options.model));
    h.value(i.edge_m);
    if (i.mesher != mesh::TetMesher::delaunay) h.text(mesh::tet_mesher_name(i.mesher));
    h.value(i.options.poisson_ratio);
    h.value(i.options.tolerance);
    h.value(static_cast<std::uint64_t>(i.report.iterations));
    h.value(i.report.relative_residual);
    h.bytes(i.mesh.nodes.data(), i.mesh.nodes.size() * sizeof(Eigen::Vector3d));
    h.bytes(i.mesh.tets.data(), i.mesh.tets.size() * sizeof(mesh::Tetrahedron));
    h.bytes(i.boundary_nodes.data(), i.boundary_nodes.size() * sizeof(std::uint32_t));
    h.bytes(i.unit_displacement.data(), i.unit_displacement.size() * sizeof(Eigen::Vector3d));
  }
  return h.hex();
}

// ---- The seal: HDF5 1.10 is not safe on damaged files (fuzz_field_cache found a use after
// free in H5Aexists and an 80 GB allocation in its metadata cache), and the cache is derived
// data, so HDF5 only ever parses a file that is byte for byte what pneuma wrote.
constexpr std::size_t kSealBytes = 512;  // HDF5's smallest user block
constexpr std::string_view kSealMagic = "pneuma-field-seal 1\n";

std::string seal_of(const std::string& body) {
  Hasher h;
  h.text(body);
  return fmt::format("{}bytes {}\nhash {}\n", kSealMagic, body.size(), h.hex());
}

void seal_file(const std::filesystem::path& path, const std::string& shown) {
  std::string bytes;
  try {
    bytes = read_file_bytes(path);
  } catch (const IoError&) {
    throw IoError(shown + ": cannot write: the HDF5 file written cannot be read back to seal it");
  }
  if (bytes.size() < kSealBytes) throw IoError(shown + ": cannot write: the HDF5 file is shorter than its user block");
  std::string seal = seal_of(bytes.substr(kSealBytes));
  seal.resize(kSealBytes, '\0');
  std::fstream out(path, std::ios::binary | std::ios::in | std::ios::out);
  out.write(seal.data(), static_cast<std::streamsize>(seal.size()));
  if (!out.flush()) throw IoError(shown + ": cannot write its seal");
}

// Refuses (through `refuse`) anything but a sealed file whose bytes match their seal.
template <typename Refuse>
void check_seal(const std::filesystem::path& path, Refuse refuse) {
  const std::string bytes = read_file_bytes(path);
  if (bytes.compare(0, kSealMagic.size(), kSealMagic) != 0) {
    constexpr std::string_view kHdf5Signature = "\x89HDF\r\n\x1a\n";
    bool hdf5 = false;
    for (std::size_t at = 0; at + kHdf5Signature.size() <= bytes.size() && !hdf5; at = at == 0 ? 512 : 2 * at)
      hdf5 = bytes.compare(at, kHdf5Signature.size(), kHdf5Signature) == 0;
    refuse(hdf5 ? std::string("an HDF5 file without pneuma's seal (from elsewhere, or from an older pneuma)")
                : std::string("not an HDF5 file"));
  }
  if (bytes.size() < kSealBytes) refuse("truncated (shorter than its seal)");
  const std::string stored = bytes.substr(0, bytes.find('\0'));
  if (stored != seal_of(bytes.substr(kSealBytes))) refuse("its bytes do not match its seal (truncated or damaged)");
}

void write_file(const std::filesystem::path& tmp, const std::string& shown, const FieldRecord& m) {
  const model::Hdf5Writer w{shown};
  model::Hdf5Handle fcpl(H5Pcreate(H5P_FILE_CREATE), H5Pclose);
  w.check(H5Pset_obj_track_times(fcpl.get(), 0), "file properties");
  w.check(H5Pset_userblock(fcpl.get(), kSealBytes), "file properties");
  model::Hdf5Handle file(H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, fcpl.get(), H5P_DEFAULT), H5Fclose);
  if (!file.ok()) w.fail("the file");
  const hid_t root = file.get();
  const FieldMetadata& d = m.metadata;
  w.string_attribute(root, "format", kFormat);
  w.number_attribute(root, "format_version", H5T_STD_I32LE, H5T_NATIVE_INT, kFormatVersion);
  w.string_attribute(root, "generator", "pneuma " + d.pneuma_version);
  w.string_attribute(root, "coordinate_frame", "LPS");
  w.string_attribute(root, "length_unit", "m");
  w.string_attribute(root, "pneuma_version", d.pneuma_version);
  w.string_attribute(root, "key", d.key);
  w.string_attribute(root, "checksum", checksum(m));
  w.string_attribute(root, "tissue", d.tissue);
  w.string_attribute(root, "solver", d.solver);
  w.number_attribute(root, "tolerance", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, d.tolerance);
  w.number_attribute(root, "clique_hops", H5T_STD_I32LE, H5T_NATIVE_INT, d.clique_hops);
  w.string_attribute(root, "path_rule", d.path_rule);
  w.number_attribute(root, "shots", H5T_STD_U64LE, H5T_NATIVE_UINT64, d.shots);
  w.number_attribute(root, "iterations", H5T_STD_U64LE, H5T_NATIVE_UINT64, d.iterations);
  w.number_attribute(root, "residual", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, d.residual);
  const hsize_t nv = m.rest.vertices.size(), nt = m.rest.triangles.size();
  {
    const model::Hdf5Handle rest = w.group(root, "rest");
    w.dataset(rest.get(), "positions", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, m.rest.vertices.data(), nv, 3, "m");
    w.dataset(rest.get(), "triangles", H5T_STD_U32LE, H5T_NATIVE_UINT32, m.rest.triangles.data(), nt, 3, "1");
  }
  {
    const model::Hdf5Handle field = w.group(root, "field");
    w.number_attribute(field.get(), "area_unit_m2", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, d.area_unit_m2);
    w.dataset(field.get(), "unit_displacement", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, m.unit_displacement.data(), nv, 3,
              "m");
    w.dataset(field.get(), "force", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, m.force.data(), nv, 0, "1");
    w.dataset(field.get(), "shear_modulus_pa", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, m.shear_modulus_pa.data(), nv, 0,
              "Pa");
  }
  if (m.interior) {
    const LungInterior& i = *m.interior;
    const model::Hdf5Handle group = w.group(root, "interior");
    const hid_t g = group.get();
    w.string_attribute(g, "key", i.key);
    w.string_attribute(g, "model", field::interior_model_name(i.options.model));
    w.number_attribute(g, "edge_m", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, i.edge_m);
    w.string_attribute(g, "mesher", mesh::tet_mesher_name(i.mesher));
    w.number_attribute(g, "poisson_ratio", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, i.options.poisson_ratio);
    w.number_attribute(g, "tolerance", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, i.options.tolerance);
    const auto iterations = static_cast<std::uint64_t>(i.report.iterations);
    w.number_attribute(g, "iterations", H5T_STD_U64LE, H5T_NATIVE_UINT64, iterations);
    w.number_attribute(g, "residual", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, i.report.relative_residual);
    w.number_attribute(g, "unfold_m3", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, i.options.unfold_volume_m3);
    const auto unfolded = static_cast<std::uint64_t>(i.report.unfolded_nodes);
    const auto dropped = static_cast<std::uint64_t>(i.report.dropped_tets);
    w.number_attribute(g, "unfolded_nodes", H5T_STD_U64LE, H5T_NATIVE_UINT64, unfolded);
    w.number_attribute(g, "dropped_tets", H5T_STD_U64LE, H5T_NATIVE_UINT64, dropped);
    w.number_attribute(g, "dropped_volume_m3", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, i.report.dropped_volume_m3);
    const hsize_t nn = i.mesh.nodes.size();
    w.dataset(g, "nodes", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, i.mesh.nodes.data(), nn, 3, "m");
    w.dataset(g, "tets", H5T_STD_U32LE, H5T_NATIVE_UINT32, i.mesh.tets.data(), i.mesh.tets.size(), 4, "1");
    w.dataset(g, "boundary_nodes", H5T_STD_U32LE, H5T_NATIVE_UINT32, i.boundary_nodes.data(), i.boundary_nodes.size(),
              0, "1");
    w.dataset(g, "unit_displacement", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, i.unit_displacement.data(), nn, 3, "m");
  }
  if (H5Fflush(root, H5F_SCOPE_GLOBAL) < 0) w.fail("the file");
}

// ---- Reading ----------------------------------------------------------------------------------
struct Reader {
  std::string file;
  hid_t root = -1;
  // The most bytes a value may claim: a damaged header can claim any size, and a file of B bytes
  // holds at most ~1032 B after deflate (zlib's largest ratio), so more is damage, not data.
  std::uint64_t max_value_bytes = std::numeric_limits<std::uint64_t>::max();
  [[noreturn]] void refuse(const std::string& why) const {
    throw InputError(file + ": not a pneuma field file: " + why);
  }
  void check_claimed_size(const char* what, std::uint64_t items, std::uint64_t bytes_per_item) const {
    if (bytes_per_item != 0 && items > max_value_bytes / bytes_per_item)
      refuse(std::string(what) + " claims " + std::to_string(items) + " items, more than the file can hold (damaged)");
  }

  std::string string_attribute(const char* name) const {
    if (H5Aexists(root, name) <= 0) refuse(std::string("no '") + name + "' attribute");
    model::Hdf5Handle attr(H5Aopen(root, name, H5P_DEFAULT), H5Aclose);
    model::Hdf5Handle type(H5Aget_type(attr.get()), H5Tclose);
    if (!type.ok() || H5Tget_class(type.get()) != H5T_STRING || H5Tis_variable_str(type.get()) != 0)
      refuse(std::string("attribute '") + name + "' is not a fixed-length string");
    const std::size_t size = H5Tget_size(type.get());
    check_claimed_size((std::string("attribute '") + name + "'").c_str(), size, 1);
    std::string value(size, '\0');
    model::Hdf5Handle memory(H5Tcopy(H5T_C_S1), H5Tclose);
    H5Tset_size(memory.get(), size);
    H5Tset_strpad(memory.get(), H5T_STR_NULLPAD);
    if (H5Aread(attr.get(), memory.get(), value.data()) < 0)
      refuse(std::string("cannot read attribute '") + name + "'");
    value.resize(std::strlen(value.c_str()));
    return value;
  }
  template <typename T>
  T number_attribute(const char* name, hid_t memory_type, H5T_class_t expected) const {
    if (H5Aexists(root, name) <= 0) refuse(std::string("no '") + name + "' attribute");
    model::Hdf5Handle attr(H5Aopen(root, name, H5P_DEFAULT), H5Aclose);
    model::Hdf5Handle type(H5Aget_type(attr.get()), H5Tclose);
    model::Hdf5Handle space(H5Aget_space(attr.get()), H5Sclose);
    if (!type.ok() || H5Tget_class(type.get()) != expected || H5Sget_simple_extent_npoints(space.get()) != 1)
      refuse(std::string("attribute '") + name + "' has the wrong type");
    T value{};
    if (H5Aread(attr.get(), memory_type, &value) < 0) refuse(std::string("cannot read attribute '") + name + "'");
    return value;
  }
  // Reads a dataset of `columns` (0: one-dimensional) into `out`, checking type and shape.
  template <typename T>
  std::size_t dataset(const char* path, hid_t memory_type, H5T_class_t expected, hsize_t columns, std::vector<T>& out,
                      std::size_t scalars_per_item) const {
    if (H5Lexists(root, path, H5P_DEFAULT) <= 0) refuse(std::string("no dataset ") + path);
    model::Hdf5Handle set(H5Dopen2(root, path, H5P_DEFAULT), H5Dclose);
    if (!set.ok()) refuse(std::string("cannot open dataset ") + path);
    model::Hdf5Handle type(H5Dget_type(set.get()), H5Tclose);
    model::Hdf5Handle space(H5Dget_space(set.get()), H5Sclose);
    const int rank = H5Sget_simple_extent_ndims(space.get());
    std::array<hsize_t, 2> dims{0, 0};
    if (!type.ok() || H5Tget_class(type.get()) != expected || rank != (columns == 0 ? 1 : 2) ||
        H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr) < 0 || (columns != 0 && dims[1] != columns))
      refuse(std::string("dataset ") + path + " has the wrong type or shape");
    const std::size_t rows = dims[0];
    check_claimed_size((std::string("dataset ") + path).c_str(), rows,
                       std::max<hsize_t>(columns, 1) * sizeof(T) / scalars_per_item);
    out.resize(rows * std::max<hsize_t>(columns, 1) / scalars_per_item);
    if (rows > 0 && H5Dread(set.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0)
      refuse(std::string("cannot read dataset ") + path + " (truncated or damaged)");
    return rows;
  }
};

// /interior: its attributes and arrays, shapes and node indices checked.
std::shared_ptr<const LungInterior> read_interior(const Reader& r) {
  model::Hdf5Handle group(H5Gopen2(r.root, "interior", H5P_DEFAULT), H5Gclose);
  if (!group.ok()) r.refuse("cannot open group /interior");
  const Reader g{r.file, group.get(), r.max_value_bytes};
  auto out = std::make_shared<LungInterior>();
  LungInterior& i = *out;
  i.key = g.string_attribute("key");
  const std::string model = g.string_attribute("model");
  if (model != "elastic" && model != "harmonic") r.refuse("interior model '" + model + "' is not elastic or harmonic");
  i.options.model = model == "elastic" ? field::InteriorModel::elastic : field::InteriorModel::harmonic;
  i.edge_m = g.number_attribute<double>("edge_m", H5T_NATIVE_DOUBLE, H5T_FLOAT);
  if (H5Aexists(group.get(), "mesher") > 0) {  // absent in files written before the lattice: delaunay
    const std::string mesher = g.string_attribute("mesher");
    if (mesher != "delaunay" && mesher != "lattice")
      r.refuse("interior mesher '" + mesher + "' is not delaunay or lattice");
    i.mesher = mesher == "lattice" ? mesh::TetMesher::lattice : mesh::TetMesher::delaunay;
  }
  i.options.poisson_ratio = g.number_attribute<double>("poisson_ratio", H5T_NATIVE_DOUBLE, H5T_FLOAT);
  i.options.tolerance = g.number_attribute<double>("tolerance", H5T_NATIVE_DOUBLE, H5T_FLOAT);
  i.report.iterations = g.number_attribute<std::uint64_t>("iterations", H5T_NATIVE_UINT64, H5T_INTEGER);
  i.report.relative_residual = g.number_attribute<double>("residual", H5T_NATIVE_DOUBLE, H5T_FLOAT);
  // The unfolding's (absent in files written before it: their key differs, so the interior is
  // computed again, but the surface field in the file is still good).
  if (H5Aexists(group.get(), "unfold_m3") > 0) {
    i.options.unfold_volume_m3 = g.number_attribute<double>("unfold_m3", H5T_NATIVE_DOUBLE, H5T_FLOAT);
    i.report.unfolded_nodes = g.number_attribute<std::uint64_t>("unfolded_nodes", H5T_NATIVE_UINT64, H5T_INTEGER);
    i.report.dropped_tets = g.number_attribute<std::uint64_t>("dropped_tets", H5T_NATIVE_UINT64, H5T_INTEGER);
    i.report.dropped_volume_m3 = g.number_attribute<double>("dropped_volume_m3", H5T_NATIVE_DOUBLE, H5T_FLOAT);
  } else {
    i.options.unfold_volume_m3 = 0.0;
  }
  const std::size_t nn = g.dataset("nodes", H5T_NATIVE_DOUBLE, H5T_FLOAT, 3, i.mesh.nodes, 3);
  g.dataset("tets", H5T_NATIVE_UINT32, H5T_INTEGER, 4, i.mesh.tets, 4);
  g.dataset("boundary_nodes", H5T_NATIVE_UINT32, H5T_INTEGER, 0, i.boundary_nodes, 1);
  if (g.dataset("unit_displacement", H5T_NATIVE_DOUBLE, H5T_FLOAT, 3, i.unit_displacement, 3) != nn) {
    r.refuse("dataset /interior/unit_displacement has another number of rows than /interior/nodes");
  }
  for (std::size_t t = 0; t < i.mesh.tets.size(); ++t) {
    for (const std::uint32_t v : i.mesh.tets[t]) {
      if (v >= nn) r.refuse(fmt::format("interior tetrahedron {} names node {} of {}", t, v, nn));
    }
  }
  for (const std::uint32_t v : i.boundary_nodes) {
    if (v >= nn) r.refuse(fmt::format("interior boundary node {} of {}", v, nn));
  }
  i.report.boundary_nodes = i.boundary_nodes.size();
  i.report.free_nodes = nn - std::min(nn, i.boundary_nodes.size());
  return out;
}

FieldRecord read_file(const std::filesystem::path& path) {
  const std::string shown = path.string();
  Reader r{shown};
  check_seal(path, [&](const std::string& why) { r.refuse(why); });
  std::error_code ec;
  const std::uint64_t file_bytes = std::filesystem::file_size(path, ec);
  if (!ec) r.max_value_bytes = 1100 * file_bytes + 65536;
  const htri_t is_hdf5 = H5Fis_hdf5(path.c_str());
  if (is_hdf5 <= 0) r.refuse("not an HDF5 file");
  model::Hdf5Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file.ok()) r.refuse("cannot open it as HDF5 (truncated or damaged)");
  r.root = file.get();
  if (H5Aexists(r.root, "format") <= 0) r.refuse("no 'format' attribute (an HDF5 file from elsewhere)");
  if (r.string_attribute("format") != kFormat) r.refuse("its format is not '" + std::string(kFormat) + "'");
  const int version = r.number_attribute<int>("format_version", H5T_NATIVE_INT, H5T_INTEGER);
  if (version != kFormatVersion)
    r.refuse("format version " + std::to_string(version) + ", this pneuma reads version " +
             std::to_string(kFormatVersion));

  FieldRecord m;
  FieldMetadata& d = m.metadata;
  d.pneuma_version = r.string_attribute("pneuma_version");
  d.key = r.string_attribute("key");
  const std::string stored_checksum = r.string_attribute("checksum");
  d.tissue = r.string_attribute("tissue");
  d.solver = r.string_attribute("solver");
  d.tolerance = r.number_attribute<double>("tolerance", H5T_NATIVE_DOUBLE, H5T_FLOAT);
  d.clique_hops = r.number_attribute<int>("clique_hops", H5T_NATIVE_INT, H5T_INTEGER);
  d.path_rule = r.string_attribute("path_rule");
  d.shots = r.number_attribute<std::uint64_t>("shots", H5T_NATIVE_UINT64, H5T_INTEGER);
  d.iterations = r.number_attribute<std::uint64_t>("iterations", H5T_NATIVE_UINT64, H5T_INTEGER);
  d.residual = r.number_attribute<double>("residual", H5T_NATIVE_DOUBLE, H5T_FLOAT);

  {
    if (H5Lexists(r.root, "field", H5P_DEFAULT) <= 0) r.refuse("no group /field");
    model::Hdf5Handle group(H5Gopen2(r.root, "field", H5P_DEFAULT), H5Gclose);
    if (!group.ok()) r.refuse("cannot open group /field");
    const Reader field{shown, group.get(), r.max_value_bytes};
    d.area_unit_m2 = field.number_attribute<double>("area_unit_m2", H5T_NATIVE_DOUBLE, H5T_FLOAT);
  }
  const std::size_t nv = r.dataset("/rest/positions", H5T_NATIVE_DOUBLE, H5T_FLOAT, 3, m.rest.vertices, 3);
  r.dataset("/rest/triangles", H5T_NATIVE_UINT32, H5T_INTEGER, 3, m.rest.triangles, 3);
  const std::array<std::pair<const char*, std::size_t>, 3> per_vertex{
      {{"/field/unit_displacement",
        r.dataset("/field/unit_displacement", H5T_NATIVE_DOUBLE, H5T_FLOAT, 3, m.unit_displacement, 3)},
       {"/field/force", r.dataset("/field/force", H5T_NATIVE_DOUBLE, H5T_FLOAT, 0, m.force, 1)},
       {"/field/shear_modulus_pa",
        r.dataset("/field/shear_modulus_pa", H5T_NATIVE_DOUBLE, H5T_FLOAT, 0, m.shear_modulus_pa, 1)}}};
  for (const auto& [name, rows] : per_vertex) {
    if (rows != nv)
      r.refuse(std::string("dataset ") + name + " has " + std::to_string(rows) + " rows for " + std::to_string(nv) +
               " vertices");
  }
  for (std::size_t t = 0; t < m.rest.triangles.size(); ++t) {
    for (std::uint32_t v : m.rest.triangles[t]) {
      if (v >= nv)
        r.refuse("triangle " + std::to_string(t) + " names vertex " + std::to_string(v) + " of " + std::to_string(nv));
    }
  }
  if (H5Lexists(r.root, "interior", H5P_DEFAULT) > 0) m.interior = read_interior(r);
  if (checksum(m) != stored_checksum) r.refuse("checksum mismatch (the file was edited or damaged)");
  return m;
}

// Every field option that changes the result, in a fixed order (both cache keys).
void hash_options(Hasher& h, const field::FieldOptions& o) {
  h.text(field::solver_name(o.solver));
  h.value(o.tolerance);
  h.value(static_cast<std::int64_t>(o.clique_hops));
  h.text(rule_name(o.path_rule));
  h.value(o.area_unit);
  h.text(field::direction_name(o.direction));
  h.value(static_cast<std::uint64_t>(o.load.size()));
  h.bytes(o.load.data(), o.load.size() * sizeof(double));
  h.value(o.magnitude_smoothing);
  if (o.sliding.active()) {  // absent: the keys of fields made before the slide existed stay valid
    h.text("sliding");
    h.value(o.sliding.caudal);
    h.value(o.sliding.anterior);
    h.value(o.sliding.mediastinal);
    h.value(o.sliding.exponent);
    h.value(o.sliding.base);
    if (o.sliding.blur_m != 0.0) h.value(o.sliding.blur_m);  // absent: earlier keys stay valid
    h.value(o.direction_smoothing);
    h.bytes(o.axes.up.data(), 3 * sizeof(double));
    h.bytes(o.axes.anterior.data(), 3 * sizeof(double));
  }
  if (o.heart.active()) {  // absent: the keys of fields made before the heart's descent stay valid
    h.text("heart");
    h.value(o.heart.descent);
    h.value(o.heart.top);
    h.text("under the diaphragm");      // the face under the dome's slope descends too (field/heart.h)
    h.text("the costophrenic margin");  // and, without a slide, the margin moves as one (field/heart.h)
    h.text("the thin lung's stretch");  // and no thin part stretches past the lung's bound (field/thin_lung.h)
    h.value(o.direction_smoothing);
    h.bytes(o.axes.up.data(), 3 * sizeof(double));
  }
  if (o.direction != field::DirectionKind::vertex_normal) {
    h.value(o.direction_smoothing);
    h.bytes(o.axes.up.data(), 3 * sizeof(double));
    h.bytes(o.axes.anterior.data(), 3 * sizeof(double));
  }
}

}  // namespace

std::string field_key(const mesh::TriangleMesh& rest, std::span<const double> mu, const std::string& tissue_name,
                      const field::FieldOptions& o) {
  Hasher h;
  h.text("pneuma-field-key/2");  // 2: wider region steps, magnitude smoothing (docs/realism.md)
  h.text(PNEUMA_VERSION);
  h.value(static_cast<std::uint64_t>(rest.vertices.size()));
  h.bytes(rest.vertices.data(), rest.vertices.size() * sizeof(Eigen::Vector3d));
  h.value(static_cast<std::uint64_t>(rest.triangles.size()));
  h.bytes(rest.triangles.data(), rest.triangles.size() * sizeof(mesh::Triangle));
  h.bytes(mu.data(), mu.size() * sizeof(double));
  h.text(tissue_name);
  hash_options(h, o);
  return h.hex();
}

std::string field_key(const mesh::TriangleMesh& rest, const field::TissueFieldInputs& inputs) {
  return field_key(rest, inputs.shear_modulus_pa, inputs.tissue_name, inputs.options);
}

FieldRecord field_record(const mesh::TriangleMesh& rest, const field::TissueFieldInputs& inputs,
                         const field::ElastostaticField& field) {
  FieldRecord m;
  m.rest = rest;
  m.unit_displacement = field.unit_displacement;
  m.force = field.force;
  m.shear_modulus_pa = inputs.shear_modulus_pa;
  FieldMetadata& d = m.metadata;
  d.key = field_key(rest, inputs);
  d.pneuma_version = PNEUMA_VERSION;
  d.tissue = inputs.tissue_name;
  d.solver = field::solver_name(inputs.options.solver);
  d.tolerance = inputs.options.tolerance;
  d.clique_hops = inputs.options.clique_hops;
  d.path_rule = rule_name(inputs.options.path_rule);
  d.area_unit_m2 = inputs.options.area_unit;
  d.shots = field.report.shots;
  d.iterations = field.report.iterations;
  d.residual = field.report.residual;
  return m;
}

FieldRecord compute_field_record(const mesh::TriangleMesh& rest, const field::TissueFieldInputs& inputs) {
  return field_record(rest, inputs, field::compute_field(rest, inputs));
}

FieldRecord compute_field_record(const mesh::TriangleMesh& rest, const field::Tissue& tissue,
                                 const field::FieldOptions& options) {
  return compute_field_record(rest, field::tissue_field_inputs(rest, tissue, options));
}

// The Debian HDF5 library is built without its thread-safe option: two lungs compiled side by
// side (compile.cpp) take turns with their cache files.
namespace {
std::mutex& hdf5_mutex() {
  static std::mutex m;
  return m;
}
}  // namespace

void save_field(const std::filesystem::path& path, const FieldRecord& model) {
  const std::lock_guard lock(hdf5_mutex());
  model::silence_hdf5_errors();
  write_atomically(path, [&](const std::filesystem::path& tmp) {
    write_file(tmp, path.string(), model);  // closes the file
    seal_file(tmp, path.string());
  });
}

FieldRecord load_field(const std::filesystem::path& path) {
  const std::lock_guard lock(hdf5_mutex());
  model::silence_hdf5_errors();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw IoError(path.string() + ": cannot open file");
  return read_file(path);
}

std::string source_field_key(const std::string& source, const std::string& tissue_name, const field::FieldOptions& o) {
  Hasher h;
  h.text("pneuma-field-source-key/1");
  h.text(PNEUMA_VERSION);
  h.text(source);
  h.text(tissue_name);
  hash_options(h, o);
  return h.hex();
}

std::string interior_key(const std::string& field_key, double edge_m, const field::InteriorOptions& options,
                         mesh::TetMesher mesher) {
  Hasher h;
  h.text("pneuma-interior-key/1");
  h.text(PNEUMA_VERSION);
  h.text(field_key);
  h.value(edge_m);
  h.text(field::interior_model_name(options.model));
  h.value(options.poisson_ratio);
  h.value(options.tolerance);
  h.value(static_cast<std::uint64_t>(options.max_iterations));
  h.value(options.unfold_volume_m3);
  if (options.unfold_deflation_m3 > 0.0) h.value(options.unfold_deflation_m3);  // earlier keys unchanged
  // Each direction's unfolding keeps the other's breaths (#45 at 2 mm): an inside cached before is
  // recomputed where both unfold (the only case it changes).
  if (options.unfold_deflation_m3 > 0.0 && options.unfold_volume_m3 > 0.0) h.text("kept-both-directions");
  // Nor raise the lighter breaths' largest Jacobian (#45, the phantom at 2 mm): any unfolding
  // cached before is recomputed.
  if (options.unfold_deflation_m3 > 0.0 || options.unfold_volume_m3 > 0.0) h.text("kept-ceiling");
  if (mesher != mesh::TetMesher::delaunay) h.text(mesh::tet_mesher_name(mesher));
  return h.hex();
}

std::string source_key(const std::vector<std::filesystem::path>& files, const std::string& options_text) {
  Hasher h;
  h.text("pneuma-source/1");
  // A folder (a mask folder, a DICOM series with its RTSTRUCT): its files' names and bytes, in
  // name order; a file alone: its bytes (the keys of earlier runs unchanged).
  std::vector<std::pair<std::filesystem::path, bool>> inputs;  // (file, named)
  for (const auto& file : files) {
    std::error_code ec;
    if (!std::filesystem::is_directory(file, ec)) {
      inputs.emplace_back(file, false);
      continue;
    }
    std::vector<std::filesystem::path> inside;
    for (const auto& entry : std::filesystem::directory_iterator(file, ec)) {
      if (entry.is_regular_file()) inside.push_back(entry.path());
    }
    std::sort(inside.begin(), inside.end());
    for (const auto& f : inside) inputs.emplace_back(f, true);
  }
  for (const auto& [file, named] : inputs) {
    if (named) h.text(file.filename().string());
    std::ifstream in(file, std::ios::binary);
    if (!in) throw IoError(file.string() + ": cannot open file");
    std::vector<char> buffer(1 << 20);
    while (in) {
      in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
      h.bytes(buffer.data(), static_cast<std::size_t>(in.gcount()));
    }
    if (in.bad()) throw IoError(file.string() + ": cannot read file");
  }
  h.text(options_text);
  return h.hex();
}

namespace {

// The model cached at `path`, if there is one. A damaged or foreign file (truncated, edited,
// not HDF5, another format) is derived data, not the user's: `discarded` says why it is not
// used, and the caller recomputes and replaces it. A file that cannot be read at all
// (permissions) is still an error: replacing it would fail too.
std::optional<FieldRecord> load_cache(const std::filesystem::path& path, std::string& discarded) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return std::nullopt;
  try {
    return load_field(path);
  } catch (const InputError& e) {
    discarded = e.what();
    return std::nullopt;
  }
}

}  // namespace

CacheLookup load_or_compute(const std::filesystem::path& path, const std::string& key,
                            const std::function<FieldRecord()>& compute, const std::filesystem::path& save_to) {
  std::string discarded;
  if (std::optional<FieldRecord> cached = load_cache(path, discarded); cached && cached->metadata.key == key) {
    if (!save_to.empty() && save_to != path) {
      std::error_code ec;
      std::filesystem::copy_file(path, save_to, std::filesystem::copy_options::overwrite_existing, ec);
      if (ec) throw IoError(save_to.string() + ": cannot copy the field cache " + path.string() + ": " + ec.message());
    }
    return {std::move(*cached), true, {}, nullptr};
  }
  CacheLookup out{compute(), false, std::move(discarded), nullptr};
  out.record.metadata.key = key;
  save_field(save_to.empty() ? path : save_to, out.record);
  return out;
}

CacheLookup load_or_compute(const std::filesystem::path& path, const mesh::TriangleMesh& rest,
                            const field::Tissue& tissue, const field::FieldOptions& options,
                            const std::filesystem::path& save_to) {
  const field::TissueFieldInputs inputs = field::tissue_field_inputs(rest, tissue, options);
  CacheLookup out = load_or_compute(
      path, field_key(rest, inputs), [&] { return compute_field_record(rest, inputs); }, save_to);
  out.regions = inputs.options.regions;
  return out;
}

}  // namespace pneuma::model
