#pragma once
// Text placed inside HTML, SVG or XML: the five characters markup gives a meaning escaped
// (element content and double-quoted attribute values alike).
#include <string>
#include <string_view>

namespace pneuma {

inline std::string escape_markup(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      default: out += c;
    }
  }
  return out;
}

}  // namespace pneuma
