#!/usr/bin/env bash
# Voxel outputs by the clock (#50; BENCHMARKS.md, "Voxel outputs", "Whole runs"): whole processes
# (/usr/bin/time -v: wall time and peak resident memory) and the manifest's stage times; the
# native time point against `plastimatch warp` of its CT with pneuma's own pull-back DVF, run by
# the same script right after it:
#   native  one time point (end-inspiration) at case004's own grid (512 x 512 x 270, 70.8 Mvoxels):
#           forward and pull-back DVF, warped label map and warped CT (a stand-in CT made from the
#           label map on its grid: lung -850 + 5 l HU for lobe l, everything else 40 HU), no report;
#           then plastimatch warps that CT with the run's pull-back DVF (linear, the default)
#   native-nii  the same with `format: nii` (no compression; the table of BENCHMARKS.md "Files"),
#           and plastimatch warping the CT with that run's plain .nii pull-back DVF
#   (each plastimatch warp twice: right after the run, its DVF read from the disk since pneuma
#   writes past the page cache; then with the DVF read into the page cache first)
#   phases  ten phase bins at that grid over 24 s of breathing (DVFs, labels and Jacobian images,
#           the defaults; no CT, no report)
#   phases-nii  the same with `format: nii`
#   shipped scenarios/4d-from-labels.yaml as shipped (2 mm, two time points, report on), cold (a
#           fresh output folder) then warm (the same folder: the field cache hit), with CPU times
#   spacing one time point (end-inspiration, no CT, no report) at case004's own grid and at the
#           shipped `spacing: 2 mm`, each run twice into its folder (the second reuses the field
#           cache): the `output voxels` stage's time per Mvoxel at each grid ("in proportion")
# Usage: [PNEUMA=path/to/pneuma] bench/voxels_speed.sh [MODES (default "native phases shipped"; also native-nii, phases-nii, spacing)] [WORK_DIR]
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
modes=${1:-native phases shipped}
work=${2:-$(mktemp -d /tmp/pneuma-voxels-speed.XXXXXX)}
pneuma=${PNEUMA:-$here/build/release/cli/pneuma}  # PNEUMA=...: another build (a baseline)
labels=$(cd "$here/../shared/data/ct-lobes" && pwd)/case004_lobes.nii.gz
mkdir -p "$work"
cd "$work"
echo "work: $work; $(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg)"

# whole PROCESS...: runs it under /usr/bin/time -v and prints its wall time and peak memory.
timed() {
  local name=$1
  shift
  /usr/bin/time -v "$@" > "$name.out" 2> "$name.time"
  local wall rss cpu
  wall=$(grep 'Elapsed (wall clock)' "$name.time" | awk '{print $NF}')
  rss=$(grep 'Maximum resident' "$name.time" | awk '{print $NF}')
  cpu=$(grep -E '(User|System) time' "$name.time" | awk '{s += $NF} END {print s}')  # the figure to compare
  printf '%-28s wall %9s  cpu %7.1f s  peak %6.2f GiB  (load %s)\n' "$name" "$wall" "$cpu" \
    "$(echo "$rss / 1048576" | bc -l)" "$(cut -d' ' -f1 /proc/loadavg)"
}
# The manifest's stage times, and each one's share of their sum.
stages() {
  /usr/bin/python3 - "$1/manifest.json" <<'PY'
import json, sys
t = json.load(open(sys.argv[1]))["timings_s"]
total = sum(t.values())
for k, v in t.items():
    print(f"    {k:34} {v:8.2f} s {100 * v / total:5.1f} %")
print(f"    {'(sum)':34} {total:8.2f} s")
PY
}
scenario() {  # scenario OUT SED-EXPRESSIONS...
  local out=$1
  shift
  sed -e "s#../../shared/data/ct-lobes/case004_lobes.nii.gz#$labels#" "$@" "$here/scenarios/4d-from-labels.yaml" > "$out"
}

if [[ " $modes " == *" native "* ]]; then
  [ -f ct.nii.gz ] || /usr/bin/python3 - "$labels" <<'PY'
import sys
import nibabel, numpy
src = nibabel.load(sys.argv[1])
lobes = numpy.asarray(src.dataobj).astype(numpy.int16)
ct = numpy.where(lobes > 0, -850 + 5 * lobes, 40).astype(numpy.int16)
nibabel.save(nibabel.Nifti1Image(ct, src.affine, src.header), "ct.nii.gz")
PY
  scenario native.yaml -e 's#at: \[end_expiration, end_inspiration\]#at: [end_inspiration]#' \
    -e "s#^    spacing: 2 mm#    image: $work/ct.nii.gz\n    jacobian: false#" \
    -e 's#^  physiology_csv: true#  physiology_csv: true\n  report: false#'
  rm -rf native
  timed "native: pneuma run" "$pneuma" run native.yaml -o native --quiet
  stages native
  ls -l native/voxels
  timed "native: plastimatch warp" plastimatch warp --input ct.nii.gz \
    --xf native/voxels/dvf-pullback-end_inspiration.nii.gz --output-img plastimatch-ct.nii.gz
  # Again with the DVF in the page cache (pneuma writes past it: the first read came from the disk).
  cat native/voxels/dvf-pullback-end_inspiration.nii.gz > /dev/null
  timed "native: plastimatch warp (cached)" plastimatch warp --input ct.nii.gz \
    --xf native/voxels/dvf-pullback-end_inspiration.nii.gz --output-img plastimatch-ct.nii.gz
fi

if [[ " $modes " == *" native-nii "* ]]; then
  [ -f native.yaml ] || { echo "native-nii needs the native mode first (its CT and scenario)" >&2; exit 2; }
  sed -e 's#^    jacobian: false#    jacobian: false\n    format: nii#' native.yaml > native-nii.yaml
  rm -rf native-nii
  timed "native-nii: pneuma run" "$pneuma" run native-nii.yaml -o native-nii --quiet
  stages native-nii
  ls -l native-nii/voxels
  timed "native-nii: plastimatch warp" plastimatch warp --input ct.nii.gz \
    --xf native-nii/voxels/dvf-pullback-end_inspiration.nii --output-img plastimatch-ct-nii.nii.gz
  cat native-nii/voxels/dvf-pullback-end_inspiration.nii > /dev/null  # as above: from the page cache
  timed "native-nii: plastimatch warp (cached)" plastimatch warp --input ct.nii.gz \
    --xf native-nii/voxels/dvf-pullback-end_inspiration.nii --output-img plastimatch-ct-nii.nii.gz
fi

if [[ " $modes " == *" phases "* ]]; then
  scenario phases.yaml -e 's#^duration: 8 s#duration: 24 s#' \
    -e 's#at: \[end_expiration, end_inspiration\]#at: [phases]#' -e "/^    spacing: 2 mm/d" \
    -e 's#^  physiology_csv: true#  physiology_csv: true\n  report: false\n  phases: {bins: 10}#'
  rm -rf phases
  timed "phases: pneuma run" "$pneuma" run phases.yaml -o phases --quiet
  stages phases
  ls phases/voxels | wc -l
fi

if [[ " $modes " == *" phases-nii "* ]]; then
  [ -f phases.yaml ] || { echo "phases-nii needs the phases mode first (its scenario)" >&2; exit 2; }
  sed -e 's#^    at: \[phases\]#    at: [phases]\n    format: nii#' phases.yaml > phases-nii.yaml
  rm -rf phases-nii
  timed "phases-nii: pneuma run" "$pneuma" run phases-nii.yaml -o phases-nii --quiet
  stages phases-nii
  ls phases-nii/voxels | wc -l
fi

if [[ " $modes " == *" shipped "* ]]; then
  # Cold: a fresh folder (surfaces, fields and insides computed). Warm: the same folder again, its
  # field-*.h5 (the field cache, with each lung's inside) read back instead (docs/formats.md).
  scenario shipped.yaml
  rm -rf shipped
  timed "shipped (cold): pneuma run" "$pneuma" run shipped.yaml -o shipped --quiet
  grep -E 'User time|System time' "shipped (cold): pneuma run.time" | sed 's/^\s*/    /'
  stages shipped
  timed "shipped (warm): pneuma run" "$pneuma" run shipped.yaml -o shipped --quiet
  grep -E 'User time|System time' "shipped (warm): pneuma run.time" | sed 's/^\s*/    /'
  stages shipped
fi

if [[ " $modes " == *" spacing "* ]]; then
  for grid in native 2mm; do
    if [ $grid = native ]; then drop_spacing=(-e "/^    spacing: 2 mm/d"); else drop_spacing=(); fi
    scenario "spacing-$grid.yaml" -e 's#at: \[end_expiration, end_inspiration\]#at: [end_inspiration]#' \
      "${drop_spacing[@]}" -e 's#^  physiology_csv: true#  physiology_csv: true\n  report: false#'
    rm -rf "spacing-$grid"
    "$pneuma" run "spacing-$grid.yaml" -o "spacing-$grid" --quiet # the field cache, not timed
    timed "spacing $grid: pneuma run" "$pneuma" run "spacing-$grid.yaml" -o "spacing-$grid" --quiet
    /usr/bin/python3 - "spacing-$grid" <<'PY'
import json, sys
import nibabel
folder = sys.argv[1]
seconds = json.load(open(f"{folder}/manifest.json"))["timings_s"]["output voxels"]
shape = nibabel.load(f"{folder}/voxels/labels-end_inspiration.nii.gz").shape
mvoxels = shape[0] * shape[1] * shape[2] / 1e6
print(f"    grid {shape[0]} x {shape[1]} x {shape[2]} = {mvoxels:.2f} Mvoxels; output voxels {seconds:.2f} s, "
      f"{1e3 * seconds / mvoxels:.1f} ms per Mvoxel")
PY
  done
fi
