// Sequences of time points (sequence_io.h): three time points of the moved ball written as files
// and as sequences. Oracles: ITK 5.2's own NRRD reader reads every item of each scalar .seq.nrrd
// (equal to the time point's own file, read by pneuma's reader), zlib every item of each DVF
// .seq.nrrd (which ITK 5.2 refuses: two non-domain axes; equal to the time point's field), a header
// parser of the test's own checks 3D Slicer's sequence fields, and nibabel reads each 4D NIfTI,
// every volume equal to the time point's own NIfTI file.
// clang-format off
#include "itk_clang.h"  // first: Debian's ITK headers under clang
// clang-format on
#include <itkNrrdImageIO.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>

#include "pneuma/core/error.h"
#include "pneuma/voxels/time_point.h"
#include "pneuma/voxels/voxel_io.h"
#include "test_support.h"
#include "tet_fixtures.h"

namespace pneuma::voxels {
namespace {
namespace fs = std::filesystem;
using pneuma::test::CommandResult;
using pneuma::test::run_program;
using pneuma::test::TempDir;

// ITK's NRRD reader: the dimensions, components, and every value as double.
struct ItkRead {
  std::vector<std::size_t> size;
  unsigned components = 0;
  std::vector<double> values;
};

ItkRead itk_read(const fs::path& path) {
  auto io = itk::NrrdImageIO::New();
  io->SetFileName(path.string());
  io->ReadImageInformation();
  ItkRead out;
  for (unsigned a = 0; a < io->GetNumberOfDimensions(); ++a) out.size.push_back(io->GetDimensions(a));
  out.components = io->GetNumberOfComponents();
  const std::size_t n = io->GetImageSizeInComponents();
  itk::ImageIORegion region(io->GetNumberOfDimensions());
  for (unsigned a = 0; a < io->GetNumberOfDimensions(); ++a) {
    region.SetIndex(a, 0);
    region.SetSize(a, io->GetDimensions(a));
  }
  io->SetIORegion(region);
  switch (io->GetComponentType()) {
    case itk::IOComponentEnum::UCHAR: {
      std::vector<std::uint8_t> v(n);
      io->Read(v.data());
      out.values.assign(v.begin(), v.end());
      break;
    }
    case itk::IOComponentEnum::FLOAT: {
      std::vector<float> v(n);
      io->Read(v.data());
      out.values.assign(v.begin(), v.end());
      break;
    }
    default: ADD_FAILURE() << path << ": unexpected component type";
  }
  return out;
}

std::map<std::string, std::string> nrrd_fields(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::map<std::string, std::string> fields;
  std::string line;
  std::getline(in, line);
  fields["magic"] = line;
  while (std::getline(in, line) && !line.empty()) {
    if (line[0] == '#') continue;
    const std::size_t kv = line.find(":="), colon = line.find(": ");
    if (kv != std::string::npos && (colon == std::string::npos || kv < colon)) {
      fields[line.substr(0, kv)] = line.substr(kv + 2);
    } else if (colon != std::string::npos) {
      fields[line.substr(0, colon)] = line.substr(colon + 2);
    }
  }
  return fields;
}

// The data of a NRRD file with `encoding: gzip` after its header's blank line, as float32.
std::vector<float> gzip_data_after_header(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t start = text.find("\n\n") + 2;
  const std::string bytes = pneuma::test::gunzip(std::string_view(text).substr(start));
  std::vector<float> values(bytes.size() / sizeof(float));
  std::memcpy(values.data(), bytes.data(), values.size() * sizeof(float));
  return values;
}

struct Breathing {
  test::Ball ball = test::make_ball();
  std::vector<Eigen::Vector3d> u = ball.radial(0.15, Eigen::Vector3d(2.5e-3, -1.5e-3, 3e-3));
  Image ct;
  std::vector<TimePoint> points;
  std::vector<double> times{0.5, 1.25, 2.0};
  Breathing() {
    ct.grid = ball.grid;
    ct.values.resize(ct.grid.voxel_count());
    for (std::size_t v = 0; v < ct.values.size(); ++v) ct.values[v] = static_cast<float>(v % 997) - 900.0f;
    TimePointInputs inputs;
    inputs.labels = &ball.labels;
    inputs.ct = &ct;
    for (const double s : {0.3, 0.6, 1.0})
      points.push_back(compute_time_point(ball.grid, std::vector<LungMotion>{LungMotion{ball.mesh, u, s}}, inputs));
  }
  std::string tag(std::size_t i) const { return std::to_string(i); }
};

TEST(Sequences, EveryItemReadsBackAndTheHeadersHaveSlicersFields) {
  const Breathing run;
  const TempDir dir;
  TimePointSequences sequences(dir.path(), {SequenceFormat::slicer_nrrd}, "time", "s", run.times, SequenceVoxel::uint8);
  for (std::size_t i = 0; i < run.points.size(); ++i) {
    sequences.append(run.points[i]);
    write_time_point(dir.path(), run.tag(i), run.points[i]);
  }
  const std::vector<fs::path> files = sequences.finish();
  std::vector<std::string> names;
  names.reserve(files.size());
  for (const fs::path& f : files) names.push_back(f.filename().string());
  EXPECT_EQ(names, (std::vector<std::string>{"labels.seq.nrrd", "ct.seq.nrrd", "jacobian.seq.nrrd",
                                             "dvf-pullback.seq.nrrd", "dvf-forward.seq.nrrd"}));
  const Grid& g = run.ball.grid;
  const std::size_t n = g.voxel_count();
  for (const std::string kind : {"labels", "ct", "jacobian"}) {
    // ITK 5.2 reads the list axis of a scalar sequence as the pixel's components (one per item:
    // its only non-domain axis), so item i of voxel v is value 3 v + i.
    const ItkRead seq = itk_read(dir / (kind + ".seq.nrrd"));
    EXPECT_EQ(seq.size, (std::vector<std::size_t>{g.size[0], g.size[1], g.size[2]})) << kind;
    EXPECT_EQ(seq.components, 3u) << kind;
    ASSERT_EQ(seq.values.size(), 3 * n) << kind;
    for (std::size_t i = 0; i < 3; ++i) {
      const fs::path own = dir / (kind + "-" + run.tag(i) + ".nii.gz");
      std::vector<double> expected;
      if (kind == "labels") {
        const image::LabelMap labels = image::read_label_map(own);
        expected.assign(labels.labels.begin(), labels.labels.end());
      } else {
        const Image image = read_image(own);
        expected.assign(image.values.begin(), image.values.end());
      }
      std::size_t differ = 0;
      for (std::size_t v = 0; v < n; ++v) differ += seq.values[3 * v + i] != expected[v];
      EXPECT_EQ(differ, 0u) << kind << " item " << i;
    }
    const auto fields = nrrd_fields(dir / (kind + ".seq.nrrd"));
    EXPECT_EQ(fields.at("kinds"), "domain domain domain list");
    EXPECT_EQ(fields.at("space"), "left-posterior-superior");
    EXPECT_EQ(fields.at("labels"), "\"\" \"\" \"\" \"time\"");
    EXPECT_EQ(fields.at("units"), "\"\" \"\" \"\" \"s\"");
    EXPECT_EQ(fields.at("axis 3 index type"), "numeric");
    EXPECT_EQ(fields.at("axis 3 index values"), "0.5 1.25 2");
    EXPECT_EQ(fields.at("DataNodeClassName"),
              kind == "labels" ? "vtkMRMLLabelMapVolumeNode" : "vtkMRMLScalarVolumeNode");
    EXPECT_TRUE(fields.at("space directions").ends_with(" none")) << fields.at("space directions");
  }
  // A DVF sequence has two non-domain axes (vector and list), which ITK 5.2's reader refuses
  // ("nrrd has 2 dependent axis (not 1); not currently handled"; Slicer reads it): its data are
  // read here with zlib after the header.
  for (const auto& [kind, type] :
       std::map<std::string, std::string>{{"dvf-pullback", "resampling"}, {"dvf-forward", "modeling"}}) {
    EXPECT_THROW(itk_read(dir / (kind + ".seq.nrrd")), itk::ExceptionObject);
    const std::vector<float> values = gzip_data_after_header(dir / (kind + ".seq.nrrd"));
    ItkRead seq;
    seq.values.assign(values.begin(), values.end());
    ASSERT_EQ(seq.values.size(), 9 * n) << kind;
    double worst = 0.0;
    for (std::size_t i = 0; i < 3; ++i) {
      const DisplacementField& field = kind == "dvf-pullback" ? run.points[i].pullback : run.points[i].forward;
      for (std::size_t v = 0; v < n; ++v)
        for (std::size_t c = 0; c < 3; ++c)
          worst = std::max(worst, std::abs(seq.values[3 * (i * n + v) + c] -
                                           field.displacement_m[v][static_cast<Eigen::Index>(c)] * 1e3));
    }
    EXPECT_LE(worst, 1e-5) << kind;  // float32 mm of a few mm, LPS
    const auto fields = nrrd_fields(dir / (kind + ".seq.nrrd"));
    EXPECT_EQ(fields.at("kinds"), "vector domain domain domain list");
    EXPECT_EQ(fields.at("measurement frame"), "(1,0,0) (0,1,0) (0,0,1)");
    EXPECT_EQ(fields.at("displacement field type"), type);
    EXPECT_EQ(fields.at("axis 3 index values"), "0.5 1.25 2");
    EXPECT_EQ(fields.count("DataNodeClassName"), 0u);
  }
}

TEST(Sequences, NibabelReadsEach4dNiftiVolumeAsTheTimePointsOwnFile) {
  const fs::path python = "/usr/bin/python3";
  if (!fs::exists(python) || run_program(python, {"-c", "import nibabel"}).exit_code != 0)
    GTEST_SKIP() << "nibabel is not importable by /usr/bin/python3 (install-deps: python3-nibabel)";
  const Breathing run;
  const TempDir dir;
  TimePointSequences sequences(dir.path(), {SequenceFormat::nifti_4d}, "phase", "%", {0.0, 10.0, 20.0},
                               SequenceVoxel::uint8);
  for (std::size_t i = 0; i < run.points.size(); ++i) {
    sequences.append(run.points[i]);
    write_time_point(dir.path(), run.tag(i), run.points[i]);
  }
  EXPECT_EQ(sequences.finish().size(), 5u);
  // Each volume against the time point's own file: the largest difference, the affines' and the
  // shapes, per kind.
  const std::string script = R"(import sys, nibabel as nib, numpy as np
for kind in ["labels", "ct", "jacobian", "dvf-pullback", "dvf-forward"]:
    seq = nib.load(f"{kind}-4d.nii.gz")
    d = np.asarray(seq.dataobj)
    worst = 0.0
    for i in range(3):
        own = nib.load(f"{kind}-{i}.nii.gz")
        o = np.asarray(own.dataobj)
        v = d[..., i, :] if o.ndim == 5 else d[..., i]
        worst = max(worst, float(np.max(np.abs(v.astype(float) - o.reshape(v.shape).astype(float)))))
        assert np.allclose(seq.affine, own.affine, atol=1e-4), kind
    print(kind, d.shape[3], d.dtype, int(seq.header["intent_code"]), worst)
)";
  const CommandResult r = run_program(python, {"-c", script}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "labels 3 uint8 0 0.0\nct 3 float32 0 0.0\njacobian 3 float32 0 0.0\n"
                   "dvf-pullback 3 float32 1007 0.0\ndvf-forward 3 float32 1007 0.0\n");
  // No temporaries left (the DVF components' files were joined and removed).
  std::vector<std::string> files = dir.files();
  EXPECT_EQ(std::count_if(files.begin(), files.end(), [](const std::string& f) { return f.ends_with("-4d.nii.gz"); }),
            5);
  EXPECT_EQ(files.size(), 5u + 15u) << ::testing::PrintToString(files);
}

// With the NIfTI standard's convention the 4D DVF is intent 1006 with RAS components: nibabel's
// volumes are the 3D DISPVECT files' (voxel_io.h, DvfConvention::nifti).
TEST(Sequences, The4dNiftiDvfKeepsTheStandardsConvention) {
  const fs::path python = "/usr/bin/python3";
  if (!fs::exists(python) || run_program(python, {"-c", "import nibabel"}).exit_code != 0)
    GTEST_SKIP() << "nibabel is not importable by /usr/bin/python3 (install-deps: python3-nibabel)";
  const Breathing run;
  const TempDir dir;
  TimePointSequences sequences(dir.path(), {SequenceFormat::nifti_4d}, "time", "s", run.times, SequenceVoxel::uint8,
                               DvfConvention::nifti);
  for (std::size_t i = 0; i < run.points.size(); ++i) {
    sequences.append(run.points[i]);
    write_time_point(dir.path(), run.tag(i), run.points[i], ".nii.gz", DvfConvention::nifti);
  }
  sequences.finish();
  const std::string script = R"(import nibabel as nib, numpy as np
seq = nib.load("dvf-forward-4d.nii.gz")
d = np.asarray(seq.dataobj)
worst = max(float(np.max(np.abs(d[..., i, :] - np.asarray(nib.load(f"dvf-forward-{i}.nii.gz").dataobj)[..., 0, :])))
            for i in range(3))
print(int(seq.header["intent_code"]), int(nib.load("dvf-forward-0.nii.gz").header["intent_code"]), worst)
)";
  const CommandResult r = run_program(python, {"-c", script}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "1006 1006 0.0\n");
}

TEST(Sequences, ASequenceMissingAnItemIsNotWritten) {
  const Breathing run;
  const TempDir dir;
  {
    TimePointSequences sequences(dir.path(), {SequenceFormat::slicer_nrrd, SequenceFormat::nifti_4d}, "time", "s",
                                 run.times, SequenceVoxel::uint8);
    sequences.append(run.points[0]);
    EXPECT_THROW(sequences.finish(), ValueError);
  }
  EXPECT_EQ(dir.files(), std::vector<std::string>{});  // the temporaries removed
  SequenceSpec spec;
  spec.grid = run.ball.grid;
  spec.index_values = {1.0};
  SequenceWriter writer(dir / "x.seq.nrrd", SequenceFormat::slicer_nrrd, spec);
  EXPECT_THROW(writer.append(run.ct.values.data(), 4), ValueError);  // the wrong size
}

}  // namespace
}  // namespace pneuma::voxels
