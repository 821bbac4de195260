// read_mesh(): assimp does the parsing; pneuma checks what assimp lets through (empty files,
// truncated binary STL, non-finite coordinates, files with no triangles) and merges vertices.
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "io_ply.h"
#include "io_vtk.h"
#include "pneuma/core/error.h"
#include "pneuma/core/paths.h"
#include "pneuma/core/units.h"
#include "pneuma/mesh/io/mesh_io.h"

namespace pneuma::mesh {
namespace {

static_assert(sizeof(ai_real) == sizeof(float), "vertex merging assumes assimp's single-precision build");

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::string read_prefix(const std::filesystem::path& path, std::size_t bytes) {
  std::ifstream in(path, std::ios::binary);
  std::string s(bytes, '\0');
  in.read(s.data(), static_cast<std::streamsize>(bytes));
  s.resize(static_cast<std::size_t>(in.gcount()));
  return s;
}

// Assimp reads a binary STL whose triangles stop short of the header's count without a word
// (or with a message that does not say why), so check the size against the header first.
void check_binary_stl(const std::filesystem::path& path, std::uintmax_t size) {
  const std::string head = read_prefix(path, 84);
  std::size_t first = 0;
  while (first < head.size() && std::isspace(static_cast<unsigned char>(head[first]))) ++first;
  const bool says_solid = lower(head.substr(first, 5)) == "solid";
  if (size < 84) {
    if (says_solid) return;  // a short ASCII STL: assimp's parser judges it
    throw InputError(path.string() + ": not an STL file: " + std::to_string(size) +
                     " bytes, less than the 84-byte header of a binary STL");
  }
  std::uint32_t count = 0;
  std::memcpy(&count, head.data() + 80, 4);
  if constexpr (std::endian::native == std::endian::big) count = __builtin_bswap32(count);
  const std::uintmax_t expected = 84 + 50 * std::uintmax_t{count};
  if (size == expected) return;  // binary, even when the header text starts with "solid"
  if (says_solid) return;        // ASCII
  if (size < expected) {
    throw InputError(path.string() + ": truncated binary STL: the header announces " + std::to_string(count) +
                     " triangles (" + std::to_string(expected) + " bytes), the file has " + std::to_string(size) +
                     " bytes");
  }
}

struct PositionHash {
  std::size_t operator()(const std::array<float, 3>& p) const noexcept {
    std::size_t h = 1469598103934665603ull;
    for (float f : p) {
      h ^= std::bit_cast<std::uint32_t>(f == 0.0f ? 0.0f : f);  // +0 and -0 are one position
      h *= 1099511628211ull;
    }
    return h;
  }
};

// The soup as assimp gives it: per mesh, its vertices (transformed, in file units) and its
// triangles indexing them, offset to one shared vertex array.
struct Soup {
  std::vector<std::array<float, 3>> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
  std::size_t skipped_primitives = 0;  // points and lines
};

void append_mesh(const aiMesh& m, const aiMatrix4x4& transform, Soup& soup) {
  const auto offset = static_cast<std::uint32_t>(soup.vertices.size());
  for (unsigned v = 0; v < m.mNumVertices; ++v) {
    const aiVector3D p = transform * m.mVertices[v];
    soup.vertices.push_back({p.x, p.y, p.z});
  }
  for (unsigned f = 0; f < m.mNumFaces; ++f) {
    const aiFace& face = m.mFaces[f];
    if (face.mNumIndices != 3) {  // aiProcess_Triangulate has split the polygons
      ++soup.skipped_primitives;
      continue;
    }
    soup.triangles.push_back({offset + face.mIndices[0], offset + face.mIndices[1], offset + face.mIndices[2]});
  }
}

void append_node(const aiScene& scene, const aiNode& node, const aiMatrix4x4& parent, Soup& soup) {
  const aiMatrix4x4 transform = parent * node.mTransformation;
  for (unsigned i = 0; i < node.mNumMeshes; ++i) append_mesh(*scene.mMeshes[node.mMeshes[i]], transform, soup);
  for (unsigned i = 0; i < node.mNumChildren; ++i) append_node(scene, *node.mChildren[i], transform, soup);
}

}  // namespace

double parse_length_unit(const std::string& text) {
  const bool has_number = !text.empty() && (std::isdigit(static_cast<unsigned char>(text[0])) || text[0] == '.');
  try {
    const double metres = units::parse(has_number ? text : "1 " + text, units::kind::length);
    if (!(metres > 0.0) || !std::isfinite(metres)) throw units::UnitError("must be positive");
    if (metres < units::kMinFileUnitM || metres > units::kMaxFileUnitM)
      throw UsageError("pneuma: --unit: expected a length unit from 1 nm to 1 km, got '" + text + "'");
    return metres;
  } catch (const units::UnitError&) {
    throw UsageError("pneuma: --unit: expected a length unit such as 'mm', 'cm' or 'm', got '" + text + "'");
  }
}

std::optional<double> recorded_unit(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::string head(4096, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  const std::string extension = lower(path.extension().string());
  // The header region where pneuma writes the unit, and the marker before it.
  std::string region, marker;
  if (head.rfind("ply", 0) == 0) {
    region = head.substr(0, head.find("end_header"));
    marker = "\ncomment unit ";
  } else if (extension == ".obj") {
    std::size_t end = 0;  // the leading comment lines
    while (end < head.size() && head[end] == '#') {
      const std::size_t newline = head.find('\n', end);
      end = newline == std::string::npos ? head.size() : newline + 1;
    }
    region.assign(1, '\n').append(head, 0, end);
    marker = "\n# unit ";
  } else if (extension == ".stl" && head.rfind("solid", 0) == 0) {
    region = head.substr(0, head.find('\n'));
    marker = " unit ";
  } else if (extension == ".stl") {
    region = head.substr(0, std::min<std::size_t>(80, head.size()));
    region = region.substr(0, region.find('\0'));
    marker = ", unit ";
  } else {
    return std::nullopt;
  }
  const std::size_t at = region.find(marker);
  if (at == std::string::npos) return std::nullopt;
  std::string text = region.substr(at + marker.size());
  text = text.substr(0, text.find_first_of("\r\n"));
  while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back()))) text.pop_back();
  const bool has_number = !text.empty() && (std::isdigit(static_cast<unsigned char>(text[0])) || text[0] == '.');
  try {
    const double metres = units::parse(has_number ? text : "1 " + text, units::kind::length);
    if (metres > 0.0 && std::isfinite(metres)) return metres;
  } catch (const units::UnitError&) {
  }
  throw InputError(path.string() + ": the recorded unit '" + text + "' is not a length such as 'mm' or 'm'");
}

TriangleMesh read_mesh(const std::filesystem::path& path, const ReadOptions& options) {
  const std::string name = path.string();
  require_readable_file(path);
  std::error_code ec;
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) throw IoError(name + ": cannot read: " + ec.message());
  if (size == 0) throw InputError(name + ": empty file");

  Assimp::Importer importer;
  const std::string extension = lower(path.extension().string());
  const double metres_per_unit =
      options.unit_from_file ? recorded_unit(path).value_or(options.metres_per_unit) : options.metres_per_unit;
  Soup soup;
  if (extension == ".vtk" || extension == ".vtp" || extension == ".ply") {
    std::string bytes = read_file_bytes(path);
    const detail::VtkSoup vtk = extension == ".vtk"   ? detail::read_vtk_legacy(name, std::move(bytes))
                                : extension == ".vtp" ? detail::read_vtk_xml(name, std::move(bytes))
                                                      : detail::read_ply(name, bytes);
    soup.vertices.reserve(vtk.points.size());
    for (const auto& p : vtk.points) {
      soup.vertices.push_back({static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2])});
    }
    soup.triangles = vtk.triangles;
  } else {
    if (extension.empty() || !importer.IsExtensionSupported(extension)) {
      throw InputError(
          name + ": unknown mesh format '" + extension +
          "' (expected a surface that assimp reads: .stl, .obj, .ply, .off, .gltf, .glb, ..., or VTK .vtk, .vtp)");
    }
    if (extension == ".stl") check_binary_stl(path, size);

    // Validate first (assimp's importers trust the file: a PLY face naming a vertex past the end
    // reached the next step and crashed it, found by fuzzing), then triangulate polygons;
    // no other post-processing (vertex joining is done below, exactly).
    const aiScene* scene = importer.ReadFile(name, 0);
    if (scene != nullptr && scene->mNumMeshes > 0) {  // none: "no triangles" below says it better
      scene = importer.ApplyPostProcessing(aiProcess_ValidateDataStructure | aiProcess_Triangulate);
    }
    if (scene == nullptr) throw InputError(name + ": cannot read as a mesh: " + importer.GetErrorString());

    if (scene->mRootNode != nullptr) {
      append_node(*scene, *scene->mRootNode, aiMatrix4x4{}, soup);
    } else {
      for (unsigned i = 0; i < scene->mNumMeshes; ++i) append_mesh(*scene->mMeshes[i], aiMatrix4x4{}, soup);
    }
  }
  if (soup.triangles.empty()) {
    throw InputError(name + ": no triangles in the file" +
                     (soup.skipped_primitives > 0 ? " (only points or lines)" : std::string(" (not a surface mesh)")));
  }
  for (std::size_t f = 0; f < soup.triangles.size(); ++f) {
    for (std::uint32_t v : soup.triangles[f]) {
      for (float c : soup.vertices[v]) {
        if (!std::isfinite(c)) {
          throw InputError(name + ": face " + std::to_string(f) + " has a non-finite vertex coordinate (" +
                           (std::isnan(c) ? "nan"
                            : c > 0       ? "inf"
                                          : "-inf") +
                           ")");
        }
      }
    }
  }

  // Merge vertices at identical positions into the first of them, keeping assimp's vertex order
  // (the file's for indexed formats such as PLY, OFF and glTF; the order of use for STL and OBJ).
  // An open-addressing table of first occurrences (std::unordered_map's node per vertex was a
  // tenth of reading a million-vertex file); positions compare as floats, +0 and -0 alike, so a
  // NaN meets nothing and stays a vertex of its own, as in a map.
  TriangleMesh mesh;
  std::vector<std::uint32_t> merged(soup.vertices.size());
  const auto key_of = [&](std::size_t v) {
    const auto& p = soup.vertices[v];
    return std::array<float, 3>{p[0] == 0.0f ? 0.0f : p[0], p[1] == 0.0f ? 0.0f : p[1], p[2] == 0.0f ? 0.0f : p[2]};
  };
  const std::size_t capacity = std::bit_ceil(std::max<std::size_t>(2 * soup.vertices.size(), 16));
  std::vector<std::uint32_t> first(capacity, 0);  // a first occurrence's vertex + 1; 0: empty
  for (std::size_t v = 0; v < soup.vertices.size(); ++v) {
    const std::array<float, 3> key = key_of(v);
    const std::size_t h = PositionHash{}(key);
    for (std::size_t at = (h ^ (h >> 32)) & (capacity - 1);; at = (at + 1) & (capacity - 1)) {
      if (first[at] == 0) {
        first[at] = static_cast<std::uint32_t>(v + 1);
        merged[v] = static_cast<std::uint32_t>(mesh.vertices.size());
        mesh.vertices.emplace_back(static_cast<double>(key[0]) * metres_per_unit,
                                   static_cast<double>(key[1]) * metres_per_unit,
                                   static_cast<double>(key[2]) * metres_per_unit);
        break;
      }
      if (key_of(first[at] - 1) == key) {
        merged[v] = merged[first[at] - 1];
        break;
      }
    }
  }
  mesh.triangles.reserve(soup.triangles.size());
  for (const auto& t : soup.triangles) mesh.triangles.push_back({merged[t[0]], merged[t[1]], merged[t[2]]});
  return mesh;
}
}  // namespace pneuma::mesh
