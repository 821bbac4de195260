#!/usr/bin/env bash
# Voxel files by measurement (BENCHMARKS.md, "Voxel outputs", "Files"): a real run's pull-back DVF
# and warped label map (scenarios/4d-from-labels.yaml on case004, end-inspiration, at SPACING,
# written plain with `format: nii`; its peak memory from /usr/bin/time), then
# build/release/bench/voxel_files_bench writes them in every kind (zlib levels, parallel members,
# libdeflate, .nii, .mha, .nrrd) and reads each back with ITK, and this script reads each with
# nibabel (/usr/bin/python3) and plastimatch (`plastimatch convert`, whole process), each checked
# voxel for voxel against the original.
# Usage: bench/voxel_files.sh [SPACING (default "2 mm"; "native" for the label map's own grid)] [WORK_DIR]
# (PNEUMA_BENCH_FILTER: a --benchmark_filter regex, e.g. for the native grid a few kinds only)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
spacing=${1:-2 mm}
work=${2:-$(mktemp -d /tmp/pneuma-voxel-files.XXXXXX)}
pneuma=$here/build/release/cli/pneuma
bench=$here/build/release/bench/voxel_files_bench
labels=$(cd "$here/../shared/data/ct-lobes" && pwd)/case004_lobes.nii.gz
mkdir -p "$work"
cd "$work"

spacing_line="    spacing: $spacing"
[ "$spacing" = native ] && spacing_line=""
sed -e "s#../../shared/data/ct-lobes/case004_lobes.nii.gz#$labels#" \
    -e 's#at: \[end_expiration, end_inspiration\]#at: [end_inspiration]#' \
    -e "s#^    spacing: 2 mm#$spacing_line\n    format: nii\n    jacobian: false#" \
    -e 's#^  physiology_csv: true#  physiology_csv: true\n  report: false#' \
    "$here/scenarios/4d-from-labels.yaml" > scenario.yaml
/usr/bin/time -v "$pneuma" run scenario.yaml -o run --quiet 2> time.txt
echo "pneuma run: $(grep -E 'Elapsed|Maximum resident' time.txt | tr -s ' ' | tr '\n' ' ')"
cp run/voxels/dvf-pullback-end_inspiration.nii dvf.nii
cp run/voxels/labels-end_inspiration.nii labels.nii
ls -l dvf.nii labels.nii

PNEUMA_VOXEL_FILES_DIR=$work "$bench" --benchmark_out=bench.json --benchmark_out_format=json ${PNEUMA_BENCH_FILTER:+--benchmark_filter="$PNEUMA_BENCH_FILTER"}

# nibabel and plastimatch: whole-file read time (median of 3) and the values against the original.
/usr/bin/python3 - "$work" <<'PY'
import json, os, subprocess, sys, time
import nibabel as nib, numpy as np
work = sys.argv[1]
orig = {n: np.array(nib.load(os.path.join(work, n + ".nii")).dataobj) for n in ("dvf", "labels")}
# The labels warped by plastimatch through the plain .nii DVF: what every other DVF file must give.
subprocess.run(["plastimatch", "warp", "--input", os.path.join(work, "labels.nii"), "--xf",
                os.path.join(work, "dvf.nii"), "--output-img", os.path.join(work, "warped.nii"),
                "--interpolation", "nn"], check=True, capture_output=True)
warped = np.array(nib.load(os.path.join(work, "warped.nii")).dataobj)
assert not np.array_equal(warped, orig["labels"]), "the DVF moved nothing"
def median(f):
    times = []
    for _ in range(3):
        t = time.perf_counter(); value = f(); times.append(time.perf_counter() - t)
    return sorted(times)[1], value
print(f"{'file':34} {'MB':>8} {'nibabel s':>10} {'plastimatch s':>14}  (DVF: warp, labels: convert)")
for name in sorted(os.listdir(os.path.join(work, "out"))):
    path = os.path.join(work, "out", name)
    key = name.split("-")[0]
    nib_t = "-"
    if ".nii" in name:
        t, data = median(lambda: np.array(nib.load(path).dataobj))  # a copy: read, not mapped
        if not np.array_equal(data, orig[key]): sys.exit(f"nibabel read other values from {name}")
        nib_t = f"{t:.3f}"
    # plastimatch: a label map read and written by `convert`; a DVF read by `warp` (the labels
    # through it, nearest neighbour), whose result must be the plain .nii's, voxel for voxel.
    out = os.path.join(work, "plastimatch.nii")
    if key == "dvf":
        command = ["plastimatch", "warp", "--input", os.path.join(work, "labels.nii"), "--xf", path,
                   "--output-img", out, "--interpolation", "nn"]
        want = warped
    else:
        command = ["plastimatch", "convert", "--input", path, "--output-img", out]
        want = orig["labels"]
    t, r = median(lambda: subprocess.run(command, capture_output=True))
    pm_t = "failed"
    if r.returncode == 0:
        data = np.array(nib.load(out).dataobj)
        pm_t = f"{t:.3f}" if np.array_equal(data.reshape(want.shape), want) else "other values"
    print(f"{name:34} {os.path.getsize(path) / 1e6:8.2f} {nib_t:>10} {pm_t:>14}", flush=True)
PY
