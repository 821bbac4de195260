// A corpus of broken meshes made here: `pneuma mesh info` names each problem in one exact
// line with exit code 3 (4 for an unreadable file); `pneuma mesh repair` closes what it can
// and refuses the rest, leaving no partial output.
#include <gtest/gtest.h>

#include <fstream>
#include <iomanip>
#include <sstream>

#include "mesh_fixture.h"
#include "pneuma/mesh/geometry/validate.h"
#include "pneuma/mesh/io/mesh_io.h"
#include "pneuma/mesh/repair/repair.h"
#include "test_support.h"

using namespace pneuma::mesh;
using pneuma::test::run_pneuma;
using pneuma::test::TempDir;

namespace {

// A 10 mm icosphere (80 triangles) numbered as read_mesh() numbers it.
TriangleMesh sphere() { return test::canonical(make_icosphere(0.01, 1)); }

std::string write(const TempDir& dir, const std::string& name, const TriangleMesh& m) {
  write_mesh(dir / name, m, {.ascii = true});
  return (dir / name).string();
}

// The repaired output is closed, manifold, outward and free of self-intersections.
void expect_repaired(const TempDir& dir, const std::string& input, const std::string& expected_action) {
  const auto out = (dir / "repaired.ply").string();
  const auto r = run_pneuma({"mesh", "repair", input, "-o", out});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find(expected_action), std::string::npos) << r.out;
  const ValidationReport v = validate(read_mesh(out));
  EXPECT_TRUE(v.valid()) << v.summary();
  EXPECT_TRUE(v.closed());
  EXPECT_TRUE(v.manifold());
  EXPECT_GT(v.volume_m3, 0.0);
}

void expect_refused(const TempDir& dir, const std::string& input, const std::string& line) {
  const auto r = run_pneuma({"mesh", "repair", input, "-o", (dir / "repaired.ply").string()});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.err, line + "\n");
  EXPECT_FALSE(std::filesystem::exists(dir / "repaired.ply")) << "no partial output";
}

void expect_info_error(const std::string& file, int code, const std::string& what) {
  const auto r = run_pneuma({"mesh", "info", file});
  EXPECT_EQ(r.exit_code, code);
  EXPECT_EQ(r.err, file + ": " + what + "\n");
}

}  // namespace

TEST(MeshCli, ValidMeshInfo) {
  TempDir dir;
  const auto file = write(dir, "s.obj", sphere());
  const auto r = run_pneuma({"mesh", "info", file});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(r.err.empty()) << r.err;
  EXPECT_NE(r.out.find(file + ": 42 vertices, 80 triangles, 120 edges, 1 component\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("closed: yes, manifold: yes, consistently oriented: yes, genus: 0\n"), std::string::npos);
  EXPECT_NE(r.out.find("self-intersections: 0\nvalid\n"), std::string::npos);
}

TEST(MeshCli, Hole) {
  TempDir dir;
  TriangleMesh m = sphere();
  const Triangle removed = m.triangles[10];
  m.triangles.erase(m.triangles.begin() + 10);
  const auto file = write(dir, "hole.obj", m);
  // The first boundary edge in (low, high) order, and the face that still uses it.
  std::array<std::uint32_t, 2> first{~0u, ~0u};
  for (int k = 0; k < 3; ++k) {
    const std::array<std::uint32_t, 2> e{std::min(removed[k], removed[(k + 1) % 3]),
                                         std::max(removed[k], removed[(k + 1) % 3])};
    first = std::min(first, e);
  }
  std::size_t face = 0;
  for (std::size_t f = 0; f < m.triangles.size(); ++f) {
    const auto& t = m.triangles[f];
    if (std::count(t.begin(), t.end(), first[0]) && std::count(t.begin(), t.end(), first[1])) face = f;
  }
  expect_info_error(file, 3,
                    "open surface: 1 hole (3 boundary edges), first at edge " + std::to_string(first[0]) + "-" +
                        std::to_string(first[1]) + " of face " + std::to_string(face));
  expect_repaired(dir, file, "filled 1 hole with 1 face");
}

TEST(MeshCli, FlippedFace) {
  TempDir dir;
  TriangleMesh m = sphere();
  std::swap(m.triangles[7][1], m.triangles[7][2]);
  const auto file = write(dir, "flipped.obj", m);
  expect_info_error(file, 3, "face 7 is oriented against its neighbours");
  expect_repaired(dir, file, "flipped 1 face to match their neighbours");
}

TEST(MeshCli, InsideOut) {
  TempDir dir;
  TriangleMesh m = sphere();
  for (auto& t : m.triangles) std::swap(t[1], t[2]);
  const auto file = write(dir, "inverted.obj", m);
  std::ostringstream volume;
  volume << std::setprecision(4) << -enclosed_volume(sphere()) * 1e6;
  expect_info_error(file, 3, "inside out: the surface encloses a negative volume (" + volume.str() + " mL)");
  expect_repaired(dir, file, "reversed 1 inside-out component");
}

TEST(MeshCli, NonManifoldEdgeOnAnOpenSurfaceIsRefused) {
  // Two tetrahedra that share the edge 0-1 (and nothing else): four faces on one edge. Closed,
  // it would be rebuilt from its inside (tests/mesh/rebuild_test.cpp); with a face missing it has
  // no inside to rebuild from.
  TempDir dir;
  // PLY keeps the file's vertex numbering, which the messages use.
  auto with_faces = [](const std::string& count) {
    return "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
           "element face " +
           count +
           "\nproperty list uchar int vertex_indices\nend_header\n"
           "0 0 0\n0 0 1\n1 0 0\n0 1 0\n-1 0 0\n0 -1 0\n"
           "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n"
           "3 0 4 1\n3 0 1 5\n3 0 5 4\n";
  };
  const auto closed = dir.write("bowtie.ply", with_faces("8") + "3 1 4 5\n").string();
  expect_info_error(closed, 3, "non-manifold edge 0-1 (shared by faces 0, 1, 4, 5)");
  const auto open = dir.write("open-bowtie.ply", with_faces("7")).string();
  expect_refused(dir, open,
                 open +
                     ": cannot repair: non-manifold edge 0-1 (shared by faces 0, 1, 4, 5) (and the surface is open, so "
                     "it cannot be rebuilt from its inside: re-export the surface, or rebuild it from its label map "
                     "with 'pneuma mesh from-labels')");
}

TEST(MeshCli, TwoComponentsAreValidAndKept) {
  TempDir dir;
  const auto file = write(dir, "two.obj", test::joined(sphere(), test::translated(sphere(), {0.05, 0, 0})));
  const auto r = run_pneuma({"mesh", "info", file});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find(file + ": 84 vertices, 160 triangles, 240 edges, 2 components\n"), std::string::npos) << r.out;
  expect_repaired(dir, file, "nothing to repair");
  EXPECT_EQ(validate(read_mesh(dir / "repaired.ply")).component_count, 2u);
}

TEST(MeshCli, EmptyFile) {
  TempDir dir;
  const auto file = dir.write("empty.stl", "").string();
  expect_info_error(file, 3, "empty file");
  expect_refused(dir, file, file + ": empty file");
}

TEST(MeshCli, TruncatedBinaryStl) {
  TempDir dir;
  write_mesh(dir / "full.stl", sphere());  // 84 + 80 * 50 = 4084 bytes
  std::string bytes = pneuma::test::read_text(dir / "full.stl");
  ASSERT_EQ(bytes.size(), 4084u);
  bytes.resize(2000);
  const auto file = dir.write("cut.stl", bytes).string();
  expect_info_error(file, 3,
                    "truncated binary STL: the header announces 80 triangles (4084 bytes), the file has 2000 bytes");
}

TEST(MeshCli, NanCoordinates) {
  TempDir dir;
  const auto file =
      dir.write("nan.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 nan\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n").string();
  expect_info_error(file, 3, "face 1 has a non-finite vertex coordinate (nan)");
}

TEST(MeshCli, NotAMesh) {
  TempDir dir;
  const auto text = dir.write("notes.obj", "these are notes, not a mesh\n").string();
  expect_info_error(text, 3, "no triangles in the file (not a surface mesh)");
  const auto other = dir.write("notes.txt", "these are notes, not a mesh\n").string();
  expect_info_error(
      other, 3,
      "unknown mesh format '.txt' (expected a surface that assimp reads: .stl, .obj, .ply, .off, .gltf, .glb, ..., or VTK .vtk, .vtp)");
  const auto ply = dir.write("notes.ply", "these are notes, not a mesh\n").string();
  expect_info_error(ply, 3, "PLY header line 1: expected 'ply', got 'these are notes, not a mesh'");
}

TEST(MeshCli, MissingFileAndBadOptions) {
  TempDir dir;
  const auto missing = (dir / "missing.stl").string();
  expect_info_error(missing, 4, "cannot read: no such file");
  const auto file = write(dir, "s.obj", sphere());
  auto r = run_pneuma({"mesh", "remesh", file, "--edge", "0 mm", "-o", (dir / "o.ply").string()});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "pneuma: --edge: expected an edge of at least 0.1 mm, got 0 mm\n");
  r = run_pneuma({"mesh", "remesh", file, "--edge", "3 kg", "-o", (dir / "o.ply").string()});
  EXPECT_EQ(r.exit_code, 2);
  r = run_pneuma({"mesh", "info", file, "--unit", "kg"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "pneuma: --unit: expected a length unit such as 'mm', 'cm' or 'm', got 'kg'\n");
  r = run_pneuma({"phantom", "--lung", "middle", "-o", (dir / "p.ply").string()});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "pneuma: --lung: expected left, right or both, got 'middle'\n");
  EXPECT_FALSE(std::filesystem::exists(dir / "o.ply"));
  EXPECT_FALSE(std::filesystem::exists(dir / "p.ply"));
}

TEST(MeshCli, RemeshRepairsAnInvalidSurfaceFirst) {
  TempDir dir;
  TriangleMesh m = sphere();
  std::swap(m.triangles[3][1], m.triangles[3][2]);
  const auto file = write(dir, "flipped.obj", m);
  const auto out = (dir / "o.ply").string();
  const auto r = run_pneuma({"mesh", "remesh", file, "--edge", "3mm", "-o", out});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(
      r.out.find(file +
                 ": not a valid surface (face 3 is oriented against its neighbours); repairing before remeshing\n" +
                 file + ": flipped 1 face to match their neighbours\n"),
      std::string::npos)
      << r.out;
  EXPECT_TRUE(validate(read_mesh(out)).valid());
}

namespace {

// A 10 mm sphere (1280 faces) with vertex `v` dragged 5 % past its first neighbour: the faces
// around it fold over their neighbours (thin slivers that intersect).
TriangleMesh folded_sphere(std::uint32_t v = 100) {
  TriangleMesh m = test::canonical(make_icosphere(0.01, 3));
  std::uint32_t w = v;
  for (const Triangle& t : m.triangles) {
    for (int k = 0; k < 3; ++k) {
      if (t[k] == v) w = t[(k + 1) % 3];
    }
  }
  m.vertices[v] = m.vertices[w] + 0.05 * (m.vertices[w] - m.vertices[v]);
  return m;
}

}  // namespace

TEST(MeshRepair, SelfIntersectingSliversAreRemovedAndRefilled) {
  const TriangleMesh m = folded_sphere();
  const ValidationReport before = validate(m);
  ASSERT_GT(before.self_intersection_count.value_or(0), 0u) << before.summary();
  const RepairResult r = repair(m, "folded.obj");
  const ValidationReport after = validate(r.mesh);
  EXPECT_TRUE(after.valid()) << after.summary();
  EXPECT_EQ(after.genus, 0);
  EXPECT_EQ(r.report.self_intersecting_pairs, *before.self_intersection_count);
  EXPECT_GE(r.report.removed_intersecting_faces, 2u);
  EXPECT_GE(r.report.filled_holes, 1u);
  // The sphere's volume, to the size of the refilled patch.
  EXPECT_NEAR(enclosed_volume(r.mesh) / enclosed_volume(test::canonical(make_icosphere(0.01, 3))), 1.0, 0.01);
  bool named = false;
  for (const auto& a : r.report.actions()) named |= a.find("pairs of intersecting faces") != std::string::npos;
  EXPECT_TRUE(named);
}

TEST(MeshRepair, RepairAndRemeshGivesAValidSurface) {
  const RepairRemeshResult r = repair_and_remesh(folded_sphere(), "folded.obj", {}, {.target_edge_length_m = 1e-3});
  const ValidationReport after = validate(r.remesh.mesh);
  EXPECT_TRUE(after.valid()) << after.summary();
  EXPECT_GT(r.repair.self_intersecting_pairs, 0u);
  EXPECT_NEAR(r.remesh.after.mean_edge_m / 1e-3, 1.0, 0.2);
}

TEST(MeshRepair, SmallIslandsAreDroppedLungsAreKept) {
  const TriangleMesh lungs = test::joined(sphere(), test::translated(sphere(), {0.05, 0, 0}));
  const TriangleMesh speck = test::translated(test::canonical(make_icosphere(0.0005, 1)), {0.0, 0.05, 0});
  const RepairResult r = repair(test::joined(lungs, speck), "specks.obj");
  EXPECT_EQ(r.report.dropped_components, 1u);
  EXPECT_EQ(r.report.dropped_component_faces, 80u);
  EXPECT_EQ(validate(r.mesh).component_count, 2u);
  EXPECT_NEAR(enclosed_volume(r.mesh), enclosed_volume(lungs), 1e-12);
}

TEST(MeshCli, SliversRepairFromTheCommandLine) {
  TempDir dir;
  const auto file = write(dir, "folded.ply", folded_sphere());
  const auto r = run_pneuma({"mesh", "repair", file, "-o", (dir / "repaired.ply").string()});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("pairs of intersecting faces"), std::string::npos) << r.out;
  const auto r2 = run_pneuma({"mesh", "remesh", file, "--edge", "1.5mm", "-o", (dir / "remeshed.ply").string()});
  EXPECT_EQ(r2.exit_code, 0) << r2.err;
  EXPECT_TRUE(validate(read_mesh(dir / "remeshed.ply")).valid());
}

TEST(MeshCli, InfoOnAnInvalidMeshStillPrintsTheWholeReport) {
  TempDir dir;
  const auto file = write(dir, "folded.ply", folded_sphere());
  const auto r = run_pneuma({"mesh", "info", file});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_NE(r.out.find(file + ": "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("closed: yes, manifold: yes"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\ninvalid\n"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_EQ(r.err.rfind(file + ": self-intersection", 0), 0u) << r.err;
}
