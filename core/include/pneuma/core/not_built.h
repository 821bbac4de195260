#pragma once
// The phantom-only build (CMake option PNEUMA_PHANTOM_ONLY, what `make demo` builds) leaves out
// the translation units that a run of the built-in phantom never calls and that are slow to
// compile (CGAL Mesh_3, mesh repair and remeshing, ITK, DCMTK). Stubs define their functions
// there, and each says what is missing instead of doing it.
#include <string>

#include "pneuma/core/error.h"

namespace pneuma {

// Throws UnsupportedError (exit 5): "<what>: not built into this pneuma (...)".
[[noreturn]] inline void throw_not_built(const std::string& what) {
  throw UnsupportedError(what +
                         ": not built into this pneuma (`make demo` builds the phantom engine only; `make build` "
                         "builds every feature)");
}

}  // namespace pneuma
