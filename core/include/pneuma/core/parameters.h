#pragma once
// The parameters that more than one front end takes (scenario YAML, CLI options, Python), each
// declared once with its valid range, default and help, so that every front end refuses the same
// values with the same words and only adds where the value came from:
//   CLI:    pneuma: --edge: expected an edge of at least 0.1 mm, got 0.05 mm
//   YAML:   s.yaml:2:30: mesh.edge: expected an edge of at least 0.1 mm, got '0.05 mm'
//   Python: edge_m: expected an edge of at least 0.1 mm, got 0.05 mm
#include <limits>
#include <optional>
#include <string>
#include <string_view>

#include "pneuma/core/units.h"

namespace pneuma::parameters {

inline constexpr double kUnbounded = std::numeric_limits<double>::infinity();

struct Parameter {
  const char* name;  // as the user writes it: the YAML key's last part, the CLI flag without '--'
  const char* noun;  // the value in a message: "an edge"
  const units::Kind* kind;
  const char* display_unit;    // the unit messages and help show values in ("" for a pure number)
  double si_per_display_unit;  // 1e-3 for mm
  double min = -kUnbounded;    // SI; an infinite bound is no bound
  double max = kUnbounded;
  bool min_closed = true;  // whether min itself is valid
  bool max_closed = true;
  bool whole = false;                                            // only whole numbers (a count)
  double default_si = std::numeric_limits<double>::quiet_NaN();  // NaN: none
  const char* help = "";

  bool accepts(double value_si) const;
  // `value_si` in the display unit: "0.05 mm", "1e-06".
  std::string show(double value_si) const;
  // The valid range: "at least 0.1 mm", "from 1e-12 to below 1", "from 1 to 4 hops".
  std::string range() const;
  // What a value must be: "an edge of at least 0.1 mm".
  std::string expected() const;
  // Nothing when `value_si` is valid; else "expected an edge of at least 0.1 mm, got 0.05 mm".
  std::optional<std::string> check(double value_si) const;
  // The same, quoting the value as the user wrote it: "..., got '1e-308 mm'" (YAML).
  std::optional<std::string> check(double value_si, std::string_view as_written) const;
  // An option's --help: "Target edge length, at least 0.1 mm (default 4 mm)"; without the default
  // where the option shows its own (CLI11's capture_default_str).
  std::string help_text(bool with_default = true) const;
};

// The target edge length of a lung surface (phantom, remeshing, labels): finer is millions of
// vertices on any lung (the scenario's size check names the edge for what is left).
inline constexpr Parameter kEdge{.name = "edge",
                                 .noun = "an edge",
                                 .kind = &units::kind::length,
                                 .display_unit = "mm",
                                 .si_per_display_unit = 1e-3,
                                 .min = 1e-4,
                                 .default_si = 4e-3,
                                 .help = "Target edge length"};

// The field solver's stopping rule, max |residual| <= tolerance * max force: below 1e-12 the
// residual is lost in rounding and the solver would never stop; 1 would stop before solving.
inline constexpr Parameter kFieldTolerance{.name = "tolerance",
                                           .noun = "a tolerance",
                                           .kind = &units::kind::number,
                                           .display_unit = "",
                                           .si_per_display_unit = 1.0,
                                           .min = 1e-12,
                                           .max = 1.0,
                                           .max_closed = false,
                                           .default_si = 1e-6,
                                           .help = "Stop when max UnShot <= tolerance * max force"};

// The field's clique size M in hops; the upper end is field::kMaxCliqueHops (a static_assert
// where both are seen keeps them equal).
inline constexpr Parameter kCliqueHops{.name = "clique",
                                       .noun = "a clique size",
                                       .kind = &units::kind::number,
                                       .display_unit = "hops",
                                       .si_per_display_unit = 1.0,
                                       .min = 1.0,
                                       .max = 4.0,
                                       .whole = true,
                                       .default_si = 1.0,
                                       .help = "Clique size M in hops"};

// The surface-area increase one unit of the field's scale s stands for.
inline constexpr Parameter kAreaUnit{.name = "area_unit",
                                     .noun = "an area unit",
                                     .kind = &units::kind::area,
                                     .display_unit = "cm^2",
                                     .si_per_display_unit = 1e-4,
                                     .min = 0.0,
                                     .min_closed = false,
                                     .default_si = 1e-4,
                                     .help = "Area increase per unit of scale s"};

}  // namespace pneuma::parameters
