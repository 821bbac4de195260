#include "pneuma/core/units.h"

#include <array>
#include <charconv>
#include <cmath>

#include "pneuma/core/text.h"

namespace pneuma::units {
namespace {

struct Atom {
  std::string_view symbol;
  double factor;  // SI value of one unit
  Dimension dimension;
};

constexpr Dimension kLength{1, 0, 0}, kVolume{3, 0, 0}, kTime{0, 0, 1}, kMass{0, 1, 0}, kPressure{-1, 1, -2},
    kFrequency{0, 0, -1}, kForce{1, 1, -2}, kNone{0, 0, 0};

// Symbols are case-sensitive, as in SI ("mL" is not "ML"); "l" is accepted beside "L".
constexpr std::array kAtoms{
    Atom{"m", 1.0, kLength},
    Atom{"cm", 1e-2, kLength},
    Atom{"mm", 1e-3, kLength},
    Atom{"um", 1e-6, kLength},
    Atom{"L", 1e-3, kVolume},
    Atom{"l", 1e-3, kVolume},
    Atom{"mL", 1e-6, kVolume},
    Atom{"ml", 1e-6, kVolume},
    Atom{"dL", 1e-4, kVolume},
    Atom{"cc", 1e-6, kVolume},
    Atom{"s", 1.0, kTime},
    Atom{"ms", 1e-3, kTime},
    Atom{"min", 60.0, kTime},
    Atom{"h", 3600.0, kTime},
    Atom{"Hz", 1.0, kFrequency},
    Atom{"bpm", 1.0 / 60.0, kFrequency},
    Atom{"Pa", 1.0, kPressure},
    Atom{"hPa", 100.0, kPressure},
    Atom{"kPa", 1e3, kPressure},
    Atom{"MPa", 1e6, kPressure},
    Atom{"cmH2O", pa_per_cmh2o, kPressure},
    Atom{"mmHg", 133.322387415, kPressure},
    Atom{"mbar", 100.0, kPressure},
    Atom{"kg", 1.0, kMass},
    Atom{"g", 1e-3, kMass},
    Atom{"N", 1.0, kForce},
    Atom{"%", 1e-2, kNone},
};

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

[[noreturn]] void fail(const Kind& kind, std::string_view text) {
  std::string article = std::string("aeiou").find(kind.name[0]) != std::string::npos ? "an " : "a ";
  throw UnitError("expected " + article + kind.name + " such as '" + kind.example + "', got " + quote_input(text));
}

// Parses one "atom[^power]" factor; returns false when it is not a known unit.
bool parse_factor(std::string_view token, int sign, double& factor, Dimension& dim) {
  int power = 1;
  if (auto caret = token.find('^'); caret != std::string_view::npos) {
    std::string_view p = token.substr(caret + 1);
    auto [end, ec] = std::from_chars(p.data(), p.data() + p.size(), power);
    if (ec != std::errc() || end != p.data() + p.size() || power == 0) return false;
    token = token.substr(0, caret);
  }
  for (const Atom& atom : kAtoms) {
    if (atom.symbol == token) {
      const int e = sign * power;
      factor *= std::pow(atom.factor, e);
      dim.length += e * atom.dimension.length;
      dim.mass += e * atom.dimension.mass;
      dim.time += e * atom.dimension.time;
      return true;
    }
  }
  return false;
}

// Parses a unit expression such as "cmH2O*s/L" or "/min".
bool parse_unit(std::string_view unit, double& factor, Dimension& dim) {
  int sign = 1;
  std::size_t start = 0;
  if (!unit.empty() && unit.front() == '/') {
    sign = -1;
    start = 1;
  }
  while (start <= unit.size()) {
    const std::size_t end = unit.find_first_of("*/", start);
    const std::string_view token = trim(unit.substr(start, end == std::string_view::npos ? end : end - start));
    if (token.empty() || !parse_factor(token, sign, factor, dim)) return false;
    if (end == std::string_view::npos) return true;
    sign = unit[end] == '/' ? -1 : 1;
    start = end + 1;
  }
  return false;
}

}  // namespace

double parse(std::string_view text, const Kind& kind) {
  const std::string_view s = trim(text);
  double value = 0.0;
  auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  if (ec != std::errc() || !std::isfinite(value)) fail(kind, text);
  const std::string_view unit = trim(s.substr(static_cast<std::size_t>(end - s.data())));
  if (unit.empty()) {
    if (!kind.unit_optional) fail(kind, text);
    return value;
  }
  double factor = 1.0;
  Dimension dim;
  if (!parse_unit(unit, factor, dim) || !(dim == kind.dimension)) fail(kind, text);
  return value * factor;
}

double parse_ratio(std::string_view text) {
  const std::string_view s = trim(text);
  const auto colon = s.find(':');
  auto bad = [&]() -> double { throw UnitError("expected a ratio such as '1:2', got " + quote_input(text)); };
  if (colon == std::string_view::npos) return bad();
  const std::string_view a = trim(s.substr(0, colon)), b = trim(s.substr(colon + 1));
  double x = 0, y = 0;
  auto ra = std::from_chars(a.data(), a.data() + a.size(), x);
  auto rb = std::from_chars(b.data(), b.data() + b.size(), y);
  if (ra.ec != std::errc() || ra.ptr != a.data() + a.size() || rb.ec != std::errc() || rb.ptr != b.data() + b.size() ||
      !(x > 0) || !(y > 0) || !std::isfinite(x) || !std::isfinite(y))
    return bad();
  return x / y;
}

}  // namespace pneuma::units
