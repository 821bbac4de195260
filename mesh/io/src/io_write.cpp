// write_mesh(): small hand-written writers (assimp's exporter is not atomic and rewrites the
// numbering); every file goes through pneuma::write_stream_atomically.
#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cstring>
#include <ostream>
#include <string>

#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/mesh/io/mesh_io.h"

namespace pneuma::mesh {
namespace {

// Output in chunks so that a multi-million-triangle mesh needs no second full copy in memory.
class Buffer {
 public:
  explicit Buffer(std::ostream& out) : out_(out) { data_.reserve(kChunk + 256); }
  ~Buffer() = default;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;

  void text(std::string_view s) {
    data_.append(s);
    maybe_flush();
  }
  void number(float value) {
    char tmp[32];
    // Shortest representation that reads back as the same float.
    const auto r = std::to_chars(tmp, tmp + sizeof tmp, value);
    data_.append(tmp, r.ptr);
  }
  void number(std::uint64_t value) {
    char tmp[24];
    const auto r = std::to_chars(tmp, tmp + sizeof tmp, value);
    data_.append(tmp, r.ptr);
  }
  template <typename T>
  void binary(T value) {
    static_assert(std::endian::native == std::endian::little, "binary writers assume a little-endian host");
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    data_.append(bytes, sizeof(T));
  }
  void maybe_flush() {
    if (data_.size() >= kChunk) flush();
  }
  void flush() {
    out_.write(data_.data(), static_cast<std::streamsize>(data_.size()));
    data_.clear();
  }

 private:
  static constexpr std::size_t kChunk = 1 << 20;
  std::ostream& out_;
  std::string data_;
};

// The text after "unit " in a file's header: a unit name where one fits, else a length.
std::string unit_label(double metres_per_unit) {
  for (const auto& [name, metres] : {std::pair{"m", 1.0}, {"cm", 1e-2}, {"mm", 1e-3}, {"um", 1e-6}}) {
    if (metres_per_unit == metres) return name;
  }
  return fmt::format("{:.17g} m", metres_per_unit);
}

std::array<float, 3> to_file(const Eigen::Vector3d& p, double metres_per_unit) {
  return {static_cast<float>(p.x() / metres_per_unit), static_cast<float>(p.y() / metres_per_unit),
          static_cast<float>(p.z() / metres_per_unit)};
}

void write_ply(std::ostream& out, const TriangleMesh& mesh, double unit, bool ascii) {
  Buffer b(out);
  b.text(ascii ? "ply\nformat ascii 1.0\n" : "ply\nformat binary_little_endian 1.0\n");
  b.text("comment written by pneuma\ncomment unit " + unit_label(unit) + "\nelement vertex ");
  b.number(std::uint64_t{mesh.vertices.size()});
  b.text("\nproperty float x\nproperty float y\nproperty float z\nelement face ");
  b.number(std::uint64_t{mesh.triangles.size()});
  b.text("\nproperty list uchar int vertex_indices\nend_header\n");
  for (const auto& v : mesh.vertices) {
    const auto p = to_file(v, unit);
    if (ascii) {
      b.number(p[0]), b.text(" "), b.number(p[1]), b.text(" "), b.number(p[2]), b.text("\n");
    } else {
      b.binary(p[0]), b.binary(p[1]), b.binary(p[2]), b.maybe_flush();
    }
  }
  for (const Triangle& t : mesh.triangles) {
    if (ascii) {
      b.text("3 "), b.number(std::uint64_t{t[0]}), b.text(" "), b.number(std::uint64_t{t[1]}), b.text(" ");
      b.number(std::uint64_t{t[2]}), b.text("\n");
    } else {
      b.binary(std::uint8_t{3});
      for (std::uint32_t v : t) b.binary(static_cast<std::int32_t>(v));
      b.maybe_flush();
    }
  }
  b.flush();
}

void write_obj(std::ostream& out, const TriangleMesh& mesh, double unit) {
  Buffer b(out);
  b.text("# written by pneuma\n# unit " + unit_label(unit) + "\n");
  for (const auto& v : mesh.vertices) {
    const auto p = to_file(v, unit);
    b.text("v "), b.number(p[0]), b.text(" "), b.number(p[1]), b.text(" "), b.number(p[2]), b.text("\n");
  }
  for (const Triangle& t : mesh.triangles) {
    b.text("f "), b.number(std::uint64_t{t[0]} + 1), b.text(" "), b.number(std::uint64_t{t[1]} + 1), b.text(" ");
    b.number(std::uint64_t{t[2]} + 1), b.text("\n");
  }
  b.flush();
}

std::array<float, 3> facet_normal(const TriangleMesh& mesh, const Triangle& t) {
  const Eigen::Vector3d n =
      (mesh.vertices[t[1]] - mesh.vertices[t[0]]).cross(mesh.vertices[t[2]] - mesh.vertices[t[0]]);
  const double len = n.norm();
  if (len == 0.0) return {0.0f, 0.0f, 0.0f};
  return {static_cast<float>(n.x() / len), static_cast<float>(n.y() / len), static_cast<float>(n.z() / len)};
}

void write_stl(std::ostream& out, const TriangleMesh& mesh, double unit, bool ascii) {
  Buffer b(out);
  if (ascii) {
    b.text("solid pneuma unit " + unit_label(unit) + "\n");
  } else {
    // The 80-byte header: the text, cut or padded with NULs (not a C string).
    std::string header = "binary STL written by pneuma, unit " + unit_label(unit);
    header.resize(80, '\0');
    b.text(header);
    b.binary(static_cast<std::uint32_t>(mesh.triangles.size()));
  }
  for (const Triangle& t : mesh.triangles) {
    const auto n = facet_normal(mesh, t);
    if (ascii) {
      b.text("facet normal "), b.number(n[0]), b.text(" "), b.number(n[1]), b.text(" "), b.number(n[2]);
      b.text("\n outer loop\n");
      for (std::uint32_t v : t) {
        const auto p = to_file(mesh.vertices[v], unit);
        b.text("  vertex "), b.number(p[0]), b.text(" "), b.number(p[1]), b.text(" "), b.number(p[2]), b.text("\n");
      }
      b.text(" endloop\nendfacet\n");
    } else {
      for (float c : n) b.binary(c);
      for (std::uint32_t v : t) {
        for (float c : to_file(mesh.vertices[v], unit)) b.binary(c);
      }
      b.binary(std::uint16_t{0});
      b.maybe_flush();
    }
  }
  if (ascii) b.text("endsolid pneuma\n");
  b.flush();
}

bool is_binary(FileFormat f) { return f == FileFormat::ply_binary || f == FileFormat::stl_binary; }

}  // namespace

FileFormat format_for_path(const std::filesystem::path& path, bool ascii) {
  std::string ext = path.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".ply") return ascii ? FileFormat::ply_ascii : FileFormat::ply_binary;
  if (ext == ".obj") return FileFormat::obj;
  if (ext == ".stl") return ascii ? FileFormat::stl_ascii : FileFormat::stl_binary;
  throw UsageError("pneuma: " + path.string() + ": cannot write '" + ext + "' files (expected .ply, .obj or .stl)");
}

const char* format_name(FileFormat format) {
  switch (format) {
    case FileFormat::ply_binary: return "binary PLY";
    case FileFormat::ply_ascii: return "ASCII PLY";
    case FileFormat::obj: return "OBJ";
    case FileFormat::stl_binary: return "binary STL";
    case FileFormat::stl_ascii: return "ASCII STL";
  }
  return "?";
}

void write_mesh(const std::filesystem::path& path, const TriangleMesh& mesh, const WriteOptions& options) {
  const FileFormat format = format_for_path(path, options.ascii);
  const double unit = options.metres_per_unit;
  write_stream_atomically(path, is_binary(format), [&](std::ostream& out) {
    switch (format) {
      case FileFormat::ply_binary: write_ply(out, mesh, unit, false); break;
      case FileFormat::ply_ascii: write_ply(out, mesh, unit, true); break;
      case FileFormat::obj: write_obj(out, mesh, unit); break;
      case FileFormat::stl_binary: write_stl(out, mesh, unit, false); break;
      case FileFormat::stl_ascii: write_stl(out, mesh, unit, true); break;
    }
  });
}

}  // namespace pneuma::mesh
