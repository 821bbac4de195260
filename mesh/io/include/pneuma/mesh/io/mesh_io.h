#pragma once
// Reading and writing triangle surfaces.
//
// read_mesh() imports anything assimp reads (STL binary and ASCII, OBJ, PLY, OFF, glTF/GLB, ...),
// applies the node transforms of scene formats, merges vertices with identical coordinates
// (STL stores none shared) and returns one indexed mesh in metres. Several meshes in one file
// are kept, as separate components of the one TriangleMesh. Vertex numbering (which error
// messages use): the file's own for indexed formats (PLY, OFF, glTF), the order of first use
// by the triangles for STL and OBJ (assimp expands OBJ vertices per face). Everything pneuma
// writes is numbered by first use, so it reads back with the same indices in every format.
// A vertex at the position of an earlier one is merged into it; unused vertices are kept.
//
// write_mesh() writes PLY (binary or ASCII), OBJ or STL (binary or ASCII) through
// pneuma::write_atomically: no partial file under the final name, ever.
//
// Coordinates in files carry a unit that the caller names: `metres_per_unit` is the length of
// one file unit in metres (1e-3 for millimetres, the default, as medical meshes are in mm).
// write_mesh() records it in the file (PLY `comment unit mm`, OBJ `# unit mm`, ASCII STL
// `solid pneuma unit mm`, binary STL header `..., unit mm`); read_mesh() uses a recorded unit
// instead of `metres_per_unit` unless `unit_from_file` is false (a unit the user gave).
// Binary formats store 32-bit floats, so a write/read round trip keeps the connectivity
// exactly and the coordinates to float precision; a second round trip is exact.
#include <filesystem>
#include <optional>
#include <string>

#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::mesh {

inline constexpr double kMetresPerMillimetre = 1e-3;

struct ReadOptions {
  double metres_per_unit = kMetresPerMillimetre;
  bool unit_from_file = true;  // a unit recorded in the file replaces metres_per_unit
};

// The unit recorded in a PLY, OBJ or STL file's header (as write_mesh() writes it), in metres
// per file unit; nullopt when there is none. Throws InputError for a recorded unit that is not
// a length.
std::optional<double> recorded_unit(const std::filesystem::path& path);

// Throws IoError when the file cannot be opened, InputError ("<file>: <what is wrong>") when
// it is empty, truncated (binary STL: the header's triangle count against the file size), not
// in a format assimp reads, holds no triangles, or has a non-finite coordinate.
TriangleMesh read_mesh(const std::filesystem::path& path, const ReadOptions& options = {});

enum class FileFormat { ply_binary, ply_ascii, obj, stl_binary, stl_ascii };

// The format for a file name: .ply -> binary PLY, .obj -> OBJ, .stl -> binary STL (ascii=true
// picks the ASCII variant). Throws UsageError for any other extension.
FileFormat format_for_path(const std::filesystem::path& path, bool ascii = false);
const char* format_name(FileFormat format);

struct WriteOptions {
  double metres_per_unit = kMetresPerMillimetre;
  bool ascii = false;  // PLY and STL: ASCII instead of binary
};

// Writes atomically in the format the extension names. Throws UsageError for an unknown
// extension and IoError when the file cannot be written.
void write_mesh(const std::filesystem::path& path, const TriangleMesh& mesh, const WriteOptions& options = {});

// A length unit name or quantity ("mm", "cm", "m", "um", "0.5 mm") in metres. Throws
// UsageError naming the text when it is not a length, or one outside 1 nm to 1 km.
double parse_length_unit(const std::string& text);

}  // namespace pneuma::mesh
