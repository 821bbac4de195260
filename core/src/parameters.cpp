#include "pneuma/core/parameters.h"

#include <cmath>
#include <cstdio>

namespace pneuma::parameters {
namespace {

// Six significant digits, as fmt's {:g} (core uses no fmt).
std::string number(double value_display) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", value_display);
  return text;
}

}  // namespace

bool Parameter::accepts(double value_si) const {
  if (!std::isfinite(value_si)) return false;
  if (whole && value_si != std::floor(value_si)) return false;
  const bool above_min = min_closed ? value_si >= min : value_si > min;
  const bool below_max = max_closed ? value_si <= max : value_si < max;
  return above_min && below_max;
}

std::string Parameter::show(double value_si) const {
  const std::string unit = *display_unit ? std::string(" ") + display_unit : std::string();
  return number(value_si / si_per_display_unit) + unit;
}

std::string Parameter::range() const {
  const bool has_min = std::isfinite(min), has_max = std::isfinite(max);
  if (has_min && has_max) {
    // One unit, after the upper end: "from 1 to 4 hops".
    const std::string lo = number(min / si_per_display_unit);
    if (min_closed) return "from " + lo + " to " + (max_closed ? "" : "below ") + show(max);
    return "above " + lo + (max_closed ? " up to " : " and below ") + show(max);
  }
  if (has_min) return (min_closed ? "at least " : "above ") + show(min);
  if (has_max) return (max_closed ? "at most " : "below ") + show(max);
  return "any finite value";
}

std::string Parameter::expected() const {
  // "an edge of at least 0.1 mm", "a tolerance from 1e-12 to below 1"
  if (!std::isfinite(min) && !std::isfinite(max)) return std::string(noun) + " (" + range() + ")";
  const bool one_closed_end =
      std::isfinite(min) != std::isfinite(max) && (std::isfinite(min) ? min_closed : max_closed);
  return std::string(noun) + (one_closed_end ? " of " : " ") + range();
}

std::optional<std::string> Parameter::check(double value_si) const {
  if (accepts(value_si)) return std::nullopt;
  return "expected " + expected() + ", got " + show(value_si);
}

std::optional<std::string> Parameter::check(double value_si, std::string_view as_written) const {
  if (accepts(value_si)) return std::nullopt;
  return "expected " + expected() + ", got '" + std::string(as_written) + "'";
}

std::string Parameter::help_text(bool with_default) const {
  std::string text = std::string(help) + ", " + range();
  if (with_default && !std::isnan(default_si)) text += " (default " + show(default_si) + ")";
  return text;
}

}  // namespace pneuma::parameters
