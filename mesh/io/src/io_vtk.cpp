// VTK surfaces without VTK: legacy .vtk (ASCII and big-endian BINARY; versions up to 5.1 with
// its OFFSETS/CONNECTIVITY cells, FIELD and METADATA blocks as VTK 9 writes them; POLYDATA
// polygons and triangle strips, UNSTRUCTURED_GRID triangles, quads, pixels, polygons and strips)
// and XML PolyData .vtp (ascii, base64 binary with or without zlib compression, inline or
// appended, base64 or raw). libvtk9-dev would pull a
// JDK, Qt and an MPI HDF5 that conflicts with ours, and no light library reads these, so this
// is a careful reader of its own: every error names the file and, for ASCII, the line.
#include <pugixml.hpp>
#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "io_vtk.h"
#include "pneuma/core/error.h"

namespace pneuma::mesh::detail {
namespace {

// ---- shared: cells to triangles ----

struct Builder {
  const std::string& name;
  VtkSoup& soup;
  std::size_t point_count = 0;

  void check(std::int64_t v, std::size_t cell, const std::string& where) const {
    if (v < 0 || static_cast<std::uint64_t>(v) >= point_count) {
      throw InputError(name + ": " + where + "cell " + std::to_string(cell) + " uses point " + std::to_string(v) +
                       ": expected an index below the " + std::to_string(point_count) + " points");
    }
  }
  // A polygon, as a fan (VTK polygons of surfaces are convex in practice).
  void polygon(const std::int64_t* v, std::size_t n, std::size_t cell, const std::string& where) {
    for (std::size_t k = 0; k < n; ++k) check(v[k], cell, where);
    for (std::size_t k = 2; k < n; ++k) {
      soup.triangles.push_back(
          {static_cast<std::uint32_t>(v[0]), static_cast<std::uint32_t>(v[k - 1]), static_cast<std::uint32_t>(v[k])});
    }
  }
  // A triangle strip: every other triangle is reversed to keep one orientation.
  void strip(const std::int64_t* v, std::size_t n, std::size_t cell, const std::string& where) {
    for (std::size_t k = 0; k < n; ++k) check(v[k], cell, where);
    for (std::size_t k = 2; k < n; ++k) {
      const auto a = static_cast<std::uint32_t>(v[k - 2]), b = static_cast<std::uint32_t>(v[k - 1]),
                 c = static_cast<std::uint32_t>(v[k]);
      if (k % 2 == 0) soup.triangles.push_back({a, b, c});
      else soup.triangles.push_back({b, a, c});
    }
  }
};

// VTK cell types (vtkCellType.h) an unstructured grid surface may hold.
void add_cell(Builder& b, int type, const std::int64_t* v, std::size_t n, std::size_t cell, const std::string& where) {
  switch (type) {
    case 1:
    case 2:
    case 3:
    case 4: return;  // vertex, poly-vertex, line, poly-line: not surface
    case 5:
    case 7:
    case 9: b.polygon(v, n, cell, where); return;  // triangle, polygon, quad
    case 6: b.strip(v, n, cell, where); return;    // triangle strip
    case 8:                                        // pixel: 0 1 3 2
      if (n == 4) {
        const std::int64_t q[4] = {v[0], v[1], v[3], v[2]};
        b.polygon(q, 4, cell, where);
      }
      return;
    default:
      throw InputError(b.name + ": " + where + "cell " + std::to_string(cell) + " is of VTK type " +
                       std::to_string(type) +
                       " (a volume or higher-order cell): expected surface cells (triangles, quads, pixels, polygons, "
                       "strips)");
  }
}

// A number of the file as an index or a count: integral and within int64 (casting anything else
// is undefined); -1, which every caller refuses as out of range, for anything else.
std::int64_t as_index(double v) {
  return v >= -9.2e18 && v <= 9.2e18 && v == std::floor(v) ? static_cast<std::int64_t>(v) : -1;
}

// ---- legacy ----

class Legacy {
 public:
  Legacy(std::string name, std::string data) : name_(std::move(name)), d_(std::move(data)) {}

  VtkSoup read() {
    const std::string version = line();
    if (version.rfind("# vtk DataFile Version", 0) != 0)
      fail(0, "expected '# vtk DataFile Version x.y' on the first line");
    line();  // title
    const std::string format = upper(trim(line()));
    if (format == "BINARY") binary_ = true;
    else if (format != "ASCII") fail(2, "expected ASCII or BINARY, got '" + format + "'");
    expect_word("DATASET");
    const std::string dataset = upper(word());
    if (dataset != "POLYDATA" && dataset != "UNSTRUCTURED_GRID") {
      fail(line_, "DATASET " + dataset + ": expected POLYDATA or UNSTRUCTURED_GRID (a surface)");
    }
    VtkSoup soup;
    Builder b{name_, soup};
    std::vector<std::int64_t> cell_offsets, cell_connectivity;  // unstructured grid cells, until CELL_TYPES
    bool have_points = false;
    while (true) {
      skip_space();
      if (pos_ >= d_.size()) break;
      const std::size_t at_line = line_;
      const std::string key = upper(word());
      binary_started_ = false;  // each section's binary block follows its own keyword line
      if (key == "POINTS") {
        const std::size_t n = count();
        const std::string type = word();
        soup.points.resize(n);
        for (std::size_t i = 0; i < n; ++i) {
          for (int c = 0; c < 3; ++c) soup.points[i][static_cast<std::size_t>(c)] = number(type);
        }
        b.point_count = n;
        have_points = true;
      } else if (key == "POLYGONS" || key == "TRIANGLE_STRIPS" || key == "VERTICES" || key == "LINES" ||
                 key == "CELLS") {
        if (!have_points) fail(at_line, key + " before POINTS: expected the points first");
        std::vector<std::int64_t> offsets, connectivity;
        cells(offsets, connectivity);
        if (key == "CELLS") {
          cell_offsets = std::move(offsets), cell_connectivity = std::move(connectivity);
          continue;
        }
        if (key == "VERTICES" || key == "LINES") continue;
        for (std::size_t c = 0; c + 1 < offsets.size(); ++c) {
          const std::int64_t* v = connectivity.data() + offsets[c];
          const auto n = static_cast<std::size_t>(offsets[c + 1] - offsets[c]);
          const std::string where = fmt_line(at_line) + key + " ";
          if (key == "POLYGONS") b.polygon(v, n, c, where);
          else b.strip(v, n, c, where);
        }
      } else if (key == "CELL_TYPES") {
        const std::size_t n = count();
        if (n + 1 != cell_offsets.size())
          fail(at_line, "CELL_TYPES " + std::to_string(n) + ": expected one type per cell");
        for (std::size_t c = 0; c < n; ++c) {
          const auto type = static_cast<int>(std::clamp<std::int64_t>(as_index(number("int")), -1, 1000));
          const std::int64_t* v = cell_connectivity.data() + cell_offsets[c];
          add_cell(b, type, v, static_cast<std::size_t>(cell_offsets[c + 1] - cell_offsets[c]), c,
                   fmt_line(at_line) + "CELL_TYPES: ");
        }
      } else if (key == "METADATA") {
        skip_metadata();
      } else if (key == "FIELD") {
        // Field data (VTK 9 writes one before POINTS, e.g. a time value): skipped, array by array,
        // each with its own binary block and optional METADATA.
        word();
        const std::size_t arrays = count();
        for (std::size_t a = 0; a < arrays; ++a) skip_field_array();
      } else if (key == "POINT_DATA" || key == "CELL_DATA") {
        break;  // attributes: not needed for the surface
      } else {
        fail(at_line, "unexpected '" + key + "': expected POINTS, POLYGONS, TRIANGLE_STRIPS, CELLS or CELL_TYPES");
      }
    }
    if (!have_points) throw InputError(name_ + ": no POINTS section: expected a surface");
    return soup;
  }

 private:
  [[noreturn]] void fail(std::size_t line0, const std::string& what) const {
    throw InputError(name_ + ":" + std::to_string(line0 + 1) + ": " + what);
  }
  std::string fmt_line(std::size_t line0) const { return "line " + std::to_string(line0 + 1) + ": "; }
  static std::string upper(std::string s) {
    for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    return s;
  }
  static std::string trim(const std::string& s) {
    const auto a = s.find_first_not_of(" \t\r\n"), b = s.find_last_not_of(" \t\r\n");
    return a == std::string::npos ? std::string() : s.substr(a, b - a + 1);
  }
  std::string line() {
    if (pos_ >= d_.size()) fail(line_, "unexpected end of file");
    const std::size_t end = d_.find('\n', pos_);
    std::string s = d_.substr(pos_, end == std::string::npos ? std::string::npos : end - pos_);
    pos_ = end == std::string::npos ? d_.size() : end + 1;
    ++line_;
    return s;
  }
  void skip_space() {
    while (pos_ < d_.size() && std::isspace(static_cast<unsigned char>(d_[pos_]))) line_ += d_[pos_++] == '\n';
  }
  std::string word() {
    skip_space();
    if (pos_ >= d_.size()) fail(line_, "unexpected end of file");
    const std::size_t start = pos_;
    while (pos_ < d_.size() && !std::isspace(static_cast<unsigned char>(d_[pos_]))) ++pos_;
    return d_.substr(start, pos_ - start);
  }
  void expect_word(const char* w) {
    const std::size_t at = line_;
    const std::string got = word();
    if (upper(got) != w) fail(at, std::string("expected ") + w + ", got '" + got + "'");
  }
  std::size_t count() {
    const std::size_t at = line_;
    const std::string w = word();
    char* end = nullptr;
    const long long v = std::strtoll(w.c_str(), &end, 10);
    if (end == w.c_str() || *end != '\0' || v < 0) fail(at, "expected a count, got '" + w + "'");
    // Every item takes at least one byte: a larger count is damage (and would be allocated).
    if (static_cast<unsigned long long>(v) > d_.size() - std::min(pos_, d_.size())) {
      fail(at, "count " + w + ": more items than the rest of the file can hold");
    }
    return static_cast<std::size_t>(v);
  }
  // The binary block of a section starts after the newline that ends its keyword line.
  void to_binary_block() {
    while (pos_ < d_.size() && d_[pos_] != '\n') ++pos_;
    if (pos_ < d_.size()) ++pos_, ++line_;
    binary_started_ = true;
  }
  template <typename T>
  double big_endian() {
    if (pos_ + sizeof(T) > d_.size())
      throw InputError(name_ + ": truncated binary data at byte " + std::to_string(pos_));
    unsigned char bytes[sizeof(T)];
    std::memcpy(bytes, d_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    if constexpr (std::endian::native == std::endian::little) std::reverse(bytes, bytes + sizeof(T));
    T v;
    std::memcpy(&v, bytes, sizeof(T));
    return static_cast<double>(v);
  }
  double number(const std::string& type_name) {
    const std::string& t = type_name;
    if (binary_) {
      if (!binary_started_) to_binary_block();
      if (t == "float") return big_endian<float>();
      if (t == "double") return big_endian<double>();
      if (t == "int") return big_endian<std::int32_t>();
      if (t == "unsigned_int") return big_endian<std::uint32_t>();
      if (t == "short") return big_endian<std::int16_t>();
      if (t == "unsigned_short") return big_endian<std::uint16_t>();
      if (t == "char") return big_endian<std::int8_t>();
      if (t == "unsigned_char") return big_endian<std::uint8_t>();
      if (t == "long" || t == "vtktypeint64") return big_endian<std::int64_t>();
      if (t == "unsigned_long" || t == "vtktypeuint64") return big_endian<std::uint64_t>();
      fail(line_, "data type '" + t + "': expected float, double or an integer type");
    }
    const std::size_t at = line_;
    const std::string w = word();
    char* end = nullptr;
    const double v = std::strtod(w.c_str(), &end);
    if (end == w.c_str() || *end != '\0') fail(at, "expected a number, got '" + w + "'");
    return v;
  }
  // Cells in either layout: "n size" then n lists "k v1 .. vk" (up to 4.2), or
  // "n_offsets n_connectivity" then OFFSETS type ... CONNECTIVITY type ... (5.x).
  void cells(std::vector<std::int64_t>& offsets, std::vector<std::int64_t>& connectivity) {
    const std::size_t at = line_;
    const std::size_t n = count(), size = count();
    const std::size_t save_pos = pos_, save_line = line_;
    skip_space();
    const std::size_t peek = pos_;
    while (pos_ < d_.size() && !std::isspace(static_cast<unsigned char>(d_[pos_]))) ++pos_;
    const bool modern = upper(d_.substr(peek, pos_ - peek)) == "OFFSETS";
    pos_ = save_pos, line_ = save_line;
    binary_started_ = false;
    if (modern) {
      expect_word("OFFSETS");
      std::string type = word();
      offsets.resize(n);
      for (auto& o : offsets) o = as_index(number(type));
      binary_started_ = false;
      expect_word("CONNECTIVITY");
      type = word();
      connectivity.resize(size);
      for (auto& c : connectivity) c = as_index(number(type));
      binary_started_ = false;
      if (offsets.empty() || offsets.front() != 0 || offsets.back() != static_cast<std::int64_t>(size) ||
          !std::is_sorted(offsets.begin(), offsets.end())) {
        fail(at, "OFFSETS: expected a non-decreasing list from 0 to the connectivity size");
      }
      return;
    }
    offsets.assign(1, 0);
    connectivity.reserve(size);
    std::size_t used = 0;
    for (std::size_t c = 0; c < n; ++c) {
      const std::int64_t k = as_index(number("int"));
      if (k < 0 || used + 1 + static_cast<std::size_t>(k) > size) {
        fail(line_, "cell " + std::to_string(c) + " has " + std::to_string(k) +
                        " points: expected the list to fit the "
                        "announced size " +
                        std::to_string(size));
      }
      for (std::int64_t i = 0; i < k; ++i) connectivity.push_back(as_index(number("int")));
      used += 1 + static_cast<std::size_t>(k);
      offsets.push_back(static_cast<std::int64_t>(connectivity.size()));
    }
    binary_started_ = false;
  }

  // "METADATA" is read: the rest of its line, then lines until an empty one.
  void skip_metadata() {
    line();
    while (pos_ < d_.size() && !trim(line()).empty()) {
    }
  }
  // One array of a FIELD block: "name components tuples type", its values (or "NULL_ARRAY"),
  // then an optional METADATA block. Strings are one per line (VTK's legacy writer).
  void skip_field_array() {
    if (upper(word()) == "NULL_ARRAY") return;
    const std::size_t comps = count(), tuples = count();
    const std::string type = word();
    binary_started_ = false;
    if (type == "string") {
      line();  // the end of the array's header line
      for (std::size_t k = 0; k < comps * tuples; ++k) line();
    } else {
      for (std::size_t k = 0; k < comps * tuples; ++k) number(type);
    }
    binary_started_ = false;
    const std::size_t save_pos = pos_, save_line = line_;
    skip_space();
    if (pos_ < d_.size() && upper(word()) == "METADATA") {
      skip_metadata();
    } else {
      pos_ = save_pos, line_ = save_line;
    }
  }

  std::string name_;
  std::string d_;
  std::size_t pos_ = 0, line_ = 0;
  bool binary_ = false, binary_started_ = false;
};

// ---- XML ----

std::vector<unsigned char> base64_decode(std::string_view text, const std::string& name) {
  // Quantum by quantum: padding may end one encoded block and another follow (VTK encodes the
  // header and the data of an array separately).
  static const auto value = [](char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
  };
  std::vector<unsigned char> out;
  out.reserve(text.size() * 3 / 4);
  char q[4];
  int n = 0;
  for (char c : text) {
    if (std::isspace(static_cast<unsigned char>(c))) continue;
    if (c != '=' && value(c) < 0)
      throw InputError(name + ": invalid base64 character '" + std::string(1, c) + "' in a DataArray");
    q[n++] = c;
    if (n < 4) continue;
    n = 0;
    const int a = value(q[0]), b = value(q[1]), cc = q[2] == '=' ? 0 : value(q[2]), d = q[3] == '=' ? 0 : value(q[3]);
    const unsigned v = (unsigned(a) << 18) | (unsigned(b) << 12) | (unsigned(cc) << 6) | unsigned(d);
    out.push_back(static_cast<unsigned char>(v >> 16));
    if (q[2] != '=') out.push_back(static_cast<unsigned char>((v >> 8) & 0xff));
    if (q[3] != '=') out.push_back(static_cast<unsigned char>(v & 0xff));
  }
  return out;
}

struct XmlContext {
  std::string name;
  bool big_endian = false;
  bool uint64_header = false;
  bool zlib = false;
  std::string appended_encoding;  // "base64" or "raw"
  std::string_view appended;      // after the '_'
};

std::size_t type_size(const std::string& t) {
  if (t == "Int8" || t == "UInt8") return 1;
  if (t == "Int16" || t == "UInt16") return 2;
  if (t == "Int32" || t == "UInt32" || t == "Float32") return 4;
  if (t == "Int64" || t == "UInt64" || t == "Float64") return 8;
  return 0;
}

double convert_value(const unsigned char* p, const std::string& t, bool big) {
  unsigned char b[8];
  const std::size_t n = type_size(t);
  std::memcpy(b, p, n);
  if (big != (std::endian::native == std::endian::big)) std::reverse(b, b + n);
  auto as = [&]<typename T>(T) {
    T v;
    std::memcpy(&v, b, sizeof v);
    return static_cast<double>(v);
  };
  if (t == "Int8") return as(std::int8_t{});
  if (t == "UInt8") return as(std::uint8_t{});
  if (t == "Int16") return as(std::int16_t{});
  if (t == "UInt16") return as(std::uint16_t{});
  if (t == "Int32") return as(std::int32_t{});
  if (t == "UInt32") return as(std::uint32_t{});
  if (t == "Int64") return as(std::int64_t{});
  if (t == "UInt64") return as(std::uint64_t{});
  if (t == "Float32") return as(float{});
  return as(double{});
}

// A byte cursor over decoded (or raw) bytes.
struct Bytes {
  std::vector<unsigned char> data;
  std::size_t pos = 0;
};

std::uint64_t read_header_word(Bytes& b, const XmlContext& x) {
  const std::string t = x.uint64_header ? "UInt64" : "UInt32";
  const std::size_t n = type_size(t);
  if (b.pos + n > b.data.size()) throw InputError(x.name + ": truncated binary DataArray header");
  const double v = convert_value(b.data.data() + b.pos, t, x.big_endian);
  b.pos += n;
  const std::int64_t word = as_index(v);
  if (word < 0) throw InputError(x.name + ": corrupt binary DataArray header");
  return static_cast<std::uint64_t>(word);
}

// The payload bytes of a binary array (header, optional zlib blocks) starting at b.pos.
std::vector<unsigned char> payload(Bytes& b, const XmlContext& x) {
  if (!x.zlib) {
    const std::uint64_t n = read_header_word(b, x);
    if (n > b.data.size() - b.pos)
      throw InputError(x.name + ": truncated binary DataArray: " + std::to_string(n) + " bytes announced");
    std::vector<unsigned char> out(b.data.begin() + static_cast<std::ptrdiff_t>(b.pos),
                                   b.data.begin() + static_cast<std::ptrdiff_t>(b.pos + n));
    b.pos += n;
    return out;
  }
  const std::uint64_t blocks = read_header_word(b, x), block_size = read_header_word(b, x),
                      last = read_header_word(b, x);
  if (blocks > b.data.size() - b.pos) throw InputError(x.name + ": truncated compressed DataArray header");
  std::vector<std::uint64_t> sizes(blocks);
  for (auto& s : sizes) s = read_header_word(b, x);
  std::vector<unsigned char> out;
  for (std::uint64_t k = 0; k < blocks; ++k) {
    const std::uint64_t raw = (k + 1 == blocks && last != 0) ? last : block_size;
    if (sizes[k] > b.data.size() - b.pos) throw InputError(x.name + ": truncated compressed DataArray");
    // zlib expands at most ~1032:1: a block announcing more is damage, not data.
    if (raw / 1032 > sizes[k] + 1)
      throw InputError(x.name + ": corrupt zlib block " + std::to_string(k) + " in a DataArray");
    const std::size_t at = out.size();
    out.resize(at + raw);
    uLongf got = static_cast<uLongf>(raw);
    if (uncompress(out.data() + at, &got, b.data.data() + b.pos, static_cast<uLong>(sizes[k])) != Z_OK || got != raw) {
      throw InputError(x.name + ": corrupt zlib block " + std::to_string(k) + " in a DataArray");
    }
    b.pos += sizes[k];
  }
  return out;
}

std::vector<double> data_array(const pugi::xml_node& array, const XmlContext& x, std::size_t expected) {
  const std::string type = array.attribute("type").as_string();
  const std::string format = array.attribute("format").as_string("ascii");
  const std::string what = std::string("DataArray '") + array.attribute("Name").as_string("") + "'";
  if (type_size(type) == 0)
    throw InputError(x.name + ": " + what + " of type '" + type + "': expected Int8..UInt64, Float32 or Float64");
  std::vector<double> values;
  if (format == "ascii") {
    std::istringstream in(array.text().as_string());
    double v;
    while (in >> v) values.push_back(v);
    if (!in.eof()) throw InputError(x.name + ": " + what + ": expected numbers in ascii format");
  } else {
    Bytes b;
    if (format == "binary") {
      b.data = base64_decode(array.text().as_string(), x.name);
    } else if (format == "appended") {
      const auto offset = static_cast<std::size_t>(array.attribute("offset").as_ullong());
      if (offset > x.appended.size()) throw InputError(x.name + ": " + what + ": offset beyond the AppendedData");
      if (x.appended_encoding == "raw") {
        b.data.assign(x.appended.begin() + static_cast<std::ptrdiff_t>(offset), x.appended.end());
      } else {
        b.data = base64_decode(x.appended.substr(offset), x.name);
      }
    } else {
      throw InputError(x.name + ": " + what + " in format '" + format + "': expected ascii, binary or appended");
    }
    const std::vector<unsigned char> bytes = payload(b, x);
    const std::size_t n = type_size(type);
    values.resize(bytes.size() / n);
    for (std::size_t i = 0; i < values.size(); ++i) values[i] = convert_value(bytes.data() + i * n, type, x.big_endian);
  }
  if (expected != 0 && values.size() < expected) {
    throw InputError(x.name + ": " + what + " holds " + std::to_string(values.size()) + " values: expected " +
                     std::to_string(expected));
  }
  return values;
}

}  // namespace

VtkSoup read_vtk_legacy(const std::string& name, std::string bytes) { return Legacy(name, std::move(bytes)).read(); }

VtkSoup read_vtk_xml(const std::string& name, std::string bytes) {
  XmlContext x;
  x.name = name;
  // Raw appended data is not XML: cut it out before parsing.
  std::string appended_raw;
  if (const auto tag = bytes.find("<AppendedData"); tag != std::string::npos) {
    const auto underscore = bytes.find('_', bytes.find('>', tag));
    const auto close = bytes.rfind("</AppendedData>");
    if (underscore == std::string::npos || close == std::string::npos || close < underscore) {
      throw InputError(name + ": AppendedData: expected '_' then the data, then </AppendedData>");
    }
    appended_raw = bytes.substr(underscore + 1, close - underscore - 1);
    bytes.erase(underscore, close - underscore);
  }
  pugi::xml_document doc;
  const pugi::xml_parse_result parsed = doc.load_buffer(bytes.data(), bytes.size());
  if (!parsed) {
    throw InputError(name + ": not a VTK XML file: " + parsed.description() + " at byte " +
                     std::to_string(parsed.offset));
  }
  const pugi::xml_node root = doc.child("VTKFile");
  if (!root || std::string(root.attribute("type").as_string()) != "PolyData") {
    throw InputError(name + ": expected <VTKFile type=\"PolyData\"> (a .vtp surface)");
  }
  x.big_endian = std::string(root.attribute("byte_order").as_string("LittleEndian")) == "BigEndian";
  x.uint64_header = std::string(root.attribute("header_type").as_string("UInt32")) == "UInt64";
  const std::string compressor = root.attribute("compressor").as_string("");
  if (!compressor.empty() && compressor != "vtkZLibDataCompressor") {
    throw InputError(name + ": compressor " + compressor + ": expected vtkZLibDataCompressor or none");
  }
  x.zlib = !compressor.empty();
  if (const pugi::xml_node app = root.child("AppendedData")) {
    x.appended_encoding = app.attribute("encoding").as_string("base64");
    x.appended = appended_raw;
  }
  VtkSoup soup;
  Builder b{name, soup};
  for (const pugi::xml_node piece : root.child("PolyData").children("Piece")) {
    const std::size_t base = soup.points.size();
    const auto n_points = static_cast<std::size_t>(piece.attribute("NumberOfPoints").as_ullong());
    const pugi::xml_node points = piece.child("Points").child("DataArray");
    if (!points) throw InputError(name + ": a Piece without <Points><DataArray>: expected the points");
    const std::vector<double> p = data_array(points, x, 3 * n_points);
    for (std::size_t i = 0; i < n_points; ++i) soup.points.push_back({p[3 * i], p[3 * i + 1], p[3 * i + 2]});
    b.point_count = soup.points.size();
    for (const char* section : {"Polys", "Strips"}) {
      const pugi::xml_node s = piece.child(section);
      if (!s) continue;
      pugi::xml_node conn, offs;
      for (const pugi::xml_node a : s.children("DataArray")) {
        const std::string n = a.attribute("Name").as_string();
        if (n == "connectivity") conn = a;
        if (n == "offsets") offs = a;
      }
      if (!conn || !offs)
        throw InputError(name + ": <" + section + ">: expected DataArrays 'connectivity' and 'offsets'");
      const std::vector<double> c = data_array(conn, x, 0), o = data_array(offs, x, 0);
      std::vector<std::int64_t> v;
      std::size_t start = 0;
      for (std::size_t cell = 0; cell < o.size(); ++cell) {
        if (!(o[cell] >= static_cast<double>(start) && o[cell] <= static_cast<double>(c.size()))) {
          throw InputError(name + ": <" + section + "> offset " + std::to_string(cell) +
                           ": expected non-decreasing offsets "
                           "within the connectivity");
        }
        const auto end = static_cast<std::size_t>(o[cell]);
        v.clear();
        for (std::size_t k = start; k < end; ++k) {
          const std::int64_t index = as_index(c[k]);
          v.push_back(index < 0 ? -1 : index + static_cast<std::int64_t>(base));
        }
        if (std::string(section) == "Polys") b.polygon(v.data(), v.size(), cell, std::string(section) + " ");
        else b.strip(v.data(), v.size(), cell, std::string(section) + " ");
        start = end;
      }
    }
  }
  return soup;
}

}  // namespace pneuma::mesh::detail
