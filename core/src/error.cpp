#include "pneuma/core/error.h"

#include <cstdio>
#include <cstdlib>

namespace pneuma {

std::string location(const std::string& file, int line0, int column0) {
  return file + ":" + std::to_string(line0 + 1) + ":" + std::to_string(column0 + 1);
}

void assertion_failed(const char* expr, const char* file, int line, const char* message) {
  std::fprintf(stderr, "pneuma: internal check failed at %s:%d: %s (%s)\n", file, line, message, expr);
  std::abort();
}

}  // namespace pneuma
