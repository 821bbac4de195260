#include "pneuma/core/error.h"

#include <cstdio>
#include <cstdlib>

namespace pneuma {

std::string without_nul(const std::string& message) {
  if (message.find('\0') == std::string::npos) return message;
  std::string out;
  out.reserve(message.size() + 8);
  for (const char c : message) {
    if (c == '\0') out += "\\x00";
    else out += c;
  }
  return out;
}

std::string location(const std::string& file, int line0, int column0) {
  return file + ":" + std::to_string(line0 + 1) + ":" + std::to_string(column0 + 1);
}

void assertion_failed(const char* expr, const char* file, int line, const char* message) {
  std::fprintf(stderr, "pneuma: internal check failed at %s:%d: %s (%s)\n", file, line, message, expr);
  std::abort();
}

}  // namespace pneuma
