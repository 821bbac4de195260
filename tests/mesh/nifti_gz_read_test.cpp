// A .nii.gz read once (#50): read_label_map and read_scalar_image inflate the file themselves
// (its stream checked whole) and take the voxels from those bytes, ITK reading only the header.
// Oracle: the values this test wrote, byte by byte (NIfTI-1 layout from nifti1.h), in every
// integer and real type, in either byte order, as one gzip member or two (pigz); and ITK's own read
// of the same file uncompressed (.nii), the path that did not change.
#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "pneuma/core/error.h"
#include "pneuma/image/label_map.h"
#include "pneuma/image/scalar_image.h"
#include "test_support.h"

namespace {

namespace fs = std::filesystem;
using pneuma::test::TempDir;

constexpr std::array<int, 3> kSize{7, 5, 4};  // 140 voxels

// The value the test stores at voxel v: whole numbers from -60 to 59 (0 to 119 unsigned).
double value_at(std::size_t v, bool is_signed) {
  const auto whole = static_cast<double>((v * 37) % 120);
  return is_signed ? whole - 60.0 : whole;
}

struct Type {
  int code;  // NIfTI datatype
  int bytes;
  bool is_signed;
  bool real;
};

constexpr Type kTypes[] = {{2, 1, false, false},   {256, 1, true, false},   {4, 2, true, false},
                           {512, 2, false, false}, {8, 4, true, false},     {768, 4, false, false},
                           {1024, 8, true, false}, {1280, 8, false, false}, {16, 4, true, true},
                           {64, 8, true, true}};

// `value` stored as the type's bytes in this machine's order.
std::string stored(const Type& t, double value) {
  std::string out(static_cast<std::size_t>(t.bytes), '\0');
  auto put = [&](auto typed) { std::memcpy(out.data(), &typed, sizeof typed); };
  switch (t.code) {
    case 2: put(static_cast<std::uint8_t>(value)); break;
    case 256: put(static_cast<std::int8_t>(value)); break;
    case 4: put(static_cast<std::int16_t>(value)); break;
    case 512: put(static_cast<std::uint16_t>(value)); break;
    case 8: put(static_cast<std::int32_t>(value)); break;
    case 768: put(static_cast<std::uint32_t>(value)); break;
    case 1024: put(static_cast<std::int64_t>(value)); break;
    case 1280: put(static_cast<std::uint64_t>(value)); break;
    case 16: put(static_cast<float>(value)); break;
    default: put(value); break;
  }
  return out;
}

struct Written {
  const Type* type;
  bool big_endian = false;
  int members = 1;  // gzip members (pigz writes several)
  float slope = 1.0f, inter = 0.0f;
  std::vector<double> values{};  // overrides value_at when given
  std::array<int, 3> size = kSize;
  std::size_t trailing = 0;  // bytes after the voxels (more data than the header's)
};

// A NIfTI-1 file of w.size voxels, 1 mm, identity qform; gzip-compressed when the name ends in .gz.
void write(const fs::path& path, const Written& w) {
  std::string bytes(352, '\0');
  auto put = [&](std::size_t at, auto value) {
    std::memcpy(bytes.data() + at, &value, sizeof value);
    if (w.big_endian) std::reverse(bytes.data() + at, bytes.data() + at + sizeof value);
  };
  put(0, std::int32_t{348});
  const std::int16_t dim[8] = {3,
                               static_cast<std::int16_t>(w.size[0]),
                               static_cast<std::int16_t>(w.size[1]),
                               static_cast<std::int16_t>(w.size[2]),
                               1,
                               1,
                               1,
                               1};
  for (std::size_t i = 0; i < 8; ++i) put(40 + 2 * i, dim[i]);
  put(70, static_cast<std::int16_t>(w.type->code));
  put(72, static_cast<std::int16_t>(8 * w.type->bytes));
  for (std::size_t i = 0; i < 8; ++i) put(76 + 4 * i, 1.0f);
  put(108, 352.0f);  // vox_offset
  put(112, w.slope);
  put(116, w.inter);
  bytes[123] = 2;             // xyzt_units: mm
  put(252, std::int16_t{1});  // qform_code: scanner, the identity rotation
  std::memcpy(bytes.data() + 344, "n+1\0", 4);
  const std::size_t count =
      static_cast<std::size_t>(w.size[0]) * static_cast<std::size_t>(w.size[1]) * static_cast<std::size_t>(w.size[2]);
  for (std::size_t v = 0; v < count; ++v) {
    std::string one = stored(*w.type, w.values.empty() ? value_at(v, w.type->is_signed) : w.values[v]);
    if (w.big_endian) std::reverse(one.begin(), one.end());
    bytes += one;
  }
  bytes.append(w.trailing, '\x7f');
  std::ofstream out(path, std::ios::binary);
  if (path.extension() != ".gz") {
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return;
  }
  // Each member a gzip stream of its part (zlib's gzip wrapper: windowBits 15 + 16).
  const std::size_t part =
      (bytes.size() + static_cast<std::size_t>(w.members) - 1) / static_cast<std::size_t>(w.members);
  for (std::size_t from = 0; from < bytes.size(); from += part) {
    const std::size_t n = std::min(part, bytes.size() - from);
    z_stream z{};
    ASSERT_EQ(deflateInit2(&z, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY), Z_OK);
    std::string member(deflateBound(&z, n) + 64, '\0');
    z.next_in = reinterpret_cast<unsigned char*>(bytes.data() + from);
    z.avail_in = static_cast<unsigned>(n);
    z.next_out = reinterpret_cast<unsigned char*>(member.data());
    z.avail_out = static_cast<unsigned>(member.size());
    ASSERT_EQ(deflate(&z, Z_FINISH), Z_STREAM_END);
    member.resize(z.total_out);
    deflateEnd(&z);
    out.write(member.data(), static_cast<std::streamsize>(member.size()));
  }
}

std::string error_of(const fs::path& file) {
  try {
    (void)pneuma::image::read_label_map(file);
  } catch (const pneuma::InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(NiftiGzOneRead, EveryTypeInEitherByteOrderAndInGzipMembersReadsTheValuesWritten) {
  TempDir dir;
  for (const Type& type : kTypes) {
    for (const bool big : {false, true}) {
      for (const int members : {1, 3}) {
        const std::string what = "datatype " + std::to_string(type.code) + (big ? " big-endian" : " little-endian") +
                                 ", " + std::to_string(members) + " gzip member(s)";
        const Written w{.type = &type, .big_endian = big, .members = members};
        write(dir / "v.nii.gz", w);
        write(dir / "v.nii", w);
        const pneuma::image::LabelMap labels = pneuma::image::read_label_map(dir / "v.nii.gz");
        const pneuma::image::LabelMap by_itk = pneuma::image::read_label_map(dir / "v.nii");
        const pneuma::image::ScalarImage image = pneuma::image::read_scalar_image(dir / "v.nii.gz");
        ASSERT_EQ(labels.labels.size(), 140u) << what;
        ASSERT_EQ(image.values.size(), 140u) << what;
        EXPECT_EQ(labels.size, (std::array<std::size_t, 3>{7, 5, 4})) << what;
        std::size_t wrong = 0;
        for (std::size_t v = 0; v < 140; ++v) {
          const double expected = value_at(v, type.is_signed);
          wrong += labels.labels[v] != static_cast<std::int32_t>(expected);
          wrong += image.values[v] != static_cast<float>(expected);
        }
        EXPECT_EQ(wrong, 0u) << what;
        EXPECT_EQ(labels.labels, by_itk.labels) << what;
        EXPECT_EQ(labels.ijk_to_lps, by_itk.ijk_to_lps) << what;
      }
    }
  }
}

// More bytes in the stream than the header's voxels (libdeflate finds no room for them, and the
// zlib pass counts them): the header's voxels, as ITK reads them from the .nii.
TEST(NiftiGzOneRead, BytesBeyondTheVoxelsAreLeftAsItkLeavesThem) {
  TempDir dir;
  const Type int16 = kTypes[2];
  write(dir / "long.nii.gz", {.type = &int16, .trailing = 1000});
  write(dir / "long.nii", {.type = &int16, .trailing = 1000});
  const pneuma::image::LabelMap labels = pneuma::image::read_label_map(dir / "long.nii.gz");
  ASSERT_EQ(labels.labels.size(), 140u);
  std::size_t wrong = 0;
  for (std::size_t v = 0; v < 140; ++v) wrong += labels.labels[v] != static_cast<std::int32_t>(value_at(v, true));
  EXPECT_EQ(wrong, 0u);
  EXPECT_EQ(labels.labels, pneuma::image::read_label_map(dir / "long.nii").labels);
}

// scl_slope and scl_inter: ITK rescales as it reads, so it reads the file itself (the values are
// slope * stored + inter, in float).
TEST(NiftiGzOneRead, ARescaledFileIsReadByItkWithItsSlopeAndIntercept) {
  TempDir dir;
  for (const Type& type : {kTypes[2], kTypes[8]}) {  // int16 (ITK: float after the rescale), float32
    write(dir / "r.nii.gz", {.type = &type, .slope = 2.0f, .inter = -10.0f});
    const pneuma::image::ScalarImage image = pneuma::image::read_scalar_image(dir / "r.nii.gz");
    ASSERT_EQ(image.values.size(), 140u);
    std::size_t wrong = 0;
    for (std::size_t v = 0; v < 140; ++v)
      wrong += image.values[v] != static_cast<float>(2.0 * value_at(v, true) - 10.0);
    EXPECT_EQ(wrong, 0u) << "datatype " << type.code;
  }
}

// A slope or intercept that is not a number is none (niftilib's rule): the stored values, as ITK
// reads them from the .nii.
TEST(NiftiGzOneRead, ASlopeOrInterceptThatIsNotANumberLeavesTheStoredValues) {
  TempDir dir;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (const Type& type : {kTypes[2], kTypes[8]}) {
    for (const auto& [slope, inter] : {std::pair{nan, 0.0f}, std::pair{nan, nan}, std::pair{1.0f, nan}}) {
      const Written w{.type = &type, .slope = slope, .inter = inter};
      write(dir / "n.nii.gz", w);
      write(dir / "n.nii", w);
      const pneuma::image::ScalarImage image = pneuma::image::read_scalar_image(dir / "n.nii.gz");
      ASSERT_EQ(image.values.size(), 140u);
      std::size_t wrong = 0;
      for (std::size_t v = 0; v < 140; ++v) wrong += image.values[v] != static_cast<float>(value_at(v, true));
      EXPECT_EQ(wrong, 0u) << "datatype " << type.code << ", slope " << slope << ", intercept " << inter;
      EXPECT_EQ(image.values, pneuma::image::read_scalar_image(dir / "n.nii").values) << type.code;
    }
  }
}

// A stored NaN or infinity: niftilib sets it to 0 as it reads ("bad floats were set to 0"), so the
// one read does too, in either byte order: the .nii.gz reads as ITK reads the same .nii.
TEST(NiftiGzOneRead, NotANumberOrInfinityReadsAsZeroAsItkReadsIt) {
  TempDir dir;
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> values(140);
  for (std::size_t v = 0; v < 140; ++v) values[v] = value_at(v, true);
  values[3] = std::numeric_limits<double>::quiet_NaN();
  values[50] = inf;
  values[99] = -inf;
  for (const Type& type : {kTypes[8], kTypes[9]}) {  // float32, float64
    for (const bool big : {false, true}) {
      const Written w{.type = &type, .big_endian = big, .values = values};
      write(dir / "bad.nii.gz", w);
      write(dir / "bad.nii", w);
      const pneuma::image::ScalarImage image = pneuma::image::read_scalar_image(dir / "bad.nii.gz");
      ASSERT_EQ(image.values.size(), 140u);
      for (const std::size_t v : {3u, 50u, 99u}) EXPECT_EQ(image.values[v], 0.0f) << type.code << " voxel " << v;
      EXPECT_EQ(image.values[4], static_cast<float>(value_at(4, true)));
      EXPECT_EQ(image.values, pneuma::image::read_scalar_image(dir / "bad.nii").values) << type.code;
      EXPECT_EQ(pneuma::image::read_label_map(dir / "bad.nii.gz").labels,
                pneuma::image::read_label_map(dir / "bad.nii").labels)
          << type.code;
    }
  }
}

// The integrity pass's messages on the one read: a label that is not whole (the same voxel named
// as ITK's read of the .nii names), a CRC that does not match, a stream cut short.
TEST(NiftiGzOneRead, DamagedOrNonIntegerFilesAreTheSameOneLineErrors) {
  TempDir dir;
  const Type float32 = kTypes[8];
  std::vector<double> values(140, 3.0);
  values[61] = 0.5;
  write(dir / "half.nii.gz", {.type = &float32, .values = values});
  write(dir / "half.nii", {.type = &float32, .values = values});
  const std::string half = (dir / "half.nii.gz").string();
  EXPECT_EQ(error_of(dir / "half.nii.gz"), half +
                                               ": voxel 61 holds 0.500000: expected integer labels (a label map, not "
                                               "an image)");
  EXPECT_EQ(
      error_of(dir / "half.nii"),
      (dir / "half.nii").string() + ": voxel 61 holds 0.500000: expected integer labels (a label map, not an image)");

  // 64^3 voxels: more than the header's own read inflates, so the CRC is first checked here.
  const Type int16 = kTypes[2];
  write(dir / "a.nii.gz", {.type = &int16, .size = {64, 64, 64}});
  std::string bytes = pneuma::test::read_text(dir / "a.nii.gz");
  std::string crc = bytes;
  crc[crc.size() - 8] = static_cast<char>(crc[crc.size() - 8] ^ 0x55);  // the CRC-32's first byte
  std::ofstream(dir / "crc.nii.gz", std::ios::binary) << crc;
  EXPECT_EQ(error_of(dir / "crc.nii.gz"), (dir / "crc.nii.gz").string() +
                                              ": the gzip data is damaged (incorrect data check): expected an intact "
                                              "compressed stream");
  std::ofstream(dir / "cut.nii.gz", std::ios::binary) << bytes.substr(0, bytes.size() - 40);
  const std::string cut = error_of(dir / "cut.nii.gz");
  EXPECT_EQ(cut, (dir / "cut.nii.gz").string() +
                     ": truncated or corrupt: expected 64 x 64 x 64 voxels of INT16 (524288 bytes of data after "
                     "decompression)");
  EXPECT_EQ(cut.find('\n'), std::string::npos);
}

// An image of several of the conversion's blocks (#50: converted a block at a time on every core):
// every voxel the value this test wrote (the plain rule, voxel by voxel), through the inflated
// bytes (.nii.gz) and through ITK's read (.nii); and of several voxels that are not whole numbers in
// different blocks, the message names the first in the file, whichever block is converted first.
TEST(NiftiGzOneRead, AnImageOfManyBlocksIsEveryVoxelsValueAndItsFirstNonIntegerVoxelIsNamed) {
  TempDir dir;
  const std::array<int, 3> size{128, 96, 64};  // 786,432 voxels: three blocks and part of a fourth
  const std::size_t count = std::size_t{128} * 96 * 64;
  for (const Type& type : {kTypes[2], kTypes[5], kTypes[8]}) {  // int16, uint32, float32
    for (const char* name : {"v.nii.gz", "v.nii"}) {
      const std::string what = std::string(name) + " datatype " + std::to_string(type.code);
      write(dir / name, {.type = &type, .size = size});
      const pneuma::image::LabelMap labels = pneuma::image::read_label_map(dir / name);
      const pneuma::image::ScalarImage image = pneuma::image::read_scalar_image(dir / name);
      ASSERT_EQ(labels.labels.size(), count) << what;
      ASSERT_EQ(image.values.size(), count) << what;
      std::size_t wrong = 0;
      for (std::size_t v = 0; v < count; ++v) {
        const double expected = value_at(v, type.is_signed);
        wrong += labels.labels[v] != static_cast<std::int32_t>(expected);
        wrong += image.values[v] != static_cast<float>(expected);
      }
      EXPECT_EQ(wrong, 0u) << what;
    }
  }
  const Type float32 = kTypes[8];
  std::vector<double> values(count, 3.0);
  for (const std::size_t v : {700000u, 300001u, 262200u}) values[v] = 0.5;  // blocks 2, 1, 1
  values[500000] = 3e9;                                                     // whole, but beyond int32
  for (const char* name : {"half.nii.gz", "half.nii"}) {
    write(dir / name, {.type = &float32, .values = values, .size = size});
    EXPECT_EQ(error_of(dir / name), (dir / name).string() + ": voxel 262200 holds 0.500000: expected integer labels (a "
                                                            "label map, not an image)");
  }
  values[262200] = 3.0, values[300001] = 3.0;  // the first left is the one beyond int32
  write(dir / "big.nii.gz", {.type = &float32, .values = values, .size = size});
  EXPECT_EQ(error_of(dir / "big.nii.gz"), (dir / "big.nii.gz").string() +
                                              ": voxel 500000 holds 3000000000.000000: expected integer labels (a "
                                              "label map, not an image)");
}
