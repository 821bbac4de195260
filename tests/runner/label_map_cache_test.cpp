// A label map's field is cached under a digest of every file it is read from: a TotalSegmentator
// mask folder's masks, a detached NRRD or MetaImage header's data file. A run from a mask folder
// works (it once failed reading the folder as a file, found by the mutation campaign of #49), a
// second run reuses the field, and a change in any of those files (never in the one the
// scenario names) computes it again.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "pneuma/image/label_map.h"
#include "test_support.h"

using pneuma::test::run_pneuma;
using pneuma::test::TempDir;

namespace {

constexpr int kNx = 20, kNy = 24, kNz = 28;

// An ellipsoid (semi-axes 21, 27 and 33 mm on a 3 mm grid) of `label`, only its voxels with
// `from_k` <= k < `below_k`; i fastest.
std::vector<std::int16_t> ellipsoid(std::int16_t label, int from_k = 0, int below_k = kNz) {
  std::vector<std::int16_t> labels(static_cast<std::size_t>(kNx) * kNy * kNz, 0);
  for (int k = from_k; k < below_k; ++k)
    for (int j = 0; j < kNy; ++j)
      for (int i = 0; i < kNx; ++i) {
        const double x = (i - kNx / 2.0) / 7.0, y = (j - kNy / 2.0) / 9.0, z = (k - kNz / 2.0) / 11.0;
        const auto at =
            static_cast<std::size_t>(i) +
            static_cast<std::size_t>(kNx) * (static_cast<std::size_t>(j) + kNy * static_cast<std::size_t>(k));
        if (x * x + y * y + z * z < 1.0) labels[at] = label;
      }
  return labels;
}

void write_raw(const std::filesystem::path& path, const std::vector<std::int16_t>& labels) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(labels.data()), static_cast<std::streamsize>(labels.size() * 2));
}

// A NIfTI-1 .nii of int16 labels, 3 mm voxels, its sform the LPS grid's (RAS: x and y negated).
void write_nii(const std::filesystem::path& path, const std::vector<std::int16_t>& labels) {
  std::string header(352, '\0');
  auto put = [&](std::size_t at, auto value) { std::memcpy(header.data() + at, &value, sizeof value); };
  put(0, std::int32_t{348});
  const std::int16_t dim[8] = {3, kNx, kNy, kNz, 1, 1, 1, 1};
  for (std::size_t i = 0; i < 8; ++i) put(40 + 2 * i, dim[i]);
  put(70, std::int16_t{4});   // DT_INT16
  put(72, std::int16_t{16});  // bitpix
  const float pixdim[8] = {1, 3, 3, 3, 1, 1, 1, 1};
  for (std::size_t i = 0; i < 8; ++i) put(76 + 4 * i, pixdim[i]);
  put(108, float{352});       // vox_offset
  put(254, std::int16_t{1});  // sform_code
  const float srow[3][4] = {{-3, 0, 0, 0}, {0, -3, 0, 0}, {0, 0, 3, 0}};
  for (std::size_t r = 0; r < 3; ++r)
    for (std::size_t c = 0; c < 4; ++c) put(280 + 16 * r + 4 * c, srow[r][c]);
  std::memcpy(header.data() + 344, "n+1\0", 4);
  std::ofstream out(path, std::ios::binary);
  out << header;
  out.write(reinterpret_cast<const char*>(labels.data()), static_cast<std::streamsize>(labels.size() * 2));
}

const std::string kGrid = "sizes: 20 24 28\nspace: left-posterior-superior\n"
                          "space directions: (3,0,0) (0,3,0) (0,0,3)\nspace origin: (0,0,0)\n";

}  // namespace

TEST(LabelMapCache, EveryFileALabelMapIsReadFromKeysItsField) {
  TempDir dir;
  // The same lung three ways: two masks of a TotalSegmentator folder (its upper and lower half),
  // a detached NRRD header with its raw data, a MetaImage header with its raw data.
  const auto masks = dir / "masks";
  std::filesystem::create_directory(masks);
  write_nii(masks / "lung_upper_lobe_right.nii", ellipsoid(1, kNz / 2, kNz));
  write_nii(masks / "lung_lower_lobe_right.nii", ellipsoid(1, 0, kNz / 2));
  std::ofstream(masks / "notes.txt") << "not a mask\n";
  dir.write("lung.nhdr", "NRRD0004\ntype: short\ndimension: 3\n" + kGrid +
                             "kinds: domain domain domain\nendian: little\nencoding: raw\ndata file: lung.raw\n");
  write_raw(dir / "lung.raw", ellipsoid(3));
  dir.write("lung.mhd",
            "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
            "CompressedData = False\nTransformMatrix = 1 0 0 0 1 0 0 0 1\nOffset = 0 0 0\n"
            "ElementSpacing = 3 3 3\nDimSize = 20 24 28\nElementType = MET_SHORT\nElementDataFile = lung.mhd.raw\n");
  write_raw(dir / "lung.mhd.raw", ellipsoid(3));

  // What each is read from: the folder (its files then hashed by name and bytes), a header and
  // its data.
  using Paths = std::vector<std::filesystem::path>;
  EXPECT_EQ(pneuma::image::label_map_files(masks), (Paths{masks}));
  EXPECT_EQ(pneuma::image::label_map_files(dir / "lung.nhdr"), (Paths{dir / "lung.nhdr", dir / "lung.raw"}));
  EXPECT_EQ(pneuma::image::label_map_files(dir / "lung.mhd"), (Paths{dir / "lung.mhd", dir / "lung.mhd.raw"}));

  struct Source {
    std::string labels, values;
    std::filesystem::path changed;  // a file the scenario does not name
    std::vector<std::int16_t> change;
  };
  const std::vector<Source> sources{
      {"masks/", "[lung_upper_lobe_right, lung_lower_lobe_right]", masks / "lung_lower_lobe_right.nii",
       ellipsoid(1, 6, kNz / 2)},
      {"lung.nhdr", "[3]", dir / "lung.raw", ellipsoid(3, 6)},
      {"lung.mhd", "[3]", dir / "lung.mhd.raw", ellipsoid(3, 6)},
  };
  for (const Source& s : sources) {
    const auto scenario = dir.write(
        "s.yaml", "duration: 2 s\nframes: {rate: 5 Hz}\nmesh: {labels: " + s.labels + ", values: " + s.values +
                      ", share: 2 %, edge: 6 mm}\nfield: {cache: field-" + std::to_string(&s - sources.data()) +
                      ".h5}\nphysiology: {preset: healthy-adult}\n"
                      "outputs: {gltf: false, hdf5: false, report: false}\n");
    auto reused = [&] {
      const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string()});
      EXPECT_EQ(r.exit_code, 0) << s.labels << ": " << r.err;
      return r.out.find("field reused from cache") != std::string::npos;
    };
    EXPECT_FALSE(reused()) << s.labels;
    EXPECT_TRUE(reused()) << s.labels << ": the same files";
    if (s.changed.extension() == ".nii") {
      write_nii(s.changed, s.change);
    } else {
      write_raw(s.changed, s.change);
    }
    EXPECT_FALSE(reused()) << s.labels << ": " << s.changed.filename() << " changed";
  }
}
