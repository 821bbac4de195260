// The phantom-only build's stubs (PNEUMA_PHANTOM_ONLY, make demo; core/not_built.h), linked here
// in place of the CGAL units they stand for: each entry point answers with one line naming what
// is missing and exit code 5, never a result.
#include <gtest/gtest.h>

#include <string>

#include "pneuma/core/error.h"
#include "pneuma/mesh/anatomy/phantom.h"
#include "pneuma/mesh/labels/labels.h"
#include "pneuma/mesh/repair/remesh.h"
#include "pneuma/mesh/repair/repair.h"
#include "pneuma/mesh/volume/tetrahedralize.h"

namespace {

using namespace pneuma::mesh;

const std::string kNotBuilt =
    ": not built into this pneuma (`make demo` builds the phantom engine only; `make build` builds every feature)";

// The message of the UnsupportedError that `call` throws, after checking its exit code.
template <typename Call>
std::string not_built_message(Call call) {
  try {
    call();
  } catch (const pneuma::UnsupportedError& e) {
    EXPECT_EQ(static_cast<int>(e.code()), 5);
    return e.what();
  }
  ADD_FAILURE() << "no UnsupportedError";
  return {};
}

TEST(NotBuilt, EachStubSaysWhatIsMissingWithExitFive) {
  const TriangleMesh lung = make_lung_phantom({.lung = Lung::right, .edge_length_m = 0.02});
  EXPECT_EQ(not_built_message([&] { remesh_isotropic(lung); }), "isotropic remeshing" + kNotBuilt);
  EXPECT_EQ(not_built_message([&] { repair(lung, "lung.stl"); }), "lung.stl: mesh repair" + kNotBuilt);
  EXPECT_EQ(not_built_message([&] { repair_unchecked(lung, "lung.stl", {}, nullptr); }),
            "lung.stl: mesh repair" + kNotBuilt);
  EXPECT_EQ(not_built_message([&] { repair_and_remesh(lung, "lung.stl", {}, {}); }),
            "lung.stl: mesh repair and remeshing" + kNotBuilt);
  EXPECT_EQ(not_built_message([&] { tetrahedralize(lung, {.mesher = TetMesher::lattice}); }),
            "the inside of a surface as tetrahedra (the lattice mesher)" + kNotBuilt);
  EXPECT_EQ(not_built_message([] { detail::mesh_level_set({}, 1e-3, 1e-4); }),
            "a label map's surface (CGAL Mesh_3)" + kNotBuilt);
}

}  // namespace
