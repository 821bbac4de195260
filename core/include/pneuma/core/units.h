#pragma once
// Quantities with units, read from text such as "0.1 L/cmH2O", "12 /min" or "500 mL", into SI.
//
// A unit expression is a product of atoms separated by '*' or '/', each with an optional
// integer power ("cm^2", "cmH2O*s/L", "/min"). The dimension of the result must match the
// kind the caller expects; otherwise, or when the unit is missing where the kind needs one,
// parse() throws UnitError whose message names the kind and gives an example:
//   expected a compliance such as '0.1 L/cmH2O', got '0.1'
#include <stdexcept>
#include <string>
#include <string_view>

#include "pneuma/core/error.h"

namespace pneuma::units {

// Exponents of the SI base dimensions (length, mass, time).
struct Dimension {
  int length = 0;
  int mass = 0;
  int time = 0;
  friend bool operator==(const Dimension&, const Dimension&) = default;
};

// The length of one unit of a mesh file (`--unit`, `mesh.unit`) must lie in [1 nm, 1 km]: no lung
// is drawn in anything else, and near the smallest doubles CGAL's remeshing divides by squared
// lengths that underflow (`--unit 1e-308mm` crashed it; found by scripts/mutate).
inline constexpr double kMinFileUnitM = 1e-9, kMaxFileUnitM = 1e3;

// What a value must be: its dimension, a human name and an example for error messages.
struct Kind {
  const char* name;
  Dimension dimension;
  const char* example;
  bool unit_optional = false;  // true only for pure numbers
};

namespace kind {
inline constexpr Kind length{"length", {1, 0, 0}, "3 mm"};
inline constexpr Kind area{"area", {2, 0, 0}, "1 cm^2"};
inline constexpr Kind volume{"volume", {3, 0, 0}, "500 mL"};
inline constexpr Kind duration{"duration", {0, 0, 1}, "2 s"};
inline constexpr Kind rate{"rate", {0, 0, -1}, "12 /min"};
inline constexpr Kind flow{"flow", {3, 0, -1}, "30 L/min"};
inline constexpr Kind pressure{"pressure", {-1, 1, -2}, "5 cmH2O"};
inline constexpr Kind shear_modulus{"shear modulus", {-1, 1, -2}, "3 kPa"};
inline constexpr Kind compliance{"compliance", {4, -1, 2}, "0.1 L/cmH2O"};
inline constexpr Kind resistance{"resistance", {-4, 1, -1}, "2 cmH2O*s/L"};
inline constexpr Kind number{"number", {0, 0, 0}, "0.5", true};
inline constexpr Kind fraction{"fraction", {0, 0, 0}, "0.5 or 50 %", true};
}  // namespace kind

class UnitError : public ValueError {
 public:
  using ValueError::ValueError;
};

// Parses "<number> <unit>" into SI. Throws UnitError.
double parse(std::string_view text, const Kind& kind);

// Parses a ratio "a:b" (both positive) and returns a/b. Throws UnitError.
double parse_ratio(std::string_view text);

// Conversion factors to SI.
inline constexpr double pa_per_cmh2o = 98.0665;
inline constexpr double m3_per_litre = 1e-3;
inline constexpr double m3_per_ml = 1e-6;
inline constexpr double m3_per_l_per_pa_per_cmh2o = m3_per_litre / pa_per_cmh2o;      // L/cmH2O -> m^3/Pa
inline constexpr double pa_s_per_m3_per_cmh2o_s_per_l = pa_per_cmh2o / m3_per_litre;  // cmH2O*s/L -> Pa*s/m^3

// From SI to the units outputs show (physiology CSV, report, Python): multiply an SI value.
inline constexpr double ml_per_m3 = 1.0 / m3_per_ml;
inline constexpr double litres_per_m3 = 1.0 / m3_per_litre;
inline constexpr double cmh2o_per_pa = 1.0 / pa_per_cmh2o;
// The reciprocals round to the exact powers of ten, so `x * ml_per_m3` is `x * 1e6` bit for bit.
static_assert(ml_per_m3 == 1e6 && litres_per_m3 == 1e3);

}  // namespace pneuma::units
