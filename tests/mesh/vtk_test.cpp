// VTK import through read_mesh: legacy .vtk (ASCII, big-endian BINARY, 5.1 OFFSETS/CONNECTIVITY,
// POLYDATA polygons and strips, UNSTRUCTURED_GRID quads) and XML .vtp (ascii, base64 binary,
// zlib-compressed, raw appended), each written here by hand from a mesh whose triangles are
// known: the read mesh must give them back, in the file's vertex numbering.
#include <gtest/gtest.h>
#include <zlib.h>

#include <bit>
#include <cstring>

#include "mesh_fixture.h"
#include "pneuma/core/error.h"
#include "pneuma/mesh/geometry/validate.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "test_support.h"

using namespace pneuma::mesh;
using pneuma::test::TempDir;

namespace {

TriangleMesh sphere() { return test::canonical(make_icosphere(0.01, 2)); }  // 320 faces, metres

std::string fmt_point(const Eigen::Vector3d& v) {
  char b[96];
  std::snprintf(b, sizeof b, "%.9g %.9g %.9g\n", v.x() * 1e3, v.y() * 1e3, v.z() * 1e3);
  return b;
}

// The mesh in millimetres, as files hold it.
std::string points_ascii(const TriangleMesh& m) {
  std::string s;
  for (const auto& v : m.vertices) s += fmt_point(v);
  return s;
}

void expect_same(const TriangleMesh& read, const TriangleMesh& original) {
  ASSERT_EQ(read.vertex_count(), original.vertex_count());
  ASSERT_EQ(read.triangles, original.triangles);
  for (std::size_t v = 0; v < read.vertex_count(); ++v)
    EXPECT_LT((read.vertices[v] - original.vertices[v]).norm(), 1e-8);
  EXPECT_TRUE(validate(read).valid());
}

template <typename T>
void put_big(std::string& s, T value) {
  char b[sizeof(T)];
  std::memcpy(b, &value, sizeof(T));
  if constexpr (std::endian::native == std::endian::little) std::reverse(b, b + sizeof(T));
  s.append(b, sizeof(T));
}

template <typename T>
void put_little(std::string& s, T value) {
  char b[sizeof(T)];
  std::memcpy(b, &value, sizeof(T));
  s.append(b, sizeof(T));
}

std::string base64(const std::string& bytes) {
  static const char* abc = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    unsigned v = static_cast<unsigned char>(bytes[i]) << 16;
    if (i + 1 < bytes.size()) v |= static_cast<unsigned char>(bytes[i + 1]) << 8;
    if (i + 2 < bytes.size()) v |= static_cast<unsigned char>(bytes[i + 2]);
    out += abc[(v >> 18) & 63];
    out += abc[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? abc[(v >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? abc[v & 63] : '=';
  }
  return out;
}

std::string float_bytes(const TriangleMesh& m) {
  std::string s;
  for (const auto& v : m.vertices)
    for (int c = 0; c < 3; ++c) put_little(s, static_cast<float>(v[c] * 1e3));
  return s;
}
std::string conn_bytes(const TriangleMesh& m) {
  std::string s;
  for (const auto& t : m.triangles)
    for (auto v : t) put_little(s, static_cast<std::int32_t>(v));
  return s;
}
std::string offs_bytes(const TriangleMesh& m) {
  std::string s;
  for (std::size_t f = 1; f <= m.triangle_count(); ++f) put_little(s, static_cast<std::int32_t>(3 * f));
  return s;
}
// Inline binary, uncompressed: UInt32 byte count then the data, encoded separately (as VTK does).
std::string inline_binary(const std::string& data) {
  std::string h;
  put_little(h, static_cast<std::uint32_t>(data.size()));
  return base64(h) + base64(data);
}
// zlib: one block.
std::string inline_zlib(const std::string& data) {
  std::string z(compressBound(data.size()), '\0');
  uLongf zn = z.size();
  compress2(reinterpret_cast<Bytef*>(z.data()), &zn, reinterpret_cast<const Bytef*>(data.data()), data.size(), 6);
  z.resize(zn);
  std::string h;
  put_little(h, std::uint32_t{1});
  put_little(h, static_cast<std::uint32_t>(data.size()));
  put_little(h, static_cast<std::uint32_t>(data.size()));
  put_little(h, static_cast<std::uint32_t>(z.size()));
  return base64(h) + base64(z);
}

std::string vtp(const TriangleMesh& m, const std::string& format, const std::string& pts, const std::string& conn,
                const std::string& offs, const std::string& extra_root = "", const std::string& appended = "") {
  return "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"0.1\" byte_order=\"LittleEndian\"" +
         extra_root + ">\n<PolyData>\n<Piece NumberOfPoints=\"" + std::to_string(m.vertex_count()) +
         "\" NumberOfPolys=\"" + std::to_string(m.triangle_count()) +
         "\">\n<Points><DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"" + format + "\"" +
         (format == "appended" ? " offset=\"0\"" : "") + ">" + pts +
         "</DataArray></Points>\n<Polys><DataArray type=\"Int32\" Name=\"connectivity\" format=\"" + format + "\"" +
         (format == "appended" ? " offset=\"" + conn + "\"" : "") + ">" + (format == "appended" ? "" : conn) +
         "</DataArray><DataArray type=\"Int32\" Name=\"offsets\" format=\"" + format + "\"" +
         (format == "appended" ? " offset=\"" + offs + "\"" : "") + ">" + (format == "appended" ? "" : offs) +
         "</DataArray></Polys>\n</Piece>\n</PolyData>\n" + appended + "</VTKFile>\n";
}

}  // namespace

TEST(Vtk, LegacyAsciiPolygonsBothVersions) {
  TempDir dir;
  const TriangleMesh m = sphere();
  std::string cells, conn, offs = "0";
  for (std::size_t f = 0; f < m.triangle_count(); ++f) {
    const auto& t = m.triangles[f];
    const std::string line = std::to_string(t[0]) + ' ' + std::to_string(t[1]) + ' ' + std::to_string(t[2]) + '\n';
    cells += "3 ";
    cells += line;
    conn += line;
    offs += ' ';
    offs += std::to_string(3 * (f + 1));
  }
  const std::string head =
      "ASCII\nDATASET POLYDATA\nPOINTS " + std::to_string(m.vertex_count()) + " float\n" + points_ascii(m);
  const auto old =
      dir.write("old.vtk", std::string("# vtk DataFile Version 3.0\nsphere\n") + head + "POLYGONS " +
                               std::to_string(m.triangle_count()) + " " + std::to_string(4 * m.triangle_count()) +
                               "\n" + cells + "POINT_DATA 3\nSCALARS s float\n");
  expect_same(read_mesh(old), m);
  const auto v51 = dir.write(
      "v51.vtk", std::string("# vtk DataFile Version 5.1\nsphere\n") + head + "\nMETADATA\nINFORMATION 0\n\nPOLYGONS " +
                     std::to_string(m.triangle_count() + 1) + " " + std::to_string(3 * m.triangle_count()) +
                     "\nOFFSETS vtktypeint64\n" + offs + "\nCONNECTIVITY vtktypeint64\n" + conn);
  expect_same(read_mesh(v51), m);
}

// VTK 9 (3D Slicer, PyVista, ParaView) writes legacy version 5.1 by default: a FIELD block before
// POINTS (here a time value and a string array, each with its METADATA), points as double, a
// METADATA block after them, and polygons as OFFSETS / CONNECTIVITY vtktypeint64 arrays; in BINARY
// every array is big-endian after its own keyword line. Written here as VTK 9's legacy writer lays
// it out; the file must give the mesh back, in binary and in ASCII.
TEST(Vtk, Version51AsVtk9WritesItWithFieldData) {
  TempDir dir;
  const TriangleMesh m = sphere();
  for (bool binary : {true, false}) {
    SCOPED_TRACE(binary ? "BINARY" : "ASCII");
    auto numbers = [&](std::string& s, const auto& values) {
      for (const auto& v : values) {
        if (binary) {
          put_big(s, v);
        } else {
          s += std::to_string(v);
          s += ' ';
        }
      }
      s += '\n';
    };
    std::string s = std::string("# vtk DataFile Version 5.1\nvtk output\n") + (binary ? "BINARY" : "ASCII") +
                    "\nDATASET POLYDATA\nFIELD FieldData 2\nTimeValue 1 1 double\n";
    numbers(s, std::vector<double>{0.25});
    s += "METADATA\nINFORMATION 1\nNAME L2_NORM_RANGE LOCATION vtkDataArray\nDATA 2 0.25 0.25\n\n";
    s += "Source 1 1 string\nlung from a segmentation\n";
    s += "POINTS " + std::to_string(m.vertex_count()) + " double\n";
    std::vector<double> xyz;
    for (const auto& v : m.vertices)
      for (int c = 0; c < 3; ++c) xyz.push_back(v[c] * 1e3);
    numbers(s, xyz);
    s += "\nMETADATA\nINFORMATION 2\nNAME L2_NORM_RANGE LOCATION vtkDataArray\nDATA 2 10 10\n"
         "NAME L2_NORM_FINITE_RANGE LOCATION vtkDataArray\nDATA 2 10 10\n\n";
    std::vector<std::int64_t> offsets{0}, connectivity;
    for (const auto& t : m.triangles) {
      for (auto v : t) connectivity.push_back(v);
      offsets.push_back(static_cast<std::int64_t>(connectivity.size()));
    }
    s += "POLYGONS " + std::to_string(offsets.size()) + " " + std::to_string(connectivity.size()) +
         "\nOFFSETS vtktypeint64\n";
    numbers(s, offsets);
    s += "CONNECTIVITY vtktypeint64\n";
    numbers(s, connectivity);
    s += "\nPOINT_DATA " + std::to_string(m.vertex_count()) + "\nFIELD FieldData 1\nNormals 3 " +
         std::to_string(m.vertex_count()) + " float\n";
    expect_same(read_mesh(dir.write(binary ? "vtk9-binary.vtk" : "vtk9-ascii.vtk", s)), m);
  }
}

TEST(Vtk, LegacyBinaryIsBigEndian) {
  TempDir dir;
  const TriangleMesh m = sphere();
  std::string s = "# vtk DataFile Version 3.0\nsphere\nBINARY\nDATASET POLYDATA\nPOINTS " +
                  std::to_string(m.vertex_count()) + " float\n";
  for (const auto& v : m.vertices)
    for (int c = 0; c < 3; ++c) put_big(s, static_cast<float>(v[c] * 1e3));
  s += "\nPOLYGONS " + std::to_string(m.triangle_count()) + " " + std::to_string(4 * m.triangle_count()) + "\n";
  for (const auto& t : m.triangles) {
    put_big(s, std::int32_t{3});
    for (auto v : t) put_big(s, static_cast<std::int32_t>(v));
  }
  s += "\n";
  expect_same(read_mesh(dir.write("bin.vtk", s)), m);
}

TEST(Vtk, StripsAndUnstructuredQuads) {
  TempDir dir;
  // A unit-square strip 0 1 2 3: triangles (0 1 2) and (2 1 3), one orientation.
  const auto strip = dir.write("strip.vtk", "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 4 float\n"
                                            "0 0 0\n1 0 0\n0 1 0\n1 1 0\nTRIANGLE_STRIPS 1 5\n4 0 1 2 3\n");
  const TriangleMesh s = read_mesh(strip);
  EXPECT_EQ(s.triangles, (std::vector<Triangle>{{0, 1, 2}, {2, 1, 3}}));
  // A cube of quads in an unstructured grid: 12 triangles, closed, the cube's volume.
  std::string pts, cells;
  for (int i = 0; i < 8; ++i)
    pts += std::to_string(i & 1) + " " + std::to_string((i >> 1) & 1) + " " + std::to_string((i >> 2) & 1) + "\n";
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads)
    cells += "4 " + std::to_string(q[0]) + " " + std::to_string(q[1]) + " " + std::to_string(q[2]) + " " +
             std::to_string(q[3]) + "\n";
  const auto cube =
      dir.write("cube.vtk", "# vtk DataFile Version 3.0\ncube\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 8 double\n" +
                                pts + "CELLS 6 30\n" + cells + "CELL_TYPES 6\n9\n9\n9\n9\n9\n9\n");
  const TriangleMesh c = read_mesh(cube);
  EXPECT_EQ(c.triangle_count(), 12u);
  const ValidationReport r = validate(c);
  EXPECT_TRUE(r.valid()) << r.summary();
  EXPECT_NEAR(r.volume_m3, 1e-9, 1e-15);
}

TEST(Vtk, XmlPolyDataEveryEncoding) {
  TempDir dir;
  const TriangleMesh m = sphere();
  std::string conn, offs;
  for (std::size_t f = 0; f < m.triangle_count(); ++f) {
    for (auto v : m.triangles[f]) conn += std::to_string(v) + " ";
    offs += std::to_string(3 * (f + 1)) + " ";
  }
  expect_same(read_mesh(dir.write("ascii.vtp", vtp(m, "ascii", points_ascii(m), conn, offs))), m);
  expect_same(read_mesh(dir.write("binary.vtp", vtp(m, "binary", inline_binary(float_bytes(m)),
                                                    inline_binary(conn_bytes(m)), inline_binary(offs_bytes(m))))),
              m);
  expect_same(
      read_mesh(dir.write("zlib.vtp", vtp(m, "binary", inline_zlib(float_bytes(m)), inline_zlib(conn_bytes(m)),
                                          inline_zlib(offs_bytes(m)), " compressor=\"vtkZLibDataCompressor\""))),
      m);
  // Raw appended: each array is a UInt32 byte count and the bytes, at its offset after '_'.
  std::string raw;
  std::vector<std::size_t> at;
  for (const std::string& a : {float_bytes(m), conn_bytes(m), offs_bytes(m)}) {
    at.push_back(raw.size());
    put_little(raw, static_cast<std::uint32_t>(a.size()));
    raw += a;
  }
  expect_same(read_mesh(dir.write("raw.vtp", vtp(m, "appended", "", std::to_string(at[1]), std::to_string(at[2]), "",
                                                 "<AppendedData encoding=\"raw\">\n_" + raw + "\n</AppendedData>\n"))),
              m);
}

TEST(Vtk, ErrorsNameTheFileAndLine) {
  TempDir dir;
  auto expect_error = [](const std::filesystem::path& file, const std::string& what) {
    try {
      read_mesh(file);
      ADD_FAILURE() << "no error for " << file;
    } catch (const pneuma::InputError& e) {
      EXPECT_EQ(std::string(e.what()), file.string() + what);
    }
  };
  expect_error(
      dir.write("num.vtk", "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 2 float\n0 0 0\n1 x 0\n"),
      ":7: expected a number, got 'x'");
  expect_error(
      dir.write("tet.vtk", "# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n"
                           "0 0 0\n1 0 0\n0 1 0\n0 0 1\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n"),
      ": line 12: CELL_TYPES: cell 0 is of VTK type 10 (a volume or higher-order cell): expected surface cells "
      "(triangles, quads, pixels, polygons, strips)");
  expect_error(dir.write("grid.vtk", "# vtk DataFile Version 3.0\nx\nASCII\nDATASET STRUCTURED_POINTS\n"),
               ":4: DATASET STRUCTURED_POINTS: expected POLYDATA or UNSTRUCTURED_GRID (a surface)");
  expect_error(dir.write("idx.vtk",
                         "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n0 0 0\n1 0 0\n0 1 0\n"
                         "POLYGONS 1 4\n3 0 1 7\n"),
               ": line 9: POLYGONS cell 0 uses point 7: expected an index below the 3 points");
  expect_error(dir.write("img.vtp", "<VTKFile type=\"ImageData\"></VTKFile>"),
               ": expected <VTKFile type=\"PolyData\"> (a .vtp surface)");

  // Found by fuzzing: a count larger than the file (allocated as announced), an index that is
  // not an integer (an undefined cast), offsets that are not numbers.
  expect_error(
      dir.write("count.vtk", "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 900000000000 float\n"),
      ":5: count 900000000000: more items than the rest of the file can hold");
  expect_error(
      dir.write("nan.vtk", "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n0 0 0\n1 0 0\n"
                           "0 1 0\nPOLYGONS 1 4\n3 0 1 1e300\n"),
      ": line 9: POLYGONS cell 0 uses point -1: expected an index below the 3 points");
  const std::string vtp =
      "<VTKFile type=\"PolyData\"><PolyData><Piece NumberOfPoints=\"3\" NumberOfPolys=\"1\"><Points>"
      "<DataArray type=\"Float32\" NumberOfComponents=\"3\">0 0 0 1 0 0 0 1 0</DataArray></Points>"
      "<Polys><DataArray type=\"Int64\" Name=\"connectivity\">0 1 2</DataArray>"
      "<DataArray type=\"Int64\" Name=\"offsets\">OFFSET</DataArray></Polys></Piece></PolyData></VTKFile>";
  for (const char* offset : {"-1e300", "-5", "1e300"}) {
    std::string text = vtp;
    text.replace(text.find("OFFSET"), 6, offset);
    expect_error(dir.write("offsets.vtp", text),
                 ": <Polys> offset 0: expected non-decreasing offsets within the connectivity");
  }
}
