// Sequences of time points (sequence_io.h): headers written here (NRRD's text fields, NIfTI-1's
// 348 bytes at their offsets), the data through zlib's gz stream. Not through ITK: its writers
// take a whole image at once, and a sequence must not hold every time point in memory.
#include "pneuma/voxels/sequence_io.h"

#include <fmt/format.h>
#include <zlib.h>

#include <array>
#include <cmath>
#include <cstring>
#include <fstream>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"

namespace pneuma::voxels {
namespace fs = std::filesystem;
namespace {

std::size_t bytes_per_voxel(SequenceVoxel voxel) {
  switch (voxel) {
    case SequenceVoxel::uint8: return 1;
    case SequenceVoxel::int16: return 2;
    case SequenceVoxel::int32:
    case SequenceVoxel::float32: return 4;
    case SequenceVoxel::vector3: return 12;
  }
  return 0;
}

const char* nrrd_type(SequenceVoxel voxel) {
  switch (voxel) {
    case SequenceVoxel::uint8: return "uchar";
    case SequenceVoxel::int16: return "short";
    case SequenceVoxel::int32: return "int";
    case SequenceVoxel::float32:
    case SequenceVoxel::vector3: return "float";
  }
  return "";
}

// NIfTI-1 datatype codes and bits per component.
std::pair<std::int16_t, std::int16_t> nifti_type(SequenceVoxel voxel) {
  switch (voxel) {
    case SequenceVoxel::uint8: return {2, 8};
    case SequenceVoxel::int16: return {4, 16};
    case SequenceVoxel::int32: return {8, 32};
    case SequenceVoxel::float32:
    case SequenceVoxel::vector3: return {16, 32};
  }
  return {0, 0};
}

// A number as NRRD and Slicer read it back exactly (no "-0").
std::string number(double x) { return fmt::format("{:.17g}", x + 0.0); }

std::string nrrd_header(const SequenceSpec& spec) {
  const bool vector = spec.voxel == SequenceVoxel::vector3;
  const Grid& g = spec.grid;
  const std::size_t n = spec.index_values.size();
  std::string h = "NRRD0005\n# Complete NRRD file format specification at:\n"
                  "# http://teem.sourceforge.net/nrrd/format.html\n";
  h += fmt::format("type: {}\ndimension: {}\nspace: left-posterior-superior\n", nrrd_type(spec.voxel), vector ? 5 : 4);
  h += fmt::format("sizes: {}{} {} {} {}\n", vector ? "3 " : "", g.size[0], g.size[1], g.size[2], n);
  h += "space directions: ";
  if (vector) h += "none ";
  for (int a = 0; a < 3; ++a)
    h += fmt::format("({},{},{}) ", number(g.ijk_to_lps(0, a) * 1e3), number(g.ijk_to_lps(1, a) * 1e3),
                     number(g.ijk_to_lps(2, a) * 1e3));
  h += "none\n";
  h += fmt::format("kinds: {}domain domain domain list\n", vector ? "vector " : "");
  h += fmt::format("labels: {}\"\" \"\" \"\" \"{}\"\n", vector ? "\"\" " : "", spec.index_name);
  h += fmt::format("units: {}\"\" \"\" \"\" \"{}\"\n", vector ? "\"\" " : "", spec.index_unit);
  h += "endian: little\nencoding: gzip\n";
  h += fmt::format("space origin: ({},{},{})\n", number(g.ijk_to_lps(0, 3) * 1e3), number(g.ijk_to_lps(1, 3) * 1e3),
                   number(g.ijk_to_lps(2, 3) * 1e3));
  if (vector) h += "measurement frame: (1,0,0) (0,1,0) (0,0,1)\n";
  // Slicer's sequence fields: the list axis is axis 3 of the range axes (its Sequences docs).
  h += "axis 3 index type:=numeric\naxis 3 index values:=";
  for (std::size_t i = 0; i < n; ++i) {
    if (i > 0) h += ' ';
    h += fmt::format("{:.6g}", spec.index_values[i]);
  }
  h += "\n";
  if (vector) {
    h += fmt::format("displacement field type:={}\nintent_code:=1006\n", spec.displacement_field_type);
  } else {
    h += fmt::format("DataNodeClassName:={}\n",
                     spec.label_map ? "vtkMRMLLabelMapVolumeNode" : "vtkMRMLScalarVolumeNode");
  }
  return h + "\n";
}

template <typename T>
void put(std::array<char, 352>& header, std::size_t offset, T value) {
  std::memcpy(header.data() + offset, &value, sizeof(T));  // little-endian hosts only (as ITK's writer)
}

std::array<char, 352> nifti_header(const SequenceSpec& spec) {
  const bool vector = spec.voxel == SequenceVoxel::vector3;
  const Grid& g = spec.grid;
  const auto n = static_cast<std::int16_t>(spec.index_values.size());
  std::array<char, 352> h{};
  put<std::int32_t>(h, 0, 348);
  const std::array<std::int16_t, 8> dim{static_cast<std::int16_t>(vector ? 5 : 4),
                                        static_cast<std::int16_t>(g.size[0]),
                                        static_cast<std::int16_t>(g.size[1]),
                                        static_cast<std::int16_t>(g.size[2]),
                                        n,
                                        static_cast<std::int16_t>(vector ? 3 : 1),
                                        1,
                                        1};
  for (std::size_t i = 0; i < 8; ++i) put<std::int16_t>(h, 40 + 2 * i, dim[i]);
  // NIFTI_INTENT_VECTOR with LPS components (ITK 5.2's layout), or the standard's DISPVECT in RAS.
  if (vector) put<std::int16_t>(h, 68, spec.nifti_ras ? std::int16_t{1006} : std::int16_t{1007});
  const auto [datatype, bits] = nifti_type(spec.voxel);
  put<std::int16_t>(h, 70, datatype);
  put<std::int16_t>(h, 72, bits);
  // pixdim: qfac, the spacing (mm), the index step when even (else 1).
  const Eigen::Vector3d spacing = g.spacing_m() * 1e3;
  double step = 1.0;
  if (spec.index_values.size() >= 2) {
    step = spec.index_values[1] - spec.index_values[0];
    for (std::size_t i = 2; i < spec.index_values.size(); ++i) {
      if (std::abs(spec.index_values[i] - spec.index_values[i - 1] - step) > 1e-9 * (1 + std::abs(step))) step = 1.0;
    }
    if (!(step > 0.0)) step = 1.0;
  }
  const std::array<float, 8> pixdim{1.0f,
                                    static_cast<float>(spacing.x()),
                                    static_cast<float>(spacing.y()),
                                    static_cast<float>(spacing.z()),
                                    static_cast<float>(step),
                                    1.0f,
                                    1.0f,
                                    1.0f};
  for (std::size_t i = 0; i < 8; ++i) put<float>(h, 76 + 4 * i, pixdim[i]);
  put<float>(h, 108, 352.0f);                                                // vox_offset
  put<float>(h, 112, 1.0f);                                                  // scl_slope
  put<char>(h, 123, static_cast<char>(spec.index_unit == "s" ? 2 | 8 : 2));  // mm (and s)
  const std::string descrip =
      fmt::format("pneuma sequence, axis 4: {} ({})", spec.index_name, spec.index_unit).substr(0, 79);
  std::memcpy(h.data() + 148, descrip.data(), descrip.size());
  put<std::int16_t>(h, 254, 1);  // sform_code: scanner
  // The sform: RAS+ in mm (LPS with x and y negated).
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) {
      const double sign = r < 2 ? -1.0 : 1.0;
      put<float>(h, 280 + 16 * static_cast<std::size_t>(r) + 4 * static_cast<std::size_t>(c),
                 static_cast<float>(sign * g.ijk_to_lps(r, c) * 1e3 + 0.0));
    }
  std::memcpy(h.data() + 344, "n+1\0", 4);
  return h;
}

void gz_write(gzFile out, const void* data, std::size_t bytes, const fs::path& path) {
  const char* p = static_cast<const char*>(data);
  while (bytes > 0) {
    const unsigned chunk = static_cast<unsigned>(std::min<std::size_t>(bytes, 1u << 30));
    if (gzwrite(out, p, chunk) != static_cast<int>(chunk)) throw IoError(path.string() + ": cannot write (disk full?)");
    p += chunk;
    bytes -= chunk;
  }
}

}  // namespace

SequenceVoxel label_voxel(std::int32_t min, std::int32_t max) {
  min = std::min(min, 0);  // warped maps hold 0 where nothing lands
  if (min >= 0 && max <= 255) return SequenceVoxel::uint8;
  if (min >= -32768 && max <= 32767) return SequenceVoxel::int16;
  return SequenceVoxel::int32;
}

struct SequenceWriter::State {
  fs::path path;
  SequenceFormat format;
  SequenceSpec spec;
  std::size_t item_bytes = 0, items = 0;
  PendingFile file;
  gzFile gz = nullptr;
  std::vector<std::unique_ptr<PendingFile>> components;  // a 4D NIfTI DVF's, one raw file each
  std::vector<std::ofstream> component_streams;

  State(const fs::path& p, SequenceFormat f, SequenceSpec s) : path(p), format(f), spec(std::move(s)), file(p) {}
  ~State() {
    if (gz != nullptr) gzclose(gz);
  }
};

SequenceWriter::SequenceWriter(const fs::path& path, SequenceFormat format, SequenceSpec spec) {
  if (spec.index_values.empty()) throw ValueError(path.string() + ": a sequence needs at least one item");
  if (spec.index_values.size() > 32767) throw ValueError(path.string() + ": more than 32767 items");
  if (spec.voxel == SequenceVoxel::vector3 && spec.displacement_field_type.empty())
    throw ValueError(path.string() + ": a DVF sequence needs its direction (resampling or modeling)");
  state_ = std::make_unique<State>(path, format, std::move(spec));
  State& s = *state_;
  s.item_bytes = bytes_per_voxel(s.spec.voxel) * s.spec.grid.voxel_count();
  const fs::path& tmp = s.file.temporary();
  if (format == SequenceFormat::slicer_nrrd) {
    {
      std::ofstream out(tmp, std::ios::binary);
      out << nrrd_header(s.spec);
      if (!out) throw IoError(path.string() + ": cannot write");
    }
    s.gz = gzopen(tmp.c_str(), "ab6");  // the data: a gzip stream after the text header
  } else {
    s.gz = gzopen(tmp.c_str(), "wb6");
    if (s.gz != nullptr) {
      const std::array<char, 352> header = nifti_header(s.spec);
      gz_write(s.gz, header.data(), header.size(), path);
    }
    if (s.spec.voxel == SequenceVoxel::vector3) {
      for (int c = 0; c < 3; ++c) {
        s.components.push_back(std::make_unique<PendingFile>(fs::path(path.string() + fmt::format(".component{}", c))));
        s.component_streams.emplace_back(s.components.back()->temporary(), std::ios::binary);
      }
    }
  }
  if (s.gz == nullptr) throw IoError(path.string() + ": cannot write");
}

SequenceWriter::~SequenceWriter() = default;

void SequenceWriter::append(const void* values, std::size_t bytes) {
  State& s = *state_;
  if (bytes != s.item_bytes)
    throw ValueError(fmt::format("{}: an item of {} bytes; expected {}", s.path.string(), bytes, s.item_bytes));
  if (s.items == s.spec.index_values.size())
    throw ValueError(fmt::format("{}: more than the {} items announced", s.path.string(), s.items));
  if (s.format == SequenceFormat::nifti_4d && s.spec.voxel == SequenceVoxel::vector3) {
    // NIfTI's vector component is its slowest axis: each component to its own file.
    const auto* v = static_cast<const float*>(values);
    const std::size_t n = s.spec.grid.voxel_count();
    std::vector<float> component(n);
    for (std::size_t c = 0; c < 3; ++c) {
      const float sign = s.spec.nifti_ras && c < 2 ? -1.0f : 1.0f;  // RAS: x and y negated
      for (std::size_t i = 0; i < n; ++i) component[i] = sign * v[3 * i + c];
      s.component_streams[c].write(reinterpret_cast<const char*>(component.data()),
                                   static_cast<std::streamsize>(n * sizeof(float)));
      if (!s.component_streams[c]) throw IoError(s.path.string() + ": cannot write (disk full?)");
    }
  } else {
    gz_write(s.gz, values, bytes, s.path);
  }
  ++s.items;
}

fs::path SequenceWriter::finish() {
  State& s = *state_;
  if (s.items != s.spec.index_values.size())
    throw ValueError(fmt::format("{}: {} items of {}", s.path.string(), s.items, s.spec.index_values.size()));
  if (!s.components.empty()) {
    std::vector<char> buffer(1 << 20);
    for (std::size_t c = 0; c < 3; ++c) {
      s.component_streams[c].close();
      std::ifstream in(s.components[c]->temporary(), std::ios::binary);
      while (in) {
        in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
        if (in.gcount() > 0) gz_write(s.gz, buffer.data(), static_cast<std::size_t>(in.gcount()), s.path);
      }
    }
    s.components.clear();  // removes the temporaries
  }
  const int closed = gzclose(s.gz);
  s.gz = nullptr;
  if (closed != Z_OK) throw IoError(s.path.string() + ": cannot write (disk full?)");
  s.file.commit();
  return s.path;
}

}  // namespace pneuma::voxels
