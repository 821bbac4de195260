// The HDF5 cache (round trip, determinism, refusal of damaged files, reuse by key) and the
// `pneuma field` command's output and one-line errors.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <fstream>

#include "pneuma/core/error.h"
#include "pneuma/model/field_cache.h"
#include "pneuma/scenario/tissue_config.h"
#include "test_support.h"

using namespace pneuma;
using namespace pneuma::field;
using pneuma::scenario::load_tissue;
using namespace pneuma::model;
using pneuma::test::read_text;
using pneuma::test::run_pneuma;
using pneuma::test::TempDir;

namespace {

Tissue preset(const std::string& name) {
  return load_tissue(test::source_dir() / "configs" / "tissue" / (name + ".yaml"));
}

template <typename T>
bool same_bytes(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

void write_bytes(const std::filesystem::path& p, const std::string& bytes) {
  std::ofstream(p, std::ios::binary | std::ios::trunc) << bytes;
}

std::string load_error(const std::filesystem::path& p) {
  try {
    load_field(p);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(FieldCache, RoundTripsBitForBitAndWritesTheSameBytesTwice) {
  TempDir dir;
  const auto rest = mesh::make_icosphere(0.1, 3);
  const model::FieldRecord model = model::compute_field_record(rest, preset("healthy-upright"), default_field_options);
  save_field(dir / "a.h5", model);
  const model::FieldRecord loaded = load_field(dir / "a.h5");
  EXPECT_TRUE(same_bytes(loaded.rest.vertices, model.rest.vertices));
  EXPECT_TRUE(same_bytes(loaded.rest.triangles, model.rest.triangles));
  EXPECT_TRUE(same_bytes(loaded.unit_displacement, model.unit_displacement));
  EXPECT_TRUE(same_bytes(loaded.force, model.force));
  EXPECT_TRUE(same_bytes(loaded.shear_modulus_pa, model.shear_modulus_pa));
  EXPECT_EQ(loaded.metadata.key, model.metadata.key);
  EXPECT_EQ(loaded.metadata.tissue, "healthy-upright");
  EXPECT_EQ(loaded.metadata.solver, "cg");
  EXPECT_EQ(loaded.metadata.tolerance, 1e-6);
  EXPECT_EQ(loaded.metadata.pneuma_version, PNEUMA_VERSION);
  save_field(dir / "b.h5", loaded);
  save_field(dir / "c.h5", model::compute_field_record(rest, preset("healthy-upright"), default_field_options));
  EXPECT_EQ(read_text(dir / "a.h5"), read_text(dir / "b.h5"));
  EXPECT_EQ(read_text(dir / "a.h5"), read_text(dir / "c.h5"));
}

TEST(FieldCache, RefusesDamagedAndForeignFilesWithOneLine) {
  TempDir dir;
  const auto rest = mesh::make_icosphere(0.1, 2);
  const model::FieldRecord model =
      model::compute_field_record(rest, preset("fibrotic-lower-lobe"), default_field_options);
  save_field(dir / "good.h5", model);
  const std::string bytes = read_text(dir / "good.h5");

  write_bytes(dir / "truncated.h5", bytes.substr(0, bytes.size() / 2));
  EXPECT_EQ(load_error(dir / "truncated.h5"),
            (dir / "truncated.h5").string() +
                ": not a pneuma field file: its bytes do not match its seal (truncated or damaged)");

  // Edit one stored displacement value in place: the seal catches it before HDF5 reads a byte.
  std::string edited = bytes;
  const auto at = edited.find(std::string(reinterpret_cast<const char*>(model.unit_displacement[7].data()), 8));
  ASSERT_NE(at, std::string::npos);
  edited[at + 3] = static_cast<char>(edited[at + 3] ^ 0x10);
  write_bytes(dir / "edited.h5", edited);
  EXPECT_EQ(load_error(dir / "edited.h5"),
            (dir / "edited.h5").string() +
                ": not a pneuma field file: its bytes do not match its seal (truncated or damaged)");

  // The first "pneuma-field" is the seal's own name: edited, the file is no longer pneuma's.
  std::string foreign = bytes;
  const auto name = foreign.find("pneuma-field");
  ASSERT_NE(name, std::string::npos);
  foreign.replace(name, 12, "other-format");
  write_bytes(dir / "foreign.h5", foreign);
  EXPECT_EQ(
      load_error(dir / "foreign.h5"),
      (dir / "foreign.h5").string() +
          ": not a pneuma field file: an HDF5 file without pneuma's seal (from elsewhere, or from an older pneuma)");
  // Another program's HDF5 file (its signature at 0), or one from before the seal.
  write_bytes(dir / "other.h5", std::string("\x89HDF\r\n\x1a\n", 8) + std::string(600, '\0'));
  EXPECT_EQ(load_error(dir / "other.h5"), (dir / "other.h5").string() +
                                              ": not a pneuma field file: an HDF5 file without "
                                              "pneuma's seal (from elsewhere, or from an older pneuma)");

  // A damaged header claiming 2^40 vertices (found by fuzz_field_cache: the reader allocated what
  // the header claimed, ~26 TB, and died): the seal refuses it; the reader's own bound on claimed
  // sizes stays behind it.
  std::string huge = bytes;
  const std::uint64_t dims[2] = {model.rest.vertex_count(), 3}, claimed = std::uint64_t{1} << 40;
  const auto dims_at = huge.find(std::string(reinterpret_cast<const char*>(dims), sizeof dims));
  ASSERT_NE(dims_at, std::string::npos);
  huge.replace(dims_at, 8, std::string(reinterpret_cast<const char*>(&claimed), 8));
  write_bytes(dir / "huge.h5", huge);
  EXPECT_EQ(
      load_error(dir / "huge.h5"),
      (dir / "huge.h5").string() + ": not a pneuma field file: its bytes do not match its seal (truncated or damaged)");

  write_bytes(dir / "text.h5", "hello\n");
  EXPECT_EQ(load_error(dir / "text.h5"), (dir / "text.h5").string() + ": not a pneuma field file: not an HDF5 file");
  write_bytes(dir / "empty.h5", "");
  EXPECT_EQ(load_error(dir / "empty.h5"), (dir / "empty.h5").string() + ": not a pneuma field file: not an HDF5 file");
  EXPECT_THROW(load_field(dir / "missing.h5"), IoError);
}

TEST(FieldCache, LoadOrComputeReusesOnlyAMatchingKey) {
  TempDir dir;
  const auto rest = mesh::make_icosphere(0.1, 2);
  const auto path = dir / "cache.h5";
  const model::CacheLookup first = load_or_compute(path, rest, preset("healthy-upright"));
  EXPECT_FALSE(first.reused);
  const model::CacheLookup second = load_or_compute(path, rest, preset("healthy-upright"));
  EXPECT_TRUE(second.reused);
  EXPECT_TRUE(same_bytes(first.record.unit_displacement, second.record.unit_displacement));
  // Another tissue, tolerance or mesh: a new key, so the field is recomputed and replaced.
  EXPECT_FALSE(load_or_compute(path, rest, preset("fibrotic-lower-lobe")).reused);
  FieldOptions tighter;
  tighter.tolerance = 1e-8;
  EXPECT_FALSE(load_or_compute(path, rest, preset("fibrotic-lower-lobe"), tighter).reused);
  EXPECT_TRUE(load_or_compute(path, rest, preset("fibrotic-lower-lobe"), tighter).reused);
  mesh::TriangleMesh moved = rest;
  moved.vertices[0].x() += 1e-9;
  EXPECT_FALSE(load_or_compute(path, moved, preset("fibrotic-lower-lobe"), tighter).reused);
}

TEST(FieldCache, ADamagedOrForeignCacheIsRecomputedAndReplacedNeverUsed) {
  TempDir dir;
  const auto rest = mesh::make_icosphere(0.1, 2);
  const auto path = dir / "cache.h5";
  const model::CacheLookup fresh = load_or_compute(path, rest, preset("healthy-upright"));
  const std::string good = read_text(path);
  // The oracle: a direct computation of the field for these inputs.
  const model::FieldRecord direct = model::compute_field_record(rest, preset("healthy-upright"), default_field_options);

  std::string edited = good;  // one displacement value changed: a wrong field if it were used
  const auto at = edited.find(std::string(reinterpret_cast<const char*>(direct.unit_displacement[5].data()), 8));
  ASSERT_NE(at, std::string::npos);
  edited[at + 2] = static_cast<char>(edited[at + 2] ^ 0x20);
  std::string foreign = good;
  foreign.replace(foreign.find("pneuma-field"), 12, "other-format");
  const std::pair<std::string, std::string> cases[] = {
      {"not a field", "not an HDF5 file"},
      {good.substr(0, good.size() / 3), "its bytes do not match its seal (truncated or damaged)"},
      {edited, "its bytes do not match its seal (truncated or damaged)"},
      {foreign, "an HDF5 file without pneuma's seal (from elsewhere, or from an older pneuma)"},
  };
  for (const auto& [bytes, why] : cases) {
    write_bytes(path, bytes);
    const model::CacheLookup again = load_or_compute(path, rest, preset("healthy-upright"));
    EXPECT_FALSE(again.reused) << why;
    EXPECT_EQ(again.discarded, path.string() + ": not a pneuma field file: " + why);
    EXPECT_TRUE(same_bytes(again.record.unit_displacement, direct.unit_displacement)) << why;
    EXPECT_EQ(read_text(path), good) << why << ": the file is replaced by the recomputed field";
    EXPECT_TRUE(load_or_compute(path, rest, preset("healthy-upright")).reused) << why;
  }
  EXPECT_TRUE(fresh.discarded.empty());
}

TEST(FieldCli, WritesTheFieldAndPrintsASummary) {
  TempDir dir;
  const auto r = run_pneuma({"field", "icosphere:0.1:3", "--tissue", "healthy-upright", "-o", (dir / "f.h5").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(r.err.empty()) << r.err;
  EXPECT_NE(r.out.find("field: 642 mass nodes + 1920 spring nodes, tissue healthy-upright, solver cg"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("displacement per cm^2 of surface area: min "), std::string::npos) << r.out;
  const model::FieldRecord m = load_field(dir / "f.h5");
  EXPECT_EQ(m.rest.vertex_count(), 642u);
  EXPECT_EQ(dir.files(), std::vector<std::string>{"f.h5"});
  const auto shot = run_pneuma({"field", "icosphere:0.1:2", "--tissue", "healthy-supine", "--solver", "shot",
                                "--clique", "2", "-o", (dir / "g.h5").string()});
  ASSERT_EQ(shot.exit_code, 0) << shot.err;
  EXPECT_EQ(load_field(dir / "g.h5").metadata.clique_hops, 2);
}

TEST(FieldCli, ReadsMeshFilesInTheirUnitAndThePhantom) {
  // A phantom written in millimetres and read back in millimetres is the same surface: the
  // field of the file equals the field of the phantom (same mesh up to float rounding).
  TempDir dir;
  ASSERT_EQ(run_pneuma({"phantom", "--lung", "right", "--edge", "15mm", "-o", (dir / "lung.ply").string()}).exit_code,
            0);
  auto r = run_pneuma({"field", (dir / "lung.ply").string(), "--unit", "mm", "--tissue", "healthy-upright", "-o",
                       (dir / "a.h5").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_pneuma({"field", "phantom:right", "--edge", "15mm", "--tissue", "healthy-upright", "-o",
                  (dir / "b.h5").string(), "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const model::FieldRecord a = load_field(dir / "a.h5"), b = load_field(dir / "b.h5");
  ASSERT_EQ(a.rest.vertex_count(), b.rest.vertex_count());
  double largest = 0.0, difference = 0.0;
  for (std::size_t i = 0; i < a.rest.vertex_count(); ++i) {
    EXPECT_LT((a.rest.vertices[i] - b.rest.vertices[i]).norm(), 1e-6);  // float32 in the PLY, in mm
    largest = std::max(largest, b.unit_displacement[i].norm());
    difference = std::max(difference, (a.unit_displacement[i] - b.unit_displacement[i]).norm());
  }
  EXPECT_LT(difference, 1e-4 * largest);
  r = run_pneuma({"field", "phantom:middle", "--tissue", "healthy-upright", "-o", (dir / "c.h5").string()});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "pneuma: MESH: expected phantom:left, phantom:right or phantom:both, got 'phantom:middle'\n");
}

TEST(FieldCli, BadInputIsOneLineWithItsExitCode) {
  TempDir dir;
  const auto out = (dir / "f.h5").string();
  const auto bad_key = dir.write("bad-key.yaml", "posture: upright\nstiffness:\n  model: gradient\n  profile: linear\n"
                                                 "  nondependent: 2 kPa\n  dependent: 1 kPa\n  slope: 3\n");
  const auto bad_unit =
      dir.write("bad-unit.yaml", "posture: upright\nstiffness:\n  model: gradient\n  profile: linear\n"
                                 "  nondependent: 2 kPa\n  dependent: 1 cmH2O/L\n");
  struct Case {
    std::vector<std::string> args;
    int exit_code;
    std::string err;
  };
  const std::vector<Case> cases = {
      {{"field", "icosphere:0.1:2", "--tissue", bad_key.string(), "-o", out},
       3,
       bad_key.string() +
           ":7:3: stiffness.slope: unknown key; expected one of: bands, dependent, model, nondependent, profile"},
      {{"field", "icosphere:0.1:2", "--tissue", bad_unit.string(), "-o", out},
       3,
       bad_unit.string() + ":6:14: stiffness.dependent: expected a shear modulus such as '3 kPa', got '1 cmH2O/L'"},
      {{"field", "icosphere:0.1:2", "--tissue", "healthy-upright", "--solver", "magic", "-o", out},
       2,
       "pneuma: --solver: expected one of shot, sweep, direct, cg; got 'magic'"},
      {{"field", "icosphere:0.1:2", "--tissue", "healthy-upright", "--solver", "cg", "--clique", "3", "-o", out},
       2,
       "pneuma: --solver cg: needs --clique 1; use shot, sweep or direct for larger cliques"},
      {{"field", "icosphere:0.1:2", "--tissue", "healthy-upright", "--clique", "5", "-o", out},
       2,
       "pneuma: --clique: expected a clique size from 1 to 4 hops, got 5 hops"},
      {{"field", "icosphere:0.1:2", "--tissue", "healthy-upright", "--clique", "2", "-o", out},
       2,
       "pneuma: --clique 2: the default solver (cg) takes clique 1 only; add --solver shot, sweep or direct"},
      {{"field", "icosphere:0.1:2", "--tissue", "healthy-martian", "-o", out},
       2,
       "pneuma: --tissue: no preset 'healthy-martian' (looked for " +
           (test::source_dir() / "configs" / "tissue" / "healthy-martian.yaml").string() +
           "; shipped presets: fibrotic-lower-lobe, healthy-supine, healthy-supine-slide, healthy-upright, healthy-upright-ct)"},
      {{"field", "icosphere:big:2", "--tissue", "healthy-upright", "-o", out},
       2,
       "pneuma: MESH: expected icosphere:<radius 1 mm to 10 m>:<subdivisions 0-9>, such as icosphere:0.1:5, got "
       "'icosphere:big:2'"},
      // #29: options out of range are usage errors (exit 2), not file errors or internal ones.
      {{"field", "icosphere:1e308m:2", "--tissue", "healthy-upright", "-o", out},
       2,
       "pneuma: MESH: expected icosphere:<radius 1 mm to 10 m>:<subdivisions 0-9>, such as icosphere:0.1:5, got "
       "'icosphere:1e308m:2'"},
      {{"field", "icosphere:0.1:2", "--tissue", "healthy-upright", "--tol", "1e-300", "-o", out},
       2,
       "pneuma: --tol: expected a tolerance from 1e-12 to below 1, got 1e-300"},
      {{"field", "phantom:right", "--tissue", "healthy-upright", "--edge", "1e-308mm", "-o", out},
       2,
       "pneuma: --edge: expected an edge of at least 0.1 mm, got 1e-308 mm"},
  };
  for (const Case& c : cases) {
    const auto r = run_pneuma(c.args);
    EXPECT_EQ(r.exit_code, c.exit_code) << c.err;
    EXPECT_EQ(r.err, c.err + "\n");
    EXPECT_TRUE(r.out.empty()) << r.out;
  }
  EXPECT_EQ(dir.files(), (std::vector<std::string>{"bad-key.yaml", "bad-unit.yaml"})) << "no partial output";
}
