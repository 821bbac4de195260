// Which reader reads which DVF (docs/formats.md, "Which reader reads which DVF"): a shared CT case
// (case004, both lungs, coarse: 8 mm tets, a 6 mm grid) at end-inspiration, its pull-back field
// written as NIfTI in ITK 5.2's layout (intent 1007, LPS), as NIfTI in the standard's
// (`dvf_convention: nifti`: intent 1006, RAS) and as NRRD. Oracles: real external readers warp the
// rest label map with each file, and their labels must be pneuma's own warped labels (Dice >= 0.99
// per lobe) where the table says they read it, and must not be where it says they misread it
// (the two layouts differ by the sign of x and y, which moves the lobes); a header parser of its
// own checks the NRRD fields 3D Slicer reads.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "pneuma/image/label_map.h"
#include "test_support.h"

namespace {
namespace fs = std::filesystem;
using pneuma::test::CommandResult;
using pneuma::test::run_pneuma;
using pneuma::test::run_program;
using pneuma::test::TempDir;

constexpr std::array<std::int32_t, 5> kLobes{1, 2, 3, 4, 5};

double dice(const pneuma::image::LabelMap& a, const pneuma::image::LabelMap& b, std::int32_t label) {
  std::size_t na = 0, nb = 0, both = 0;
  for (std::size_t v = 0; v < a.labels.size() && v < b.labels.size(); ++v) {
    na += a.labels[v] == label;
    nb += b.labels[v] == label;
    both += a.labels[v] == label && b.labels[v] == label;
  }
  return na + nb == 0 ? 0.0 : 2.0 * static_cast<double>(both) / static_cast<double>(na + nb);
}

// The smallest Dice over the lobes of another reader's warp against pneuma's, on the same grid.
double worst_lobe_dice(const pneuma::image::LabelMap& ours, const fs::path& theirs_file) {
  const pneuma::image::LabelMap theirs = pneuma::image::read_label_map(theirs_file);
  EXPECT_EQ(theirs.size, ours.size) << theirs_file;
  EXPECT_LE((theirs.ijk_to_lps - ours.ijk_to_lps).cwiseAbs().maxCoeff(), 1e-6) << theirs_file;
  double worst = 1.0;
  for (const std::int32_t lobe : kLobes) worst = std::min(worst, dice(ours, theirs, lobe));
  return worst;
}

// The three runs, once for all tests, sharing one field cache (the field and the inside once).
class DvfReaders : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    rest_ = pneuma::test::ct_lobes_dir() / "case004_lobes.nii.gz";
    if (!fs::exists(rest_)) return;
    dir_ = new TempDir();
    for (const auto& [name, format] : std::map<std::string, std::string>{
             {"itk", "format: nii.gz"}, {"nifti", "format: nii.gz, dvf_convention: nifti"}, {"nrrd", "format: nrrd"}}) {
      const fs::path scenario = dir_->write(
          name + ".yaml", "duration: 4 s\nframes: {rate: 5 Hz}\nmesh: {labels: " + rest_.string() +
                              ", lungs: {right: [3, 4, 5], left: [1, 2]}, edge: 8 mm}\n"
                              "field: {tissue: healthy-supine, interior: {edge: 8 mm}, cache: field.h5}\n"
                              "physiology:\n  preset: healthy-adult\n"
                              "  driver: {mode: spontaneous, rate: 15 /min, ie_ratio: 1:2, tidal_volume: 800 mL}\n"
                              "outputs: {gltf: false, report: false, hdf5: false, voxels: {at: [end_inspiration], "
                              "spacing: 6 mm, jacobian: false, " +
                              format + "}}\n");
      const CommandResult r = run_pneuma({"run", scenario.string(), "-o", (*dir_ / name).string(), "--quiet"});
      run_errors_ += r.exit_code == 0 ? "" : name + ": " + r.err;
    }
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  void SetUp() override {
    if (!fs::exists(rest_)) GTEST_SKIP() << "no CT lobe maps at " << rest_.parent_path();
    ASSERT_EQ(run_errors_, "");
    ours_ = pneuma::image::read_label_map(file("itk", "labels", ".nii.gz"));
  }
  static fs::path file(const std::string& run, const std::string& kind, const std::string& extension) {
    return *dir_ / run / "voxels" / (kind + "-end_inspiration" + extension);
  }
  static fs::path pullback(const std::string& run) {
    return file(run, "dvf-pullback", run == "nrrd" ? ".nrrd" : ".nii.gz");
  }

  static inline fs::path rest_;
  static inline TempDir* dir_ = nullptr;
  static inline std::string run_errors_;
  pneuma::image::LabelMap ours_;
};

// plastimatch 1.9 (ITK 5.2's readers): the NIfTI in ITK's layout and the NRRD, not the standard's
// DISPVECT (it takes the RAS components as LPS).
TEST_F(DvfReaders, PlastimatchReadsItksLayoutAndNrrdNotTheStandards) {
  const fs::path plastimatch = pneuma::test::find_program({"plastimatch"});
  PNEUMA_REQUIRE_CLIENT(plastimatch, "plastimatch");
  for (const std::string run : {"itk", "nrrd", "nifti"}) {
    const fs::path out = *dir_ / ("plastimatch-" + run + ".nii.gz");
    const CommandResult r = run_program(plastimatch, {"warp", "--input", rest_.string(), "--xf", pullback(run).string(),
                                                      "--fixed", file("itk", "labels", ".nii.gz").string(),
                                                      "--output-img", out.string(), "--interpolation", "nn"});
    ASSERT_EQ(r.exit_code, 0) << run << ": " << r.out << r.err;
    const double d = worst_lobe_dice(ours_, out);
    std::printf("plastimatch, %s pull-back: smallest lobe Dice %.4f\n", run.c_str(), d);
    if (run == "nifti") {
      EXPECT_LT(d, 0.95) << run;  // misread: x and y the wrong way
    } else {
      EXPECT_GE(d, 0.99) << run;
    }
  }
}

// transformix (elastix 5.0.1, DeformationFieldTransform: the field maps the output grid's points
// into the input, as pneuma's pull-back does): the same as plastimatch.
TEST_F(DvfReaders, TransformixReadsItksLayoutAndNrrdNotTheStandards) {
  const fs::path transformix = pneuma::test::find_program({"transformix"});
  PNEUMA_REQUIRE_CLIENT(transformix, "transformix");
  // The output grid is pneuma's labels'; its direction is diagonal here, so the order elastix
  // reads `Direction` in does not matter.
  const Eigen::Matrix4d& g = ours_.ijk_to_lps;
  std::array<double, 3> spacing{};
  std::string direction;
  for (int a = 0; a < 3; ++a) {
    spacing[static_cast<std::size_t>(a)] = g.block<3, 1>(0, a).norm() * 1e3;
    for (int r = 0; r < 3; ++r)
      direction += fmt::format(" {:.9f}", g(r, a) * 1e3 / spacing[static_cast<std::size_t>(a)]);
  }
  for (const std::string run : {"itk", "nrrd", "nifti"}) {
    const fs::path out = *dir_ / ("transformix-" + run);
    fs::create_directories(out);
    const fs::path parameters = out / "TransformParameters.txt";
    std::ofstream(parameters) << fmt::format(
        "(Transform \"DeformationFieldTransform\")\n(DeformationFieldFileName \"{}\")\n"
        "(DeformationFieldInterpolationOrder 1)\n(NumberOfParameters 0)\n"
        "(InitialTransformParametersFileName \"NoInitialTransform\")\n(HowToCombineTransforms \"Compose\")\n"
        "(FixedImageDimension 3)\n(MovingImageDimension 3)\n(FixedInternalImagePixelType \"float\")\n"
        "(MovingInternalImagePixelType \"float\")\n(Size {} {} {})\n(Index 0 0 0)\n(Spacing {:.9f} {:.9f} {:.9f})\n"
        "(Origin {:.9f} {:.9f} {:.9f})\n(Direction{})\n(UseDirectionCosines \"true\")\n"
        "(ResampleInterpolator \"FinalBSplineInterpolator\")\n(FinalBSplineInterpolationOrder 0)\n"
        "(Resampler \"DefaultResampler\")\n(DefaultPixelValue 0)\n(ResultImageFormat \"nii.gz\")\n"
        "(ResultImagePixelType \"unsigned char\")\n(CompressResultImage \"true\")\n",
        pullback(run).string(), ours_.size[0], ours_.size[1], ours_.size[2], spacing[0], spacing[1], spacing[2],
        g(0, 3) * 1e3, g(1, 3) * 1e3, g(2, 3) * 1e3, direction);
    const CommandResult r =
        run_program(transformix, {"-in", rest_.string(), "-tp", parameters.string(), "-out", out.string()});
    ASSERT_EQ(r.exit_code, 0) << run << ": " << r.out.substr(r.out.size() > 2000 ? r.out.size() - 2000 : 0) << r.err;
    const double d = worst_lobe_dice(ours_, out / "result.nii.gz");
    std::printf("transformix, %s pull-back: smallest lobe Dice %.4f\n", run.c_str(), d);
    if (run == "nifti") {
      EXPECT_LT(d, 0.95) << run;
    } else {
      EXPECT_GE(d, 0.99) << run;
    }
  }
}

// nibabel + scipy as the NIfTI standard says (the vector components in the file's RAS world, no
// sign of its own): the DISPVECT file warps as pneuma does, ITK's layout does not; each file's
// header says which it is (intent and descrip).
TEST_F(DvfReaders, NibabelReadsTheStandardsDispvectAndEachHeaderSaysWhich) {
  const fs::path python = "/usr/bin/python3";
  if (!fs::exists(python) || run_program(python, {"-c", "import nibabel, scipy.ndimage"}).exit_code != 0) {
    GTEST_SKIP() << "nibabel or scipy is not importable by /usr/bin/python3 (install-deps: python3-nibabel "
                    "python3-scipy)";
  }
  const std::string script = R"(import sys, nibabel as nib, numpy as np, scipy.ndimage as ndi
from nibabel.affines import apply_affine
src, v = nib.load(sys.argv[1]), nib.load(sys.argv[2])
print(int(v.header["intent_code"]), v.header["descrip"].tobytes().rstrip(b"\0").decode())
y = apply_affine(v.affine, np.moveaxis(np.indices(v.shape[:3]), 0, -1)) + v.get_fdata().reshape(v.shape[:3] + (3,))
ijk = np.moveaxis(apply_affine(np.linalg.inv(src.affine), y), -1, 0)
out = ndi.map_coordinates(np.asarray(src.dataobj), ijk, order=0, cval=0).astype("uint8")
nib.save(nib.Nifti1Image(out, v.affine), sys.argv[3])
)";
  for (const std::string run : {"nifti", "itk"}) {
    const fs::path out = *dir_ / ("nibabel-" + run + ".nii.gz");
    const CommandResult r = run_program(python, {"-c", script, rest_.string(), pullback(run).string(), out.string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const double d = worst_lobe_dice(ours_, out);
    std::printf("nibabel + scipy (the standard's reading), %s pull-back: smallest lobe Dice %.4f; header: %s",
                run.c_str(), d, r.out.c_str());
    if (run == "nifti") {
      EXPECT_GE(d, 0.99);
      EXPECT_EQ(r.out, "1006 pneuma pull-back DVF out(x)=in(x+v), RAS mm, NIfTI DISPVECT, jumps at pleura\n");
    } else {
      EXPECT_LT(d, 0.95);
      EXPECT_EQ(r.out, "1007 pneuma pull-back DVF out(x)=in(x+v), LPS mm, ITK<=5.2 layout, jumps at pleura\n");
    }
  }
}

// A NRRD header's fields, read as text up to the blank line (the data after it is gzipped).
std::map<std::string, std::string> nrrd_header(const fs::path& path, std::string& magic) {
  std::ifstream in(path, std::ios::binary);
  std::map<std::string, std::string> fields;
  std::getline(in, magic);
  for (std::string line; std::getline(in, line) && !line.empty();) {
    if (line[0] == '#') continue;
    const std::size_t kv = line.find(":="), colon = line.find(": ");
    if (kv != std::string::npos && (colon == std::string::npos || kv < colon)) {
      fields["kv:" + line.substr(0, kv)] = line.substr(kv + 2);
    } else if (colon != std::string::npos) {
      fields[line.substr(0, colon)] = line.substr(colon + 2);
    } else {
      ADD_FAILURE() << path << ": not a NRRD field: " << line;
    }
  }
  return fields;
}

// Each NRRD DVF as 3D Slicer reads a displacement field, on the grid of the labels beside it (read
// by ITK's NRRD reader), and its data the length the header says.
TEST_F(DvfReaders, TheNrrdDvfsCarrySlicersDisplacementFieldFields) {
  const pneuma::image::LabelMap labels = pneuma::image::read_label_map(file("nrrd", "labels", ".nrrd"));
  EXPECT_EQ(labels.labels, ours_.labels);  // the same warp as the NIfTI run's
  const Eigen::Matrix4d& g = labels.ijk_to_lps;
  for (const auto& [kind, type] :
       std::map<std::string, std::string>{{"dvf-pullback", "resampling"}, {"dvf-forward", "modeling"}}) {
    const fs::path path = file("nrrd", kind, ".nrrd");
    std::string magic;
    const auto fields = nrrd_header(path, magic);
    EXPECT_TRUE(magic.starts_with("NRRD000")) << magic;
    EXPECT_EQ(fields.at("type"), "float");
    EXPECT_EQ(fields.at("dimension"), "4");
    EXPECT_EQ(fields.at("space"), "left-posterior-superior");
    EXPECT_EQ(fields.at("kinds"), "vector domain domain domain");
    EXPECT_EQ(fields.at("sizes"), fmt::format("3 {} {} {}", labels.size[0], labels.size[1], labels.size[2]));
    EXPECT_EQ(fields.at("measurement frame"), "(1,0,0) (0,1,0) (0,0,1)");
    EXPECT_EQ(fields.at("kv:displacement field type"), type) << kind;
    EXPECT_EQ(fields.at("kv:intent_code"), "1006") << kind;
    EXPECT_EQ(fields.at("encoding"), "gzip");
    // space directions: none, then one vector per domain axis (mm, LPS); the origin likewise.
    std::string directions = fields.at("space directions");
    ASSERT_TRUE(directions.starts_with("none ")) << directions;
    for (char& c : directions) c = (c == '(' || c == ')' || c == ',') ? ' ' : c;
    std::istringstream d(directions.substr(5));
    for (int a = 0; a < 3; ++a)
      for (int r = 0; r < 3; ++r) {
        double x = 0.0;
        d >> x;
        EXPECT_NEAR(x, g(r, a) * 1e3, 1e-6) << kind << " axis " << a;
      }
    std::string origin = fields.at("space origin");
    for (char& c : origin) c = (c == '(' || c == ')' || c == ',') ? ' ' : c;
    std::istringstream o(origin);
    for (int r = 0; r < 3; ++r) {
      double x = 0.0;
      o >> x;
      EXPECT_NEAR(x, g(r, 3) * 1e3, 1e-6) << kind;
    }
    // The gzipped data: 3 float32 per voxel.
    std::ifstream in(path, std::ios::binary);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::size_t start = text.find("\n\n") + 2;
    EXPECT_EQ(pneuma::test::gunzip(std::string_view(text).substr(start)).size(), std::size_t{12} * labels.labels.size())
        << kind;
  }
}

}  // namespace
