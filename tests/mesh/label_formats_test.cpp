// Label maps in every format read_label_map takes (NIfTI, NRRD, .seg.nrrd, MetaImage,
// TotalSegmentator's mask folder and multilabel file), written here byte by byte, with the
// one-line errors for damaged files. Oracles: voxel counts and boxes computed here, the
// transform the test wrote, and the surface of the NIfTI CT case (../shared/data/ct-lobes).
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <map>

#include "label_formats_fixture.h"
#include "nifti_fixture.h"
#include "pneuma/core/error.h"
#include "pneuma/mesh/geometry/validate.h"
#include "pneuma/mesh/labels/labels.h"
#include "test_support.h"

using namespace pneuma::mesh;
using namespace pneuma::image;
using namespace pneuma::mesh::test;
using pneuma::test::TempDir;

namespace {

using Size3 = std::array<std::size_t, 3>;

// The one-line message of what `f` throws (of the given type), or "" when it throws nothing.
template <typename E, typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  return "";
}

std::map<int, std::size_t> counts(const std::vector<std::int32_t>& labels) {
  std::map<int, std::size_t> n;
  for (std::int32_t l : labels) ++n[l];
  return n;
}

// A crop of a label map: the voxels [lo, lo + size) and its transform (the same LPS points).
struct Crop {
  Size3 lo{}, size{};
  std::vector<std::int16_t> labels;
  Eigen::Matrix4d ijk_to_lps;
};

Crop crop_around(const LabelMap& map, const std::vector<int>& labels, const Size3& margin) {
  Size3 lo{~std::size_t{0}, ~std::size_t{0}, ~std::size_t{0}}, hi{0, 0, 0};
  for (std::size_t k = 0, v = 0; k < map.size[2]; ++k)
    for (std::size_t j = 0; j < map.size[1]; ++j)
      for (std::size_t i = 0; i < map.size[0]; ++i, ++v) {
        if (std::find(labels.begin(), labels.end(), map.labels[v]) == labels.end()) continue;
        const Size3 ijk{i, j, k};
        for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], ijk[a]), hi[a] = std::max(hi[a], ijk[a]);
      }
  Crop c;
  for (int a = 0; a < 3; ++a) {
    c.lo[a] = lo[a] > margin[a] ? lo[a] - margin[a] : 0;
    c.size[a] = std::min(hi[a] + margin[a] + 1, map.size[a]) - c.lo[a];
  }
  c.labels.resize(c.size[0] * c.size[1] * c.size[2]);
  for (std::size_t k = 0, v = 0; k < c.size[2]; ++k)
    for (std::size_t j = 0; j < c.size[1]; ++j)
      for (std::size_t i = 0; i < c.size[0]; ++i, ++v) {
        const std::size_t from = (i + c.lo[0]) + map.size[0] * ((j + c.lo[1]) + map.size[1] * (k + c.lo[2]));
        c.labels[v] = static_cast<std::int16_t>(map.labels[from]);
      }
  Eigen::Matrix4d shift = Eigen::Matrix4d::Identity();
  shift.block<3, 1>(0, 3) =
      Eigen::Vector3d(static_cast<double>(c.lo[0]), static_cast<double>(c.lo[1]), static_cast<double>(c.lo[2]));
  c.ijk_to_lps = map.ijk_to_lps * shift;
  return c;
}

// The crop's qform: the case's, moved to the crop's first voxel (RAS millimetres).
Qform crop_qform(const Qform& q, const Crop& c) {
  Qform out = q;
  const Eigen::Vector3d lps = c.ijk_to_lps.block<3, 1>(0, 3);
  out.offset = Eigen::Vector3d(-lps.x(), -lps.y(), lps.z()) * 1e3;
  return out;
}

std::array<int, 3> int_size(const Size3& s) {
  return {static_cast<int>(s[0]), static_cast<int>(s[1]), static_cast<int>(s[2])};
}

std::vector<std::int16_t> relabel(const std::vector<std::int16_t>& labels, const std::map<int, int>& to) {
  std::vector<std::int16_t> out(labels.size(), 0);
  for (std::size_t v = 0; v < labels.size(); ++v) {
    const auto found = to.find(labels[v]);
    if (found != to.end()) out[v] = static_cast<std::int16_t>(found->second);
  }
  return out;
}

// Same surface: volume within 0.5 %, bounding box within half a voxel.
void expect_same_surface(const LabelSurface& s, const LabelSurface& reference, double half_voxel_m,
                         const std::string& what) {
  EXPECT_TRUE(validate(s.mesh).closed()) << what;
  EXPECT_NEAR(enclosed_volume(s.mesh) / enclosed_volume(reference.mesh), 1.0, 0.005) << what;
  const auto box = bounding_box(s.mesh.vertices), ref = bounding_box(reference.mesh.vertices);
  const double box_difference_m =
      std::max((box[0] - ref[0]).cwiseAbs().maxCoeff(), (box[1] - ref[1]).cwiseAbs().maxCoeff());
  ::testing::Test::RecordProperty(
      what, "volume ratio - 1: " + std::to_string(enclosed_volume(s.mesh) / enclosed_volume(reference.mesh) - 1) +
                ", bounding box max difference (mm): " + std::to_string(box_difference_m * 1e3));
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(box[0][a], ref[0][a], half_voxel_m) << what << " axis " << a;
    EXPECT_NEAR(box[1][a], ref[1][a], half_voxel_m) << what << " axis " << a;
  }
}

constexpr const char* kCase = "case006";  // the smallest of the six (512 x 512 x 213, 1.5 mm slices)
const LabelSurfaceOptions kCoarse{.edge_length_m = 4e-3};

std::filesystem::path ct_case() { return pneuma::test::ct_lobes_dir() / (std::string(kCase) + "_lobes.nii.gz"); }

// Slicer's segment keys for the five lobes of the case (its label values).
std::string lobe_segments() {
  const char* names[] = {"lung_upper_lobe_left", "lung_lower_lobe_left", "lung_upper_lobe_right",
                         "lung_middle_lobe_right", "lung_lower_lobe_right"};
  std::string lines;
  for (int s = 0; s < 5; ++s) {
    const std::string key = "Segment" + std::to_string(s) + "_";
    lines += fmt::format("{0}ID:=Segment_{1}\n{0}Name:={2}\n{0}LabelValue:={1}\n{0}Layer:=0\n", key, s + 1, names[s]);
  }
  return lines;
}

// The CT case read once for the tests that use it: the left lung's crop, the voxel counts of
// the whole file, and the reference surface from the NIfTI file.
struct CtCase {
  Crop crop;
  Qform crop_qform;
  std::map<int, std::size_t> counts;
  double half_voxel_m = 0.0;
  LabelSurface left;  // labels 1, 2 at 4 mm
};

const CtCase& ct_case_data() {
  static const CtCase data = [] {
    const LabelMap nifti = read_label_map(ct_case());
    CtCase d;
    d.crop = crop_around(nifti, {1, 2}, {20, 20, 12});
    d.crop_qform = crop_qform(read_raw_qform(ct_case()), d.crop);
    d.counts = counts(nifti.labels);
    d.half_voxel_m = 0.5 * nifti.spacing_m().maxCoeff();
    d.left = surface_from_labels(nifti, ct_case().string(), {1, 2}, kCoarse);
    return d;
  }();
  return data;
}

}  // namespace

// The left lung of a CT case, cropped and written as NRRD (raw and gzip), .seg.nrrd (picked by
// segment name) and MetaImage (raw and zlib), gives the surface of the NIfTI file.
TEST(LabelFormats, CtCaseInEveryFormatGivesTheNiftiSurface) {
  if (!std::filesystem::exists(ct_case())) GTEST_SKIP() << "no CT lobe maps at " << pneuma::test::ct_lobes_dir();
  const CtCase& ct = ct_case_data();
  const std::vector<int> left{1, 2};
  const Crop& c = ct.crop;
  TempDir dir;
  write_nrrd(dir / "left.nrrd", c.size, c.labels, c.ijk_to_lps);
  write_nrrd(dir / "left-gzip.nrrd", c.size, c.labels, c.ijk_to_lps, {.gzip = true});
  write_nrrd(dir / "left.seg.nrrd", c.size, c.labels, c.ijk_to_lps, {.gzip = true, .extra_lines = lobe_segments()});
  write_mha(dir / "left-raw.mha", c.size, raw_bytes(c.labels), "MET_SHORT", c.ijk_to_lps);
  write_mha(dir / "left.mha", c.size, raw_bytes(c.labels), "MET_SHORT", c.ijk_to_lps, true);  // zlib

  for (const char* file : {"left.nrrd", "left-gzip.nrrd", "left.seg.nrrd", "left-raw.mha", "left.mha"}) {
    SCOPED_TRACE(file);
    const LabelMap map = read_label_map(dir / file);
    ASSERT_EQ(map.size, c.size);
    EXPECT_LT((map.ijk_to_lps - c.ijk_to_lps).cwiseAbs().maxCoeff(), 1e-9);
    const std::map<int, std::size_t> n = counts(map.labels);
    EXPECT_EQ(n.at(1), ct.counts.at(1));
    EXPECT_EQ(n.at(2), ct.counts.at(2));
    std::vector<int> labels = left;
    if (std::string(file) == "left.seg.nrrd") {
      ASSERT_EQ(map.segments.size(), 5u);
      EXPECT_EQ(map.segments[1].name, "lung_lower_lobe_left");
      EXPECT_EQ(map.segments[1].label, 2);
      labels = resolve_labels(map, file, {"lung_upper_lobe_left", "lung_lower_lobe_left"});
      EXPECT_EQ(labels, left);
    }
    // The surfaces of three (the voxels and transforms of all five are checked above).
    if (std::string(file).find('-') != std::string::npos) continue;
    expect_same_surface(surface_from_labels(map, file, labels, kCoarse), ct.left, ct.half_voxel_m, file);
  }
}

// TotalSegmentator's outputs from the same crop: a folder of per-lobe masks (with files that are
// not lobes beside them) and the multilabel file with its label table, without it (v2 numbers
// named by the class map) and with v1's numbers. Names resolve to the class numbers; the
// surfaces are those of the lobe map.
TEST(LabelFormats, TotalSegmentatorMasksAndMultilabelFile) {
  if (!std::filesystem::exists(ct_case())) GTEST_SKIP() << "no CT lobe maps at " << pneuma::test::ct_lobes_dir();
  const CtCase& ct = ct_case_data();
  const Crop& c = ct.crop;
  const Qform& q = ct.crop_qform;
  const std::map<int, std::size_t>& n = ct.counts;
  // The case's lobes 1..5 (LUL, LLL, RUL, RML, RLL) are TotalSegmentator v2's 10..14.
  const std::map<std::string, int> lobe_of{{"lung_upper_lobe_left", 1},
                                           {"lung_lower_lobe_left", 2},
                                           {"lung_upper_lobe_right", 3},
                                           {"lung_middle_lobe_right", 4},
                                           {"lung_lower_lobe_right", 5}};
  const std::map<int, std::size_t> crop_counts = [&] {
    std::map<int, std::size_t> m;
    for (std::int16_t l : c.labels) ++m[l];
    return m;
  }();

  TempDir dir;
  const auto masks = dir / "segmentations";
  std::filesystem::create_directory(masks);
  for (const auto& [stem, lobe] : lobe_of) {
    write_nifti(masks / (stem + ".nii.gz"), int_size(c.size), relabel(c.labels, {{lobe, 1}}), q);
  }
  write_nifti(masks / "heart.nii.gz", int_size(c.size), relabel(c.labels, {{1, 1}}), q);  // not read
  std::ofstream(masks / "notes.txt") << "not a mask\n";

  const LabelMap folder = read_label_map(masks);
  ASSERT_EQ(folder.segments.size(), 5u);
  for (const Segment& s : folder.segments) {
    EXPECT_EQ(s.label, lobe_of.at(s.name) + 9) << s.name;  // v2 class numbers
    EXPECT_EQ(counts(folder.labels)[s.label], crop_counts.at(lobe_of.at(s.name))) << s.name;
  }
  const std::vector<int> left =
      resolve_labels(folder, "segmentations", {"lung_upper_lobe_left", "lung_lower_lobe_left"});
  EXPECT_EQ(left, (std::vector<int>{10, 11}));

  // The multilabel file: v2 numbers, with TotalSegmentator's label table in the header extension.
  std::string table = "<?xml version=\"1.0\" encoding=\"UTF-8\"?> <CaretExtension> <VolumeInformation Index=\"0\"> "
                      "<LabelTable>\n";
  for (const auto& [stem, lobe] : lobe_of) {
    table += "<Label Key=\"" + std::to_string(lobe + 9) + "\" Red=\"1\" Green=\"0\" Blue=\"0\" Alpha=\"1\"><![CDATA[" +
             stem + "]]></Label>\n";
  }
  table += "</LabelTable> </VolumeInformation></CaretExtension>\n";
  const std::map<int, int> to_v2{{1, 10}, {2, 11}, {3, 12}, {4, 13}, {5, 14}};
  write_nifti(dir / "total.nii.gz", int_size(c.size), relabel(c.labels, to_v2), q, {.extension = table});
  write_nifti(dir / "total-plain.nii", int_size(c.size), relabel(c.labels, to_v2), q);
  write_nifti(dir / "total-v1.nii", int_size(c.size), relabel(c.labels, {{1, 13}, {2, 14}, {3, 15}, {4, 16}, {5, 17}}),
              q);

  const LabelMap with_table = read_label_map(dir / "total.nii.gz");
  ASSERT_EQ(with_table.segments.size(), 5u);
  EXPECT_EQ(resolve_labels(with_table, "total.nii.gz", {"lung_upper_lobe_left", "lung_lower_lobe_left"}), left);
  const LabelMap plain = read_label_map(dir / "total-plain.nii");
  EXPECT_TRUE(plain.segments.empty());
  const LabelMap named = read_label_map(dir / "total-plain.nii", {.names = SegmentNames::totalsegmentator});
  EXPECT_EQ(resolve_labels(named, "total-plain.nii", {"lung_upper_lobe_left", "lung_lower_lobe_left"}), left);
  EXPECT_EQ(named.segments.size(), 5u);  // only the classes present
  const LabelMap v1 = read_label_map(dir / "total-v1.nii", {.names = SegmentNames::totalsegmentator_v1});
  EXPECT_EQ(resolve_labels(v1, "total-v1.nii", {"lung_upper_lobe_left", "lung_lower_lobe_left"}),
            (std::vector<int>{13, 14}));
  EXPECT_EQ(resolve_labels(v1, "total-v1.nii", {"14", "lung_upper_lobe_left", "14"}), (std::vector<int>{14, 13}));

  const LabelSurface from_masks = surface_from_labels(folder, "segmentations", left, kCoarse);
  const LabelSurface from_multilabel = surface_from_labels(with_table, "total.nii.gz", left, kCoarse);
  expect_same_surface(from_masks, from_multilabel, ct.half_voxel_m, "masks against multilabel");
  expect_same_surface(from_multilabel, ct.left, ct.half_voxel_m, "multilabel against the lobe map");
  EXPECT_EQ(from_masks.report.label_voxels, n.at(1) + n.at(2));

  // Names that are not there, and a selection of a class without voxels.
  EXPECT_EQ(error_of<pneuma::ValueError>([&] { resolve_labels(folder, "segmentations", {"lung_left"}); }),
            "\"lung_left\" is not a segment of segmentations (segments: lung_upper_lobe_left = 10, "
            "lung_lower_lobe_left = 11, lung_upper_lobe_right = 12, lung_middle_lobe_right = 13, "
            "lung_lower_lobe_right = 14)");
  EXPECT_EQ(error_of<pneuma::ValueError>([&] { resolve_labels(plain, "total-plain.nii", {"lung_upper_lobe_left"}); }),
            "\"lung_upper_lobe_left\" is not a segment of total-plain.nii: it names no segments (a .seg.nrrd, a "
            "TotalSegmentator file or mask folder does); give label numbers (labels present: 0, 10, 11, 12, 13, 14)");
}

// ---- Small synthetic maps: layers, the NIfTI transform rule, and the one-line errors ----

namespace {

// Two boxes in a 12 x 10 x 8 grid: label 1 at i < 4, label 2 at i >= 8 (j, k all).
std::vector<std::int16_t> two_boxes() {
  std::vector<std::int16_t> v(std::size_t{12} * 10 * 8, 0);
  for (std::size_t k = 0; k < 8; ++k)
    for (std::size_t j = 0; j < 10; ++j)
      for (std::size_t i = 0; i < 12; ++i)
        v[i + 12 * (j + 10 * k)] = static_cast<std::int16_t>(i < 4 ? 1 : i >= 8 ? 2 : 0);
  return v;
}

constexpr Size3 kBoxes{12, 10, 8};

Eigen::Matrix4d box_transform() {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.block<3, 3>(0, 0) = Eigen::Vector3d(0.8e-3, 0.9e-3, 2.0e-3).asDiagonal();
  m.block<3, 1>(0, 3) = Eigen::Vector3d(-0.1, 0.05, 0.2);
  return m;
}

std::string segment_lines(int index, const std::string& name, int label, int layer) {
  const std::string key = "Segment" + std::to_string(index) + "_";
  return key + "Name:=" + name + "\n" + key + "LabelValue:=" + std::to_string(label) + "\n" + key +
         "Layer:=" + std::to_string(layer) + "\n";
}

}  // namespace

// A 4D .seg.nrrd (3D Slicer's layers): both layers use label value 1; they do not overlap, so
// they are flattened and the second one's segment renumbered; overlapping layers are refused.
TEST(LabelFormats, SegNrrdLayersAreFlattenedOrRefused) {
  TempDir dir;
  const std::vector<std::int16_t> boxes = two_boxes();
  std::vector<std::int16_t> layered(boxes.size() * 2, 0);
  for (std::size_t v = 0; v < boxes.size(); ++v) {
    layered[2 * v] = boxes[v] == 1 ? 1 : 0;      // layer 0: "left", value 1
    layered[2 * v + 1] = boxes[v] == 2 ? 1 : 0;  // layer 1: "right", value 1
  }
  const std::string segments = segment_lines(0, "left", 1, 0) + segment_lines(1, "right", 1, 1);
  write_nrrd(dir / "two.seg.nrrd", kBoxes, layered, box_transform(), {.layers = 2, .extra_lines = segments});
  const LabelMap map = read_label_map(dir / "two.seg.nrrd");
  ASSERT_EQ(map.segments.size(), 2u);
  const std::vector<int> left = resolve_labels(map, "two", {"left"}), right = resolve_labels(map, "two", {"right"});
  ASSERT_EQ(left.size(), 1u);
  ASSERT_EQ(right.size(), 1u);
  EXPECT_NE(left[0], right[0]);
  EXPECT_EQ(counts(map.labels)[left[0]], 4u * 10 * 8);
  EXPECT_EQ(counts(map.labels)[right[0]], 4u * 10 * 8);
  EXPECT_EQ(map.labels[0], left[0]);    // voxel (0, 0, 0) is in the left box
  EXPECT_EQ(map.labels[11], right[0]);  // voxel (11, 0, 0) in the right one
  EXPECT_EQ(map.transform_source, "space directions");

  layered[11] = 1;  // voxel (5, 0, 0) of layer 1 (layer fastest: 2 * 5 + 1) ...
  layered[10] = 1;  // ... and of layer 0: one voxel in both
  write_nrrd(dir / "overlap.seg.nrrd", kBoxes, layered, box_transform(), {.layers = 2, .extra_lines = segments});
  const std::string f = (dir / "overlap.seg.nrrd").string();
  EXPECT_EQ(error_of<pneuma::InputError>([&] { read_label_map(f); }),
            f + ": layers 0 and 1 overlap in 1 voxels (segments \"left\" and \"right\"): expected segments that do "
                "not overlap (in 3D Slicer, export them to a labelmap volume)");
}

// pneuma's rule: the sform when sform_code > 0 (with its shear), else the qform.
TEST(LabelFormats, NiftiSformWinsOverQform) {
  TempDir dir;
  NiftiExtras extras;
  extras.has_sform = true;
  extras.srow = {{{0.9f, 0.1f, 0.0f, -20.0f}, {0.0f, 1.1f, 0.2f, 30.0f}, {0.0f, 0.0f, 2.0f, 40.0f}}};
  std::vector<std::int16_t> boxes = two_boxes();
  write_nifti(dir / "s.nii", {12, 10, 8}, boxes, Qform{}, extras);
  const LabelMap map = read_label_map(dir / "s.nii");
  EXPECT_EQ(map.transform_source, "sform");
  Eigen::Matrix4d expected = Eigen::Matrix4d::Identity();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c)
      expected(r, c) = static_cast<double>(extras.srow[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)]) *
                       1e-3 * (r < 2 ? -1.0 : 1.0);
  EXPECT_LT((map.ijk_to_lps - expected).cwiseAbs().maxCoeff(), 1e-15) << map.ijk_to_lps;
  write_nifti(dir / "q.nii", {12, 10, 8}, boxes, Qform{});
  EXPECT_EQ(read_label_map(dir / "q.nii").transform_source, "qform");
  EXPECT_EQ(counts(map.labels)[2], 4u * 10 * 8);
}

TEST(LabelFormats, DamagedFilesAreOneLineErrors) {
  TempDir dir;
  const std::vector<std::int16_t> boxes = two_boxes();
  auto expect_error = [&](const std::string& file, const std::string& what) {
    const std::string f = (dir / file).string();
    const std::string message = error_of<pneuma::InputError>([&] { read_label_map(f); });
    EXPECT_EQ(message, f + ": " + what);
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  };
  const std::string nrrd_line = "truncated or corrupt: expected 12 x 10 x 8 voxels of INT16 (1920 bytes of data";

  // Truncated: raw and gzip NRRD, raw and zlib MetaImage, raw and gzip NIfTI.
  write_nrrd(dir / "a.nrrd", kBoxes, boxes, box_transform());
  std::string bytes = pneuma::test::read_text(dir / "a.nrrd");
  write_bytes(dir / "cut.nrrd", bytes.substr(0, bytes.size() - 100));
  expect_error("cut.nrrd", nrrd_line + ")");
  write_nrrd(dir / "g.nrrd", kBoxes, boxes, box_transform(), {.gzip = true});
  bytes = pneuma::test::read_text(dir / "g.nrrd");
  write_bytes(dir / "cut-gzip.nrrd", bytes.substr(0, bytes.size() - 20));
  expect_error("cut-gzip.nrrd", nrrd_line + " after decompression)");
  write_mha(dir / "a.mha", kBoxes, raw_bytes(boxes), "MET_SHORT", box_transform());
  bytes = pneuma::test::read_text(dir / "a.mha");
  write_bytes(dir / "cut.mha", bytes.substr(0, bytes.size() - 100));
  expect_error("cut.mha", nrrd_line + ")");
  write_mha(dir / "z.mha", kBoxes, raw_bytes(boxes), "MET_SHORT", box_transform(), true);
  bytes = pneuma::test::read_text(dir / "z.mha");
  write_bytes(dir / "cut-zlib.mha", bytes.substr(0, bytes.size() - 10));
  expect_error("cut-zlib.mha", nrrd_line + " after decompression)");
  write_nifti(dir / "a.nii", {12, 10, 8}, boxes, Qform{});
  bytes = pneuma::test::read_text(dir / "a.nii");
  write_bytes(dir / "cut.nii", bytes.substr(0, bytes.size() - 2));
  expect_error("cut.nii", nrrd_line + ")");

  // Sizes: a header promising more voxels than the data holds, a 4D volume, a 2-value size line.
  bytes = pneuma::test::read_text(dir / "a.nrrd");
  std::string bigger = bytes;
  bigger.replace(bigger.find("sizes: 12 10 8"), 14, "sizes: 12 10 9");
  write_bytes(dir / "sizes.nrrd", bigger);
  expect_error("sizes.nrrd", "truncated or corrupt: expected 12 x 10 x 9 voxels of INT16 (2160 bytes of data)");
  std::string four = bytes;
  four.replace(four.find("dimension: 3"), 12, "dimension: 4");
  four.replace(four.find("sizes: 12 10 8"), 14, "sizes: 12 10 4 2");
  four.replace(four.find("kinds: domain domain domain"), 27, "kinds: domain domain domain domain");
  four.replace(four.find(" (0,0,2)"), 8, " (0,0,2) (0,0,0)");
  write_bytes(dir / "four.nrrd", four);
  const std::string four_message = error_of<pneuma::InputError>([&] { read_label_map(dir / "four.nrrd"); });
  EXPECT_NE(four_message.find("four.nrrd: "), std::string::npos) << four_message;
  EXPECT_EQ(four_message.find('\n'), std::string::npos) << four_message;
  std::string two = bytes;
  two.replace(two.find("sizes: 12 10 8"), 14, "sizes: 12 10");
  write_bytes(dir / "two-sizes.nrrd", two);
  expect_error("two-sizes.nrrd",
               "not a NRRD file: expected the magic line 'NRRD0001'..'NRRD0005' and a header with type, dimension, "
               "sizes and encoding");

  // Labels that are not integers.
  std::vector<float> halves(boxes.begin(), boxes.end());
  halves[12 * 10 + 3] = 0.5f;
  write_mha(dir / "float.mha", kBoxes, raw_bytes(halves), "MET_FLOAT", box_transform());
  expect_error("float.mha", "voxel 123 holds 0.500000: expected integer labels (a label map, not an image)");

  // Not the format its name says, and a name of no known format.
  write_bytes(dir / "notes.nrrd", "these are notes\n");
  expect_error("notes.nrrd",
               "not a NRRD file: expected the magic line 'NRRD0001'..'NRRD0005' and a header with type, dimension, "
               "sizes and encoding");
  write_bytes(dir / "notes.mha", "these are notes\n");
  expect_error("notes.mha",
               "not a MetaImage file: expected 'Key = Value' header lines with NDims, DimSize, ElementType and "
               "ElementDataFile");
  write_bytes(dir / "labels.png", "x");
  expect_error("labels.png", "expected a label map: .nii, .nii.gz, .nrrd, .nhdr, .seg.nrrd, .mha, .mhd, or a folder of "
                             "TotalSegmentator masks");

  // A .seg.nrrd whose segment names a label value the voxels do not hold: refused when picked.
  write_nrrd(dir / "absent.seg.nrrd", kBoxes, boxes, box_transform(),
             {.extra_lines =
                  segment_lines(0, "left", 1, 0) + segment_lines(1, "right", 2, 0) + segment_lines(2, "middle", 7, 0)});
  const LabelMap absent = read_label_map(dir / "absent.seg.nrrd");
  EXPECT_EQ(resolve_labels(absent, "absent.seg.nrrd", {"right", "left"}), (std::vector<int>{2, 1}));
  EXPECT_EQ(error_of<pneuma::ValueError>([&] { resolve_labels(absent, "absent.seg.nrrd", {"middle"}); }),
            "segment \"middle\" (label 7) has no voxels in absent.seg.nrrd (labels present: 0, 1, 2)");
  EXPECT_EQ(error_of<pneuma::ValueError>([&] { resolve_labels(absent, "absent.seg.nrrd", {"7"}); }),
            "label 7 is not in absent.seg.nrrd (labels present: 0, 1, 2)");
  write_nrrd(dir / "bad-layer.seg.nrrd", kBoxes, boxes, box_transform(), {.extra_lines = segment_lines(0, "x", 1, 2)});
  expect_error("bad-layer.seg.nrrd", "Segment0_Layer is '2': expected a layer from 0 to 0");

  // Masks on different grids, and a folder without masks.
  const auto masks = dir / "masks";
  std::filesystem::create_directory(masks);
  write_nifti(masks / "lung_upper_lobe_left.nii.gz", {12, 10, 8}, relabel(boxes, {{1, 1}}), Qform{});
  Qform moved;
  moved.offset = {0.0, 0.0, 5.0};
  write_nifti(masks / "lung_lower_lobe_left.nii.gz", {12, 10, 8}, relabel(boxes, {{2, 1}}), moved);
  expect_error("masks",
               "lung_lower_lobe_left.nii.gz is on another grid than lung_upper_lobe_left.nii.gz (12 x 10 x 8 voxels "
               "against 12 x 10 x 8, voxel-to-LPS transform differs by 5.000000 mm): expected every mask on the grid "
               "of the CT");
  write_nifti(masks / "lung_upper_lobe_left.nii.gz", {12, 10, 9},
              std::vector<std::int16_t>(std::size_t{12} * 10 * 9, 0), moved);
  expect_error("masks",
               "lung_lower_lobe_left.nii.gz is on another grid than lung_upper_lobe_left.nii.gz (12 x 10 x 8 voxels "
               "against 12 x 10 x 9): expected every mask on the grid of the CT");
  const auto empty = dir / "empty";
  std::filesystem::create_directory(empty);
  expect_error("empty", "a folder without TotalSegmentator masks: expected lung_upper_lobe_left.nii.gz, "
                        "lung_lower_lobe_left.nii.gz, lung_upper_lobe_right.nii.gz, lung_middle_lobe_right.nii.gz, "
                        "lung_lower_lobe_right.nii.gz");
}

namespace {

// `text` with its line that starts with `key` replaced by `line`.
std::string with_line(const std::string& text, const std::string& key, const std::string& line) {
  const std::size_t at = text.find("\n" + key) + 1;
  return text.substr(0, at) + line + text.substr(text.find('\n', at));
}

}  // namespace

// Every format's header passes one set of rules before ITK reads it and before any voxel is
// allocated (#49): the files a header brings in are regular files, the claimed voxels fit the
// data and a cap, the geometry is finite, positive and not flat, a compressed stream is intact.
TEST(LabelFormats, HeadersAreCheckedBeforeItkAndBeforeAllocation) {
  TempDir dir;
  const std::vector<std::int16_t> boxes = two_boxes();
  auto expect_error = [&](const std::string& file, const std::string& what) {
    const std::string f = (dir / file).string();
    EXPECT_EQ(error_of<pneuma::InputError>([&] { read_label_map(f); }), f + what);
  };
  const std::string nrrd_head = "NRRD0004\ntype: short\ndimension: 3\nsizes: 12 10 8\nencoding: raw\nendian: little\n";

  // A pipe as a detached data file or as a mask: refused before it is opened (it blocked).
  ASSERT_EQ(mkfifo((dir / "pipe.raw").c_str(), 0600), 0);
  write_bytes(dir / "pipe.nhdr", nrrd_head + "data file: pipe.raw\n");
  EXPECT_EQ(error_of<pneuma::InputError>([&] { read_label_map(dir / "pipe.nhdr"); }),
            (dir / "pipe.raw").string() + ": not a regular file (a device, pipe or socket); expected a file");
  std::filesystem::create_directory(dir / "masks");
  ASSERT_EQ(mkfifo((dir / "masks/lung_upper_lobe_left.nii.gz").c_str(), 0600), 0);
  EXPECT_EQ(error_of<pneuma::InputError>([&] { read_label_map(dir / "masks"); }),
            (dir / "masks/lung_upper_lobe_left.nii.gz").string() +
                ": not a regular file (a device, pipe or socket); expected a file");

  // A LIST of three 100-byte files claiming 75e6 voxels, and 7.5e9 voxels: refused at once.
  for (const char* f : {"a.raw", "b.raw", "c.raw"}) write_bytes(dir / f, std::string(100, '\1'));
  write_bytes(dir / "list.nhdr", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 5000 5000 3\nencoding: raw\n"
                                 "data file: LIST\na.raw\nb.raw\nc.raw\n");
  expect_error("list.nhdr",
               ": truncated or corrupt: expected 5000 x 5000 x 3 voxels of UINT8 (75000000 bytes of data)");
  write_bytes(dir / "huge.nhdr", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 50000 50000 3\nencoding: raw\n"
                                 "data file: LIST\na.raw\nb.raw\nc.raw\n");
  expect_error("huge.nhdr", ": 50000 x 50000 x 3 voxels: expected at most 2.14748e+09 voxel values");
  write_bytes(dir / "pattern.nhdr", nrrd_head + "data file: s%s.raw 1 3 1\n");
  expect_error("pattern.nhdr",
               ": data file 's%s.raw 1 3 1': expected a file name, LIST, or a pattern with one %d and its first, "
               "last and step (at most 100000 files)");

  // NRRD geometry: NaN and negative spacings, 1e308 directions, 1e-9 mm voxels, flat axes.
  const std::string data = raw_bytes(boxes);
  write_bytes(dir / "nan.nrrd", nrrd_head + "spacings: nan 1 1\n\n" + data);
  expect_error("nan.nrrd", ":7:11: spacings: expected a number for each of the three spatial axes, got 'nan 1 1'");
  write_bytes(dir / "negative.nrrd", nrrd_head + "spacings: 1 -1 1\n\n" + data);
  expect_error("negative.nrrd",
               ":7:11: spacings: expected positive numbers of magnitude at most 1e6 (millimetres), got '-1'");
  const std::string lps = "space: left-posterior-superior\nspace directions: ";
  write_bytes(dir / "far.nrrd", nrrd_head + lps + "(1e308,0,0) (0,1,0) (0,0,1)\n\n" + data);
  expect_error("far.nrrd",
               ":8:19: space directions: expected finite numbers of magnitude at most 1e6 (millimetres), got '1e308'");
  write_bytes(dir / "thin.nrrd", nrrd_head + lps + "(1e-9,0,0) (0,1,0) (0,0,1)\n\n" + data);
  expect_error("thin.nrrd", ": the voxel size along axis 1 (space directions) is 1e-09 mm: expected at least 0.001 mm");
  write_bytes(dir / "flat.nrrd", nrrd_head + lps + "(1,0,0) (2,0,0) (0,0,1)\n\n" + data);
  expect_error("flat.nrrd",
               ": the space directions gives voxel axes in one plane: expected three independent directions");

  // MetaImage: a header MetaIO would hang on (NDims without a value), a damaged ElementType, a
  // negative or 1e-9 mm ElementSpacing.
  write_mha(dir / "a.mha", kBoxes, data, "MET_SHORT", box_transform());
  const std::string mha = pneuma::test::read_text(dir / "a.mha");
  write_bytes(dir / "ndims.mha", with_line(mha, "NDims", "NDims"));
  expect_error("ndims.mha", ":2:1: expected 'Key = Value' (a MetaImage header line), got 'NDims'");
  write_bytes(dir / "ndims-empty.mha", with_line(mha, "NDims", "NDims ="));
  expect_error("ndims-empty.mha", ":2:1: NDims: expected 1 whole numbers from 2 to 4, got ''");
  write_bytes(dir / "type.mha", with_line(mha, "ElementType", "ElementType = MET_SH\x01ORT"));
  expect_error("type.mha",
               ":11:1: ElementType: expected MET_UCHAR, MET_SHORT, MET_INT, MET_FLOAT, ... (a MetaIO type), got "
               "'MET_SH\x01ORT'");
  write_bytes(dir / "mirrored.mha", with_line(mha, "ElementSpacing", "ElementSpacing = -0.8 0.9 2"));
  expect_error("mirrored.mha", ":9:1: ElementSpacing: expected 3 numbers from 0.001 to 1e+06, got '-0.8 0.9 2'");
  write_bytes(dir / "thin.mha", with_line(mha, "ElementSpacing", "ElementSpacing = 1e-9 0.9 2"));
  expect_error("thin.mha", ":9:1: ElementSpacing: expected 3 numbers from 0.001 to 1e+06, got '1e-9 0.9 2'");
  // A 250-byte key (MetaIO copies unknown keys into a 255-byte name: fuzz_labels_mha's overflow).
  const std::string long_key(250, 'K');
  write_bytes(dir / "long-key.mha", long_key + " = Image\n" + mha);
  expect_error("long-key.mha", ":1:1: expected a key of letters, digits and '_' (at most 64 characters), got '" +
                                   long_key.substr(0, 80) + "...' (250 bytes)");
  // Compressed data without BinaryData = True: MetaIO inflated the whole file from its first byte,
  // so the voxels read as zeros, and a header that begins like a zlib stream ('Hj') never ended
  // (fuzz_labels_mha's hang). The zlib stream here is intact and ITK reads it with BinaryData.
  write_mha(dir / "z.mha", kBoxes, data, "MET_SHORT", box_transform(), true);
  const std::string zmha = pneuma::test::read_text(dir / "z.mha");
  EXPECT_NO_THROW(read_label_map(dir / "z.mha"));
  write_bytes(dir / "text-z.mha", with_line(zmha, "BinaryData", "BinaryData = False"));
  expect_error("text-z.mha",
               ":5:1: CompressedData: expected BinaryData = True in the header (compressed data is binary)");
  write_bytes(dir / "hang-z.mha", "Hj = mage\n" + with_line(zmha, "BinaryData", "Comment = no BinaryData"));
  expect_error("hang-z.mha",
               ":6:1: CompressedData: expected BinaryData = True in the header (compressed data is binary)");
  // Tabs and carriage returns before LOCAL: MetaIO looked for a data file (and leaked its stream).
  write_bytes(dir / "tabs.mha", with_line(mha, "ElementDataFile", "ElementDataFile = \r\t\tLOCAL"));
  expect_error("tabs.mha", ":12:1: ElementDataFile: expected printable text of at most 254 bytes, got '\r\t\tLOCAL'");
  // A 300-byte ObjectType: MetaIO copies it into a 255-byte field (fuzz_labels_mha's overflow).
  write_bytes(dir / "long-type.mha", "ObjectType = " + std::string(300, 'I') + "\n" + mha);
  expect_error("long-type.mha", ":1:1: ObjectType: expected printable text of at most 254 bytes, got '" +
                                    std::string(80, 'I') + "...' (300 bytes)");
  write_bytes(dir / "key.mha", with_line(mha, "ElementType", "Element Type = MET_SHORT"));
  expect_error("key.mha",
               ":11:1: expected a key of letters, digits and '_' (at most 64 characters), got 'Element Type'");

  // A compressed stream whose check fails: gzip's CRC-32 (NRRD), zlib's Adler-32 (MetaImage).
  write_nrrd(dir / "g.nrrd", kBoxes, boxes, box_transform(), {.gzip = true});
  std::string bytes = pneuma::test::read_text(dir / "g.nrrd");
  bytes[bytes.size() - 8] = static_cast<char>(bytes[bytes.size() - 8] ^ 0x55);  // the CRC's first byte
  write_bytes(dir / "crc.nrrd", bytes);
  expect_error("crc.nrrd", ": the gzip data is damaged (incorrect data check): expected an intact compressed stream");
  write_mha(dir / "z.mha", kBoxes, data, "MET_SHORT", box_transform(), true);
  bytes = pneuma::test::read_text(dir / "z.mha");
  bytes.back() = static_cast<char>(bytes.back() ^ 0x55);  // Adler-32's last byte
  write_bytes(dir / "adler.mha", bytes);
  expect_error("adler.mha", ": the zlib data is damaged (incorrect data check): expected an intact compressed stream");
}
