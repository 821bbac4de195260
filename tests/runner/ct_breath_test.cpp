// The breath in voxels on every shared CT case and the built-in phantom (#45, docs/voxels.md "What
// a run measures", "The issue's checks, measured"): at end-inspiration of a quiet breath the
// lungs' inside does not shrink (the forward map's Jacobian 6 mm inside the pleura), the body does
// not tear (outside a 2-voxel band at the pleura the pull-back field's Jacobian lies in [0.5, 2]
// and no voxel's displacement differs from a neighbour's by more than a voxel) and the warped CT
// keeps each lung's mass at every time point, darkening as the mass-preserving rule predicts. The
// oracle is nibabel + numpy + scipy reading the written files (their own affine, their own finite differences and
// distance transform): none of it is pneuma's arithmetic. Cheap settings (5 mm surfaces, 6 mm
// tets, 4 mm voxels) keep each run near 20 s of CPU; the scenario's own (4 mm, 3 mm voxels) are
// measured in docs/voxels.md.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <tuple>

#include "pneuma/image/label_map.h"
#include "pneuma/voxels/grid.h"
#include "pneuma/voxels/voxel_io.h"
#include "pneuma/voxels/warp.h"
#include "test_support.h"

using pneuma::test::run_pneuma;
using pneuma::test::run_program;
using pneuma::test::TempDir;

namespace {

constexpr double kSpacingM = 4e-3;
// The share of the lung voxels 6 mm inside that shrink by more than 5 % (J < 0.95): the issue
// asks for 0.1 %, met by the forward DVF's finite differences since the lung's face on the heart
// descends with it and the supine preset has no forward slide (docs/voxels.md, "The lung on the
// heart"): 0.004-0.094 % here (2026-11-27; 0.11-0.38 % before). The Jacobian image, the
// recovered gradient's Jacobian at each voxel's rest point (voxels::recovered_gradients), is held
// at the same 0.1 %: 0-0.019 % here, where each voxel its tetrahedron's exact Jacobian (6 mm tets
// here) gave 0.16-0.41 % (single tets and a few lingula clusters beside the heart).
constexpr double kShrinkingFraction = 1e-3;
constexpr double kShrinkingImage = 1e-3;
// No lung voxel outside the pleural band has a pull-back J outside [0.5, 2] (the issue's none):
// case009's thin recess under the diaphragm left 2 (6.6e-5 of the lungs' voxels, forward J up to
// 3.2) until its upper face moved with the diaphragm around it (field/heart.h; docs/voxels.md,
// "The stretched recess of case009").
// The lungs' mass at every time point against the rest scan's (the issue's 1 %), and the mean lung
// HU at end-inspiration against the mass-preserving prediction (the issue's 2 HU): docs/voxels.md,
// "The lungs' mass" (+0.35 to +1.61 % before the warped CT's lung was interpolated from lung
// voxels only).
constexpr double kMass = 0.01;
constexpr double kMeanHu = 2.0;

// A synthetic CT on the run's grid (the label map's extent at `spacing_m`, kSpacingM but for the 2 mm test): lung
// parenchyma -849.5 HU where the label map's nearest voxel is a lobe, soft tissue 40 HU elsewhere.
void write_synthetic_ct(const std::filesystem::path& labels, const std::filesystem::path& out, double spacing_m) {
  const pneuma::image::LabelMap map = pneuma::image::read_label_map(labels);
  const pneuma::voxels::Grid source = pneuma::voxels::grid_of(map);
  pneuma::voxels::Image ct;
  ct.grid = pneuma::voxels::grid_with_spacing(source, spacing_m);
  ct.values.resize(ct.grid.voxel_count());
  const Eigen::Matrix4d to_source = source.lps_to_ijk();
  for (std::size_t k = 0; k < ct.grid.size[2]; ++k) {
    for (std::size_t j = 0; j < ct.grid.size[1]; ++j) {
      for (std::size_t i = 0; i < ct.grid.size[0]; ++i) {
        const Eigen::Vector3d at = ct.grid.centre_m(i, j, k);
        const Eigen::Vector4d q = to_source * Eigen::Vector4d(at.x(), at.y(), at.z(), 1.0);
        int label = 0;
        std::array<std::size_t, 3> s{};
        bool inside = true;
        for (std::size_t a = 0; a < 3; ++a) {
          const double r = std::round(q(static_cast<Eigen::Index>(a)));
          inside = inside && r >= 0.0 && r < static_cast<double>(map.size[a]);
          s[a] = inside ? static_cast<std::size_t>(r) : 0;
        }
        if (inside) label = map.labels[s[0] + map.size[0] * (s[1] + map.size[1] * s[2])];
        ct.values[ct.grid.index(i, j, k)] = label >= 1 && label <= 5 ? -849.5f : 40.0f;
      }
    }
  }
  pneuma::voxels::write_image(out, ct);
}

// The phantom's CT on the run's grid: lung -849.5 HU where pneuma's label map at the scan (its
// rest tetrahedra on the grid: right 1, left 2) is a lung, 40 HU elsewhere. The grid and the rest
// lungs depend on neither the tissue nor the scan's place on the breath.
void write_phantom_ct(const std::filesystem::path& labels, const std::filesystem::path& out) {
  const pneuma::image::LabelMap map = pneuma::image::read_label_map(labels);
  pneuma::voxels::Image ct;
  ct.grid = pneuma::voxels::grid_of(map);
  ct.values.resize(map.labels.size());
  for (std::size_t v = 0; v < ct.values.size(); ++v) ct.values[v] = map.labels[v] > 0 ? -849.5f : 40.0f;
  pneuma::voxels::write_image(out, ct);
}

// The checks of #45 on one run's voxels folder; argv[3] is the scan's place on the breath (the
// rest, s = 0), end_expiration or end_inspiration, and the checks are made at the breath's other
// end. With the scan at end-inspiration the forward map goes to end-expiration, and the
// inspiration's Jacobian at a voxel is the inverse of its Jacobian. argv[4] names the labels of
// the lungs: `lobes` (the shared lobe maps: right 3-5, left 1-2) or `phantom` (right 1, left 2).
constexpr const char* kChecks = R"(import sys, numpy as np, nibabel as nib
from scipy import ndimage
d = sys.argv[1]
ref = sys.argv[3]
right, left = ([1], [2]) if sys.argv[4] == "phantom" else ([3, 4, 5], [1, 2])
other = "end_inspiration" if ref == "end_expiration" else "end_expiration"
def load(name):
    img = nib.load(f"{d}/{name}.nii.gz")
    return img, np.asarray(img.dataobj).squeeze().astype(np.float64)
def jacobian(img, v):
    # v: LPS displacements (ITK's layout) on the grid; the index -> LPS map from nibabel's affine.
    m = np.diag([-1.0, -1.0, 1.0]) @ img.affine[:3, :3]
    g = np.stack([np.stack(np.gradient(v[..., c]), -1) for c in range(3)], -2)  # d v_c / d index_a
    return np.linalg.det(np.eye(3) + g @ np.linalg.inv(m))
_, rest_labels = load(f"labels-{ref}")
_, labels = load(f"labels-{other}")
fimg, forward = load(f"dvf-forward-{other}")
pimg, pullback = load(f"dvf-pullback-{other}")
_, ct_rest = load(f"ct-{ref}")
_, ct = load(f"ct-{other}")
_, jimage = load(f"jacobian-{other}")
spacing = np.array(fimg.header.get_zooms()[:3], dtype=float)
voxel = spacing.min()
# Interior: the rest lung 6 mm inside the pleura; the forward map's Jacobian, by finite differences
# of the forward DVF and as the written Jacobian image.
rest = rest_labels > 0
deep = ndimage.distance_transform_edt(rest, sampling=spacing) > 6.0
deep[[0, -1], :, :] = deep[:, [0, -1], :] = deep[:, :, [0, -1]] = False
jf = jacobian(fimg, forward)[deep]
ji = jimage[deep]
if ref == "end_inspiration":
    jf, ji = 1.0 / jf, 1.0 / ji
# No tear: outside a 2-voxel band at the pleura of the warped lungs, and off the grid's faces.
lung = labels > 0
ok = ~(ndimage.binary_dilation(lung, iterations=2) & ~ndimage.binary_erosion(lung, iterations=2))
ok[[0, -1], :, :] = ok[:, [0, -1], :] = ok[:, :, [0, -1]] = False
jp = jacobian(pimg, pullback)
torn = ok & ((jp < 0.5) | (jp > 2.0))
jp = jp[ok]
pairs, widest = 0, 0.0
for a in range(3):
    lo = [slice(None)] * 3; hi = [slice(None)] * 3
    lo[a] = slice(0, -1); hi[a] = slice(1, None)
    both = ok[tuple(lo)] & ok[tuple(hi)]
    apart = np.linalg.norm(pullback[tuple(lo)] - pullback[tuple(hi)], axis=-1)[both]
    pairs += int((apart > voxel).sum()); widest = max(widest, float(apart.max()))
# Mass: (HU + 1000) x voxel volume over the lung voxels that show parenchyma (the synthetic CT's
# lung, darker or not: -1000 to -500 HU; its lung and the run's label map differ at the rim), each
# time point's over the rest scan's that stays in the field of view (the rest voxels whose forward
# map, x + u(x) by the forward DVF, lies on the grid: case004's lobe map ends at the lungs' base,
# and the descending domes take 1.1 % of the lungs' mass out of it), for both lungs and for each
# (the scenario's lobes): the one farthest from 1. The mean lung HU at end-inspiration (the same
# voxels) against the mass-preserving prediction: the rest lung's mean HU + 1000 scaled by the
# lung's volume at rest (its label voxels that stay in view) over its volume at end-inspiration,
# for both lungs and the larger offset of the two lungs'.
def mean_and_prediction(in_lung, view):
    rest_in_view = in_lung(rest_labels) & view
    rest_mean = float(ct_rest[rest_in_view & (ct_rest >= -1000.0) & (ct_rest < -500.0)].mean())
    now = in_lung(labels)
    mean = float(ct[now & (ct >= -1000.0) & (ct < -500.0)].mean())
    return mean, -1000.0 + (rest_mean + 1000.0) * rest_in_view.sum() / now.sum()
def in_view(img, u):
    m = np.diag([-1.0, -1.0, 1.0]) @ img.affine[:3, :3]
    q = np.indices(u.shape[:3]).transpose(1, 2, 3, 0) + u @ np.linalg.inv(m).T
    return np.all((q >= -0.5) & (q <= np.array(u.shape[:3]) - 0.5), axis=-1)
lungs = {"both": lambda l: l > 0, "right": lambda l: np.isin(l, right), "left": lambda l: np.isin(l, left)}
mass = lambda c, l: float(((c + 1000.0) * ((c >= -1000.0) & (c < -500.0) & l)).sum())
worst = 1.0
for tag in ("1.000s", other):
    view = in_view(*load(f"dvf-forward-{tag}"))
    c, l = load(f"ct-{tag}")[1], load(f"labels-{tag}")[1]
    for name, in_lung in lungs.items():
        ratio = mass(c, in_lung(l)) / mass(ct_rest, in_lung(rest_labels) & view)
        worst = ratio if abs(ratio - 1.0) > abs(worst - 1.0) else worst
        if tag == other and name == "both": mass_ratio, end_view = ratio, view
lung_mean, predicted = mean_and_prediction(lungs["both"], end_view)
offsets = [m - p for m, p in (mean_and_prediction(lungs[n], end_view) for n in ("right", "left"))]
worst_offset = max(offsets, key=abs)
# At rest (a zero field) the warped CT is the input CT.
rest_changed = int((np.abs(ct_rest - np.asarray(nib.load(sys.argv[2]).dataobj).squeeze()) > 0.01).sum())
print(deep.sum(), (jf < 0.95).mean(), jf.min(), (ji < 0.95).mean(), ji.min(), (torn & ~lung).sum(),
      (torn & lung).sum() / (ok & lung).sum(), jp.min(), jp.max(), pairs, widest,
      mass_ratio, worst, lung_mean, predicted, worst_offset, rest_changed, (lung.sum() / rest.sum()),
      rest.sum() * spacing.prod() * 1e-3, lung.sum() * spacing.prod() * 1e-3)
)";

struct Checks {
  std::size_t deep_voxels = 0;
  double below_095 = 0, min_j = 0, image_below_095 = 0, image_min_j = 0;
  std::size_t body_torn = 0;  // voxels outside the lungs whose pull-back J is outside [0.5, 2]
  double lung_torn = 0;       // the share of the lungs' voxels (outside the band) that are
  double pull_min = 0, pull_max = 0;
  std::size_t pairs = 0;
  double widest_mm = 0;
  double mass_ratio = 0;                 // end-inspiration's mass over the rest scan's
  double worst_mass = 0;                 // the mass ratio farthest from 1 (time points; both lungs, each)
  double mean_hu = 0, predicted_hu = 0;  // at end-inspiration, both lungs
  double lung_hu_offset = 0;             // the larger of the two lungs' mean minus its prediction
  std::size_t rest_changed = 0;          // voxels of the warped CT at rest that are not the input's
  double growth = 0;
  double scan_ml = 0, other_ml = 0;  // the lungs' volume at rest and at the breath's other end
};

// The scenario of one run at the test's settings: a quiet breath (healthy-adult: 500 mL) of the
// lungs `mesh` names, the scan at `breath` (mesh.breath), with `tissue`; `voxels` the voxels' keys.
std::string breath_scenario(const std::string& mesh, const std::string& breath, const std::string& tissue,
                            const std::string& voxels, double spacing_m = kSpacingM) {
  return "duration: 8 s\nframes: {rate: 5 Hz}\nmesh: {" + mesh + ", edge: 5 mm, breath: " + breath +
         "}\nfield: {tissue: " + tissue +
         ", interior: {edge: 6 mm}}\nphysiology: {preset: healthy-adult}\n"
         "outputs: {gltf: false, report: false, hdf5: false, physiology_csv: false,\n  voxels: {" +
         voxels + ", spacing: " + std::to_string(std::lround(spacing_m * 1e3)) + " mm}}\n";
}

// One case's run at the test's settings, the scan at `breath` (mesh.breath), with `tissue`, and
// its checks; nothing (after a GTEST_SKIP or a failed run) when there is nothing to check. The
// case `phantom` is both built-in phantom lungs, its CT made from the label map a run without it
// writes at the scan (write_phantom_ct).
std::optional<Checks> run_and_check(const std::string& name, const std::string& breath,
                                    const std::string& tissue = "healthy-supine", double spacing_m = kSpacingM) {
  TempDir dir;
  const bool phantom = name == "phantom";
  std::string mesh = "phantom: both";
  if (phantom) {
    const auto probe = dir.write("probe.yaml", breath_scenario(mesh, "end_expiration", tissue, "at: [end_expiration]"));
    const auto r = run_pneuma({"run", probe.string(), "-o", (dir / "probe").string(), "--quiet"});
    if (r.exit_code != 0) {
      ADD_FAILURE() << name << ": " << r.err;
      return std::nullopt;
    }
    write_phantom_ct(dir / "probe/voxels/labels-end_expiration.nii.gz", dir / "ct.nii.gz");
  } else {
    const auto file = pneuma::test::ct_lobes_dir() / (name + "_lobes.nii.gz");
    if (!std::filesystem::exists(file)) {
      ADD_FAILURE() << "unreachable: the caller checks " << file;
      return std::nullopt;
    }
    write_synthetic_ct(file, dir / "ct.nii.gz", spacing_m);
    mesh = "labels: " + file.string() + ", lungs: {right: [3, 4, 5], left: [1, 2]}";
  }
  // By default with the scenario's tissue (4d-from-labels.yaml).
  const auto scenario = dir.write(
      "ct.yaml",
      breath_scenario(mesh, breath, tissue, "at: [end_expiration, 1 s, end_inspiration], image: ct.nii.gz", spacing_m));
  const auto r = run_pneuma({"run", scenario.string(), "-o", (dir / "out").string(), "--quiet"});
  if (r.exit_code != 0) {
    ADD_FAILURE() << name << ": " << r.err;
    return std::nullopt;
  }
  const auto c = run_program("/usr/bin/python3", {"-c", kChecks, (dir / "out/voxels").string(),
                                                  (dir / "ct.nii.gz").string(), breath, phantom ? "phantom" : "lobes"});
  if (c.exit_code != 0) {
    ADD_FAILURE() << c.err;
    return std::nullopt;
  }
  Checks k;
  std::istringstream in(c.out);
  in >> k.deep_voxels >> k.below_095 >> k.min_j >> k.image_below_095 >> k.image_min_j >> k.body_torn >> k.lung_torn >>
      k.pull_min >> k.pull_max >> k.pairs >> k.widest_mm >> k.mass_ratio >> k.worst_mass >> k.mean_hu >>
      k.predicted_hu >> k.lung_hu_offset >> k.rest_changed >> k.growth >> k.scan_ml >> k.other_ml;
  if (in.fail()) {
    ADD_FAILURE() << c.out;
    return std::nullopt;
  }
  std::cout << name << ", " << tissue << ", scan at " << breath << ": " << k.deep_voxels
            << " lung voxels 6 mm inside; inspiration's J < 0.95 in " << 100 * k.below_095 << " % (image "
            << 100 * k.image_below_095 << " %), smallest " << k.min_j << " (image " << k.image_min_j
            << "); pull-back J outside the band " << k.pull_min << "-" << k.pull_max << ", "
            << "outside [0.5, 2] " << k.body_torn << " voxels of the body, " << 100 * k.lung_torn
            << " % of the lungs'; " << k.pairs << " neighbours more than a voxel apart (widest " << k.widest_mm
            << " mm); lungs x" << k.growth << " (" << k.scan_ml << " -> " << k.other_ml << " mL), mass x"
            << k.mass_ratio << " (farthest from 1 x" << k.worst_mass
            << " over the time points and the lungs), mean lung " << k.mean_hu << " HU (predicted " << k.predicted_hu
            << "; a lung's " << k.lung_hu_offset << " HU from its own); " << k.rest_changed
            << " voxels of the CT at rest not the input's\n";
  return k;
}

bool have_inputs(const std::string& name) {
  const auto file = pneuma::test::ct_lobes_dir() / (name + "_lobes.nii.gz");
  if (name != "phantom" && !std::filesystem::exists(file)) {
    std::cout << "no CT lobe maps at " << file.parent_path()
              << " (set PNEUMA_CT_LOBES to the folder of case00N_lobes.nii.gz)\n";
    return false;
  }
  if (run_program("/usr/bin/python3", {"-c", "import nibabel, scipy.ndimage"}).exit_code != 0) {
    std::cout << "nibabel or scipy is not importable by /usr/bin/python3 (install-deps: python3-nibabel "
                 "python3-scipy)\n";
    return false;
  }
  return true;
}

// The issue's interior and mass checks.
void expect_interior_and_mass(const std::string& name, const Checks& k) {
  EXPECT_GT(k.deep_voxels, 10000u) << name;
  // Interior: few voxels 6 mm inside shrink by more than 5 % (kShrinkingFraction, kShrinkingImage),
  // none below 0.5.
  EXPECT_LT(k.below_095, kShrinkingFraction) << name;
  EXPECT_LT(k.image_below_095, kShrinkingImage) << name;
  EXPECT_GT(k.min_j, 0.5) << name;
  EXPECT_GT(k.image_min_j, 0.5) << name;
  // The lungs keep their mass at every time point, and their mean HU follows the mass-preserving rule.
  EXPECT_NEAR(k.mass_ratio, 1.0, kMass) << name;
  EXPECT_NEAR(k.worst_mass, 1.0, kMass) << name;
  EXPECT_NEAR(k.mean_hu, k.predicted_hu, kMeanHu) << name;
  EXPECT_LT(std::abs(k.lung_hu_offset), kMeanHu) << name;
  EXPECT_EQ(k.rest_changed, 0u) << name;
}

// The checks both places of the scan share: the issue's interior, no tear and mass.
void expect_the_issues_checks(const std::string& name, const Checks& k) {
  expect_interior_and_mass(name, k);
  // No tear outside the pleural band: none in the body or the lungs, and no two neighbours a
  // voxel apart.
  EXPECT_EQ(k.body_torn, 0u) << name;
  EXPECT_EQ(k.lung_torn, 0.0) << name;
  EXPECT_EQ(k.pairs, 0u) << name;
}

}  // namespace

class CtBreath : public ::testing::TestWithParam<const char*> {};

TEST_P(CtBreath, TheInsideDoesNotShrinkTheBodyDoesNotTearAndTheLungsKeepTheirMass) {
  if (!have_inputs(GetParam())) GTEST_SKIP() << "no inputs (above)";
  const std::optional<Checks> k = run_and_check(GetParam(), "end_expiration");
  if (!k) return;
  expect_the_issues_checks(GetParam(), *k);
  EXPECT_GT(k->growth, 1.05) << GetParam();     // the breath is in the files
  EXPECT_LT(k->mean_hu, -855.0) << GetParam();  // darker than the rest lung's -849.5 HU
}

INSTANTIATE_TEST_SUITE_P(RealAnatomy, CtBreath,
                         ::testing::Values("case004", "case005", "case006", "case007", "case008", "case009"));

// The scan at end-inspiration (`mesh.breath: end_inspiration`, a breath-hold CT as the shared
// cases are): the lungs deflate from it by the breath and come back. The same checks at
// end-expiration, the inspiration's Jacobian the inverse of the forward map's there, and the
// issue's reference check: the end-expiration lungs hold the scan's volume less the 500 mL breath
// within 2 % (their warped label voxels against the scan's; the warped breath is about 90 % of
// the physiology's, docs/voxels.md "What a run measures", which 2 % of the lungs' volume allows).
// Three cases keep it about a minute of CPU: case004 (its dome pairs, docs/voxels.md), case009
// (the smallest lungs, the largest motion) and case007 (whose mean HU failed the 2 HU while the
// gap the deflating lung leaves took the rim's lung labels: docs/voxels.md, "The warped lung
// below the scan"). The other three are measured by scripts/ct-breath-audit.py (docs/voxels.md,
// "The issue's checks, measured"). Since that rule the end-expiration lungs are the scan's less
// 500 mL within 1 % (audit: +0.33, +0.25, -0.06 %; +1.02, +1.33, +0.91 % before).
class CtBreathFromInspiration : public ::testing::TestWithParam<const char*> {};

TEST_P(CtBreathFromInspiration, TheLungsDeflateByTheBreathWithoutTearOrFoldAndKeepTheirMass) {
  if (!have_inputs(GetParam())) GTEST_SKIP() << "no inputs (above)";
  const std::optional<Checks> k = run_and_check(GetParam(), "end_inspiration");
  if (!k) return;
  expect_the_issues_checks(GetParam(), *k);
  EXPECT_NEAR(k->other_ml / (k->scan_ml - 500.0), 1.0, 0.01) << GetParam();
  EXPECT_GT(k->mean_hu, -845.0) << GetParam();  // brighter than the scan's -849.5 HU
}

INSTANTIATE_TEST_SUITE_P(RealAnatomy, CtBreathFromInspiration, ::testing::Values("case004", "case007", "case009"));

// Upright (`healthy-upright`, the scan at end-expiration): the same checks on case008, whose left
// lung's recesses under the diaphragm stretched 5 voxels past J = 2 until the upright preset took
// the heart's descent and with it the recess rule, and on case009, whose costophrenic margins
// (the right lung's anterior edge under the dome's 19.8 mm piston, the left lung's tongue) kept
// 2 voxels in each lung there until the rule took the margin too (field/heart.h; docs/voxels.md,
// "The costophrenic margin"). The other four are measured by scripts/ct-breath-audit.py.
class CtBreathUpright : public ::testing::TestWithParam<const char*> {};

TEST_P(CtBreathUpright, TheInsideDoesNotShrinkTheBodyDoesNotTearAndTheLungsKeepTheirMass) {
  if (!have_inputs(GetParam())) GTEST_SKIP() << "no inputs (above)";
  const std::optional<Checks> k = run_and_check(GetParam(), "end_expiration", "healthy-upright");
  if (!k) return;
  expect_the_issues_checks(GetParam(), *k);
  EXPECT_GT(k->growth, 1.05) << GetParam();
  EXPECT_LT(k->mean_hu, -855.0) << GetParam();
}

INSTANTIATE_TEST_SUITE_P(RealAnatomy, CtBreathUpright, ::testing::Values("case008", "case009"));

// case004 at 2 mm voxels (the scan at end-expiration, supine): the tear check is per voxel, so at
// a finer grid it checks nearer the pleura. Here the smoothed surface, and so the deformed lung's
// tets, reaches 4-6 mm below the label map's lung under the left lung's anterior base, and the
// body under it descended 8.3 mm where the lung's boundary descended 10.5 mm (the body field's
// blur, an average, fell short of the lung's motion across the pleura): 22 neighbours 2.0-2.5 mm
// apart just outside the 2-voxel band. With the body field's correction at the pleura
// (model/body_motion.h, "At the pleura") the body follows the lung across it and none is left.
// About 35 s of CPU.
TEST(CtBreathAt2mm, Case004sBodyDoesNotTearUnderTheLeftBase) {
  if (!have_inputs("case004")) GTEST_SKIP() << "no inputs (above)";
  const std::optional<Checks> k = run_and_check("case004", "end_expiration", "healthy-supine", 2e-3);
  if (!k) return;
  expect_the_issues_checks("case004 at 2 mm", *k);
  EXPECT_GT(k->growth, 1.05);
}

namespace {

// A supine lung deflating 500 mL from a scan at end-inspiration, at 2 mm voxels: the issue's
// interior and mass checks, no body or lung voxel outside [0.5, 2], no two neighbours a voxel
// apart, the end-expiration volume within 1 %, the lung brighter than the scan.
void expect_deflation_at_2mm_untorn(const std::string& case_name) {
  const std::optional<Checks> k = run_and_check(case_name, "end_inspiration", "healthy-supine", 2e-3);
  if (!k) return;
  const std::string name = case_name + " at 2 mm, scan at end_inspiration";
  expect_interior_and_mass(name, *k);
  EXPECT_EQ(k->body_torn, 0u) << name;
  EXPECT_EQ(k->lung_torn, 0.0) << name;
  EXPECT_LT(k->pull_max, 2.0) << name;
  EXPECT_GT(k->pull_min, 0.5) << name;
  EXPECT_EQ(k->pairs, 0u) << name;
  EXPECT_NEAR(k->other_ml / (k->scan_ml - 500.0), 1.0, 0.01) << name;
  EXPECT_GT(k->mean_hu, -845.0) << name;  // brighter than the scan's -849.5 HU
}

}  // namespace

// case004 at 2 mm voxels with the scan at end-inspiration (a breath-hold scan, supine): the lung
// deflates by 500 mL. The interior's one U serves the inflation and this deflation, and the
// unfolding for 1 L above rest moved free nodes under the left lung's anterior base that
// steepened the deflation: 3 left-lung voxels 4.5 mm inside the warped pleura at a pull-back J of
// 2.12-2.31 (rest tets at J 0.27-0.37) and 31 neighbour pairs. Each direction's unfolding now keeps
// the other's breaths (field/untangle.h, model/src/interior.cpp): no lung voxel leaves [0.5, 2]
// (largest 1.88), but 15 neighbour pairs 2.00-2.39 mm apart were left at the base. The deflation's
// field must also be a contraction on the surface (field::is_contraction, model::field_for_deflation):
// with both rules no pair is left (measured: pull-back J 0.66-1.82). Held: the issue's interior
// and mass checks, no body or lung voxel outside [0.5, 2], no two neighbours a voxel apart, the
// end-expiration volume within 1 %. About 35 s of CPU.
TEST(CtBreathAt2mm, Case004sLungDoesNotTearUnderTheLeftBaseWhenItDeflates) {
  if (!have_inputs("case004")) GTEST_SKIP() << "no inputs (above)";
  expect_deflation_at_2mm_untorn("case004");
}

// case005 at 2 mm voxels with the scan at end-inspiration (supine): the lung deflates by 500 mL.
// With the contraction at 1.5 times the depth (above) 3 neighbour pairs 2.03 mm apart were left
// 4.5-6 mm inside the left base (pull-back J 1.73-1.78), in the wedge under the heart's overhang:
// the surface field compressed the vertical line through them (21-24 mm) to 0.44-0.50, and the
// deflated surface's own slope was 0.59 (|s (u_i - u_j)| / |x_i - x_j|), so pull-backs could part
// by up to 0.59 / 0.41 times their distance. The ladder now also asks for a slope of at most 1/2 at
// the depth itself (model::field_for_deflation), under which no two pull-backs part by more than
// their points' distance. Held: the issue's interior and mass checks, no body or lung voxel
// outside [0.5, 2], no two neighbours a voxel apart, the end-expiration volume within 1 %.
TEST(CtBreathAt2mm, Case005sLungDoesNotTearUnderTheHeartWhenItDeflates) {
  if (!have_inputs("case005")) GTEST_SKIP() << "no inputs (above)";
  expect_deflation_at_2mm_untorn("case005");
}

// case008 at 2 mm voxels with the scan at end-inspiration (supine): the lung deflates by 500 mL.
// The right lung's surface is closed over its root at the hilum (vessels and airways the lobe map
// leaves out, filled in slices to reach genus 0): a flat medial face 3-6.5 mm off the lobes, which
// the lung's motion carries. The body beside it followed only the motion across it, as beside the
// pleura, and the lung's 2.5 mm vertical slide there, 2 voxels outside the warped lobes' band,
// read as 4 neighbour pairs 2.0-2.5 mm apart (23 upright). Off the lobes there is no pleura, so
// the body follows the whole motion there (model/body_motion.h, "Off the lobes"). Held: the issue's
// interior and mass checks, no body or lung voxel outside [0.5, 2], no two neighbours a voxel
// apart, the end-expiration volume within 1 %. About 35 s of CPU.
TEST(CtBreathAt2mm, Case008sBodyDoesNotTearBesideTheRightHilumWhenItDeflates) {
  if (!have_inputs("case008")) GTEST_SKIP() << "no inputs (above)";
  expect_deflation_at_2mm_untorn("case008");
}

// The built-in phantom (`phantom: both`), which has no label map: the voxels' grid is a box around
// the lungs, the rest label map the lungs' rest tetrahedra on it (right 1, left 2), and its CT is
// made from that map (write_phantom_ct). The same run and checks as above in both postures, the
// scan at end-expiration and at end-inspiration (the phantom is an FRC shape; put at the breath's
// peak it deflates by 500 mL as a breath-hold scan does): the interior, the mass and mean HU, and
// the end-expiration or end-inspiration volume within 1 % (measured: -0.20 to +0.21 %). The tear
// checks of the body (no voxel outside the lungs with a pull-back J outside [0.5, 2]) in every
// cell: with the scan at end-inspiration the supine body beside the posterior recesses was
// compressed to a pull-back J of 2.65 (221 voxels) until the body field's narrowest blur became
// the least that keeps it a contraction (model/body_motion.h; 24 mm supine, 12 mm upright). The
// lungs' tear check too (no lung voxel outside the band with a pull-back J outside [0.5, 2])
// supine: with the scan at end-expiration 6 voxels at the posterior recesses' tips (J 0.47-0.50)
// left it until the supine preset's gravity gradients became ones per metre (`depth: 175 mm`: the
// phantom, 129-141 mm deep, had the CT lungs' 3:1 ratios; field/tissue.h, docs/voxels.md, "A
// shallow lung's gravity"), and upright with the scan at end-inspiration; upright with it at
// end-expiration 2 right-lung voxels at 0.48 under the dome's posterior slope left it until the
// unfolding's moves could no longer stretch a quiet breath's tets past J = 2 (field/untangle.h;
// docs/voxels.md, "The phantom's interior tears at 2 mm, diagnosed"). No two neighbours a voxel
// apart in every cell: upright with the scan at end-inspiration two neighbours inside the right lung lay 4.1 mm
// apart at 4 mm voxels until the deflation's field had to be a contraction on the surface
// (model::field_for_deflation, field::is_contraction; docs/voxels.md, "The scan's place on the
// breath"). About 4 s of CPU per cell.
class PhantomBreath : public ::testing::TestWithParam<std::tuple<const char*, const char*>> {};

TEST_P(PhantomBreath, TheInsideDoesNotShrinkAndTheLungsKeepTheirMassAndTheBreathsVolume) {
  const auto [tissue, breath] = GetParam();
  if (!have_inputs("phantom")) GTEST_SKIP() << "no inputs (above)";
  const std::optional<Checks> k = run_and_check("phantom", breath, tissue);
  if (!k) return;
  const std::string name = std::string("phantom, ") + tissue + ", scan at " + breath;
  expect_interior_and_mass(name, *k);
  const bool from_inspiration = std::string(breath) == "end_inspiration";
  EXPECT_NEAR(k->other_ml / (k->scan_ml + (from_inspiration ? -500.0 : 500.0)), 1.0, 0.01) << name;
  if (from_inspiration) {
    EXPECT_GT(k->mean_hu, -845.0) << name;  // brighter than the scan's -849.5 HU
  } else {
    EXPECT_LT(k->mean_hu, -855.0) << name;  // darker
  }
  EXPECT_EQ(k->body_torn, 0u) << name;
  EXPECT_EQ(k->lung_torn, 0.0) << name;
  EXPECT_EQ(k->pairs, 0u) << name;
}

INSTANTIATE_TEST_SUITE_P(BothPostures, PhantomBreath,
                         ::testing::Combine(::testing::Values("healthy-supine", "healthy-upright"),
                                            ::testing::Values("end_expiration", "end_inspiration")),
                         [](const auto& cell) {
                           std::string name =
                               std::string(std::get<0>(cell.param)) + "_scan_at_" + std::get<1>(cell.param);
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });
