#pragma once
// The HDF5 plumbing shared by the field cache (model) and series.h5 (outputs): an owning handle
// and a writer of untimed groups, datasets and attributes. HDF5 stays inside those two targets.
#include <hdf5.h>

#include <algorithm>
#include <array>
#include <string>

#include "pneuma/core/error.h"

namespace pneuma::model {

// Owns one HDF5 identifier and closes it with the matching function.
class Hdf5Handle {
 public:
  Hdf5Handle(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  ~Hdf5Handle() {
    if (id_ >= 0) close_(id_);
  }
  Hdf5Handle(Hdf5Handle&& other) noexcept : id_(other.id_), close_(other.close_) { other.id_ = -1; }
  Hdf5Handle(const Hdf5Handle&) = delete;
  Hdf5Handle& operator=(const Hdf5Handle&) = delete;
  Hdf5Handle& operator=(Hdf5Handle&&) = delete;
  hid_t get() const { return id_; }
  operator hid_t() const { return id_; }
  bool ok() const { return id_ >= 0; }
  // Gives up ownership (for an object that outlives this scope, closed by its new owner).
  hid_t release() {
    const hid_t id = id_;
    id_ = -1;
    return id;
  }

 private:
  hid_t id_;
  herr_t (*close_)(hid_t);
};

// HDF5 reports through exceptions here, not by printing its error stack on stderr.
inline void silence_hdf5_errors() { H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); }

// Writes objects into an open file; any failure is an IoError "<file>: cannot write <what>".
// Nothing it creates records a modification time: the same inputs write the same bytes.
struct Hdf5Writer {
  std::string file;
  [[noreturn]] void fail(const std::string& what) const { throw IoError(file + ": cannot write " + what); }
  void check(herr_t status, const std::string& what) const {
    if (status < 0) fail(what);
  }

  void string_attribute(hid_t object, const char* name, const std::string& value) const {
    Hdf5Handle type(H5Tcopy(H5T_C_S1), H5Tclose);
    check(H5Tset_size(type.get(), std::max<std::size_t>(1, value.size())), name);
    check(H5Tset_strpad(type.get(), H5T_STR_NULLPAD), name);
    Hdf5Handle space(H5Screate(H5S_SCALAR), H5Sclose);
    Hdf5Handle attr(H5Acreate2(object, name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
    if (!attr.ok()) fail(name);
    const std::string padded = value.empty() ? std::string(1, '\0') : value;
    check(H5Awrite(attr.get(), type.get(), padded.data()), name);
  }
  template <typename T>
  void number_attribute(hid_t object, const char* name, hid_t file_type, hid_t memory_type, T value) const {
    Hdf5Handle space(H5Screate(H5S_SCALAR), H5Sclose);
    Hdf5Handle attr(H5Acreate2(object, name, file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
    if (!attr.ok()) fail(name);
    check(H5Awrite(attr.get(), memory_type, &value), name);
  }
  // A 1-D (columns == 0) or 2-D dataset; `units` (e.g. "m") becomes its `units` attribute.
  // `compress`: shuffle + deflate at `level` in one chunk (zlib is deterministic: same data, same
  // bytes); otherwise contiguous.
  void dataset(hid_t parent, const char* name, hid_t file_type, hid_t memory_type, const void* data, hsize_t rows,
               hsize_t columns, const char* units = nullptr, bool compress = false,
               unsigned level = kDeflateLevel) const {
    const std::array<hsize_t, 2> dims{rows, columns};
    const int rank = columns == 0 ? 1 : 2;
    Hdf5Handle space(H5Screate_simple(rank, dims.data(), nullptr), H5Sclose);
    Hdf5Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
    check(H5Pset_obj_track_times(dcpl.get(), 0), name);  // no timestamps: same inputs, same bytes
    if (compress && rows > 0) {
      check(H5Pset_chunk(dcpl.get(), rank, dims.data()), name);
      check(H5Pset_shuffle(dcpl.get()), name);
      check(H5Pset_deflate(dcpl.get(), level), name);
    }
    Hdf5Handle set(H5Dcreate2(parent, name, file_type, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT), H5Dclose);
    if (!set.ok()) fail(name);
    if (rows > 0) check(H5Dwrite(set.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), name);
    if (units != nullptr) string_attribute(set.get(), "units", units);
  }
  static constexpr unsigned kDeflateLevel = 4;
  Hdf5Handle group(hid_t parent, const char* name) const {
    Hdf5Handle gcpl(H5Pcreate(H5P_GROUP_CREATE), H5Pclose);
    check(H5Pset_obj_track_times(gcpl.get(), 0), name);
    Hdf5Handle g(H5Gcreate2(parent, name, H5P_DEFAULT, gcpl.get(), H5P_DEFAULT), H5Gclose);
    if (!g.ok()) fail(name);
    return g;
  }
};

}  // namespace pneuma::model
