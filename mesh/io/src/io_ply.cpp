// read_ply(): the header against the PLY grammar, then the body, every count and index checked
// against the bytes that are there before anything is allocated or used.
#include "io_ply.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <iterator>
#include <map>
#include <set>
#include <sstream>
#include <vector>

#include "pneuma/core/error.h"

namespace pneuma::mesh::detail {
namespace {

enum class Encoding { ascii, little_endian, big_endian };

// The PLY scalar types, resolved once from the header (the body is read value by value).
enum class Type { i8, u8, i16, u16, i32, u32, f32, f64 };

struct Property {
  std::string name;
  Type type = Type::f32;       // of the value, or of each item of a list
  Type count_type = Type::u8;  // lists only
  bool list = false;
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;
};

const std::map<std::string, Type>& type_names() {
  static const std::map<std::string, Type> names = {
      {"char", Type::i8},   {"int8", Type::i8},     {"uchar", Type::u8},   {"uint8", Type::u8},
      {"short", Type::i16}, {"int16", Type::i16},   {"ushort", Type::u16}, {"uint16", Type::u16},
      {"int", Type::i32},   {"int32", Type::i32},   {"uint", Type::u32},   {"uint32", Type::u32},
      {"float", Type::f32}, {"float32", Type::f32}, {"double", Type::f64}, {"float64", Type::f64}};
  return names;
}

std::size_t size_of(Type t) {
  switch (t) {
    case Type::i8:
    case Type::u8: return 1;
    case Type::i16:
    case Type::u16: return 2;
    case Type::i32:
    case Type::u32:
    case Type::f32: return 4;
    case Type::f64: return 8;
  }
  return 8;
}

class Reader {
 public:
  Reader(const std::string& name, const std::string& bytes) : name_(name), d_(bytes) {}

  VtkSoup read() {
    header();
    VtkSoup soup;
    std::uint64_t vertex_count = 0;
    for (const Element& e : elements_) {
      if (e.name == "vertex") vertex_count = e.count;
    }
    for (const Element& e : elements_) {
      // Every item takes at least one byte (ASCII: a digit and a space): more is damage.
      if (e.count > d_.size() - pos_) fail(e.name + " count " + std::to_string(e.count) + ": more than the file holds");
      int x = -1, y = -1, z = -1, indices = -1;
      for (std::size_t p = 0; p < e.properties.size(); ++p) {
        const Property& pr = e.properties[p];
        if (e.name == "vertex" && !pr.list) {
          if (pr.name == "x") x = static_cast<int>(p);
          if (pr.name == "y") y = static_cast<int>(p);
          if (pr.name == "z") z = static_cast<int>(p);
        }
        if (e.name == "face" && pr.list && (pr.name == "vertex_indices" || pr.name == "vertex_index"))
          indices = static_cast<int>(p);
      }
      if (e.name == "vertex" && (x < 0 || y < 0 || z < 0)) fail("element vertex: expected properties x, y and z");
      if (e.name == "vertex") soup.points.reserve(e.count);
      std::vector<double> list;
      for (std::uint64_t i = 0; i < e.count; ++i) {
        std::array<double, 3> point{};
        for (std::size_t p = 0; p < e.properties.size(); ++p) {
          const Property& pr = e.properties[p];
          if (!pr.list) {
            const double v = value(pr.type, e, i);
            if (static_cast<int>(p) == x) point[0] = v;
            if (static_cast<int>(p) == y) point[1] = v;
            if (static_cast<int>(p) == z) point[2] = v;
            continue;
          }
          const double n = value(pr.count_type, e, i);
          if (!(n >= 0.0 && n <= static_cast<double>(d_.size() - pos_) && n == std::floor(n))) {
            fail(e.name + " " + std::to_string(i) + ": a list of " + number_text(n) +
                 " items, more than the file holds");
          }
          list.resize(static_cast<std::size_t>(n));
          for (double& item : list) item = value(pr.type, e, i);
          if (static_cast<int>(p) != indices) continue;
          if (list.size() < 3) continue;  // a point or a line: not part of a surface
          for (double v : list) {
            if (!(v >= 0.0 && v < static_cast<double>(vertex_count) && v == std::floor(v))) {
              fail("face " + std::to_string(i) + " uses vertex " + number_text(v) + ": expected an index below the " +
                   std::to_string(vertex_count) + " vertices");
            }
          }
          for (std::size_t k = 1; k + 1 < list.size(); ++k) {  // a fan: polygons are convex in practice
            soup.triangles.push_back({static_cast<std::uint32_t>(list[0]), static_cast<std::uint32_t>(list[k]),
                                      static_cast<std::uint32_t>(list[k + 1])});
          }
        }
        if (e.name == "vertex") soup.points.push_back(point);
      }
    }
    return soup;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const { throw InputError(name_ + ": PLY " + what); }
  [[noreturn]] void fail_at_end(const Element& e, std::uint64_t i) const {
    fail(e.name + " " + std::to_string(i) + ": the file ends (the header announces " + std::to_string(e.count) + ")");
  }

  static std::string number_text(double v) {
    std::ostringstream out;
    out << v;
    return out.str();
  }

  void header() {
    std::set<std::string> element_names;
    for (std::size_t line = 1;; ++line) {
      if (pos_ >= d_.size() || line > 100000) fail("header without 'end_header'");
      std::size_t end = d_.find('\n', pos_);
      if (end == std::string::npos) fail("header without 'end_header'");
      std::string text = d_.substr(pos_, end - pos_);
      pos_ = end + 1;
      if (!text.empty() && text.back() == '\r') text.pop_back();
      std::istringstream words(text);
      const std::vector<std::string> w{std::istream_iterator<std::string>(words), std::istream_iterator<std::string>()};
      const std::string keyword = w.empty() ? std::string() : w[0];
      auto refuse = [&](const std::string& expected) {
        fail("header line " + std::to_string(line) + ": expected " + expected + ", got '" + text.substr(0, 40) + "'");
      };
      if (line == 1) {
        if (text != "ply") refuse("'ply'");
      } else if (line == 2) {
        if (w.size() != 3 || keyword != "format") refuse("'format ascii|binary_little_endian|binary_big_endian 1.0'");
        if (w[1] == "ascii") encoding_ = Encoding::ascii;
        else if (w[1] == "binary_little_endian") encoding_ = Encoding::little_endian;
        else if (w[1] == "binary_big_endian") encoding_ = Encoding::big_endian;
        else refuse("'format ascii|binary_little_endian|binary_big_endian 1.0'");
      } else if (keyword == "end_header") {
        return;
      } else if (keyword == "comment" || keyword == "obj_info") {
      } else if (keyword == "element") {
        if (w.size() != 3 || w[2].empty() || w[2].size() > 19 ||
            w[2].find_first_not_of("0123456789") != std::string::npos) {
          refuse("'element NAME COUNT'");
        }
        if (!element_names.insert(w[1]).second) refuse("each element once");
        elements_.push_back({w[1], std::strtoull(w[2].c_str(), nullptr, 10), {}});
      } else if (keyword == "property" && !elements_.empty()) {
        const auto& names = type_names();
        if (w.size() == 3 && names.count(w[1])) {
          elements_.back().properties.push_back({w[2], names.at(w[1]), Type::u8, false});
        } else if (w.size() == 5 && w[1] == "list" && names.count(w[2]) && names.count(w[3])) {
          elements_.back().properties.push_back({w[4], names.at(w[3]), names.at(w[2]), true});
        } else {
          refuse("'property TYPE NAME' or 'property list COUNT_TYPE TYPE NAME'");
        }
      } else {
        refuse(elements_.empty() ? "comment, element or end_header" : "comment, element, property or end_header");
      }
    }
  }

  // One value of `type` (ASCII: the next token), as a double (exact for every PLY integer type).
  double value(Type type, const Element& e, std::uint64_t i) {
    if (encoding_ == Encoding::ascii) {
      while (pos_ < d_.size() && std::isspace(static_cast<unsigned char>(d_[pos_]))) ++pos_;
      const std::size_t start = pos_;
      while (pos_ < d_.size() && !std::isspace(static_cast<unsigned char>(d_[pos_]))) ++pos_;
      if (start == pos_) fail_at_end(e, i);
      const std::string token = d_.substr(start, pos_ - start);
      char* end = nullptr;
      const double v = std::strtod(token.c_str(), &end);
      if (*end != '\0')
        fail(e.name + " " + std::to_string(i) + ": expected a number, got '" + token.substr(0, 20) + "'");
      return v;
    }
    const std::size_t size = size_of(type);
    if (size > d_.size() - pos_) fail_at_end(e, i);
    unsigned char b[8];
    std::memcpy(b, d_.data() + pos_, size);
    pos_ += size;
    const bool swap = (encoding_ == Encoding::big_endian) != (std::endian::native == std::endian::big);
    if (swap) std::reverse(b, b + size);
    auto as = [&](auto t) {
      std::memcpy(&t, b, sizeof t);
      return static_cast<double>(t);
    };
    switch (type) {
      case Type::i8: return as(std::int8_t{});
      case Type::u8: return as(std::uint8_t{});
      case Type::i16: return as(std::int16_t{});
      case Type::u16: return as(std::uint16_t{});
      case Type::i32: return as(std::int32_t{});
      case Type::u32: return as(std::uint32_t{});
      case Type::f32: return as(float{});
      case Type::f64: return as(double{});
    }
    return 0.0;
  }

  const std::string& name_;
  const std::string& d_;
  std::size_t pos_ = 0;
  Encoding encoding_ = Encoding::ascii;
  std::vector<Element> elements_;
};

}  // namespace

VtkSoup read_ply(const std::string& name, const std::string& bytes) {
  Reader reader(name, bytes);
  return reader.read();
}

}  // namespace pneuma::mesh::detail
