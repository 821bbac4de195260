#!/bin/bash
# The unit field of two pneuma binaries on the twelve shared CT lungs (six cases, both lungs):
# each lung's surface from its label map (Mesh_3 at EDGE, default 2 mm), `pneuma field --tissue
# healthy-upright` with each binary, and per lung the largest |u_new - u_old| over the vertices
# relative to the largest |u_old|, read with h5py (BENCHMARKS.md, #50).
# Usage: bench/field_tissue_diff.sh OLD NEW [CT_LOBES_DIR] [EDGE]
set -euo pipefail
old=$1 new=$2
lobes=${3:-$(dirname "$0")/../../shared/data/ct-lobes}
edge=${4:-2mm}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for case in case004 case005 case006 case007 case008 case009; do
  for side in right left; do
    labels=$([[ $side == right ]] && echo 3,4,5 || echo 1,2)
    mesh="$work/$case-$side.ply"
    "$old" mesh from-labels "$lobes/${case}_lobes.nii.gz" --labels "$labels" --edge "$edge" -o "$mesh" >/dev/null
    "$old" field "$mesh" --tissue healthy-upright -o "$work/old.h5" -q
    "$new" field "$mesh" --tissue healthy-upright -o "$work/new.h5" -q
    same=$(cmp -s "$work/old.h5" "$work/new.h5" && echo "same bytes" || echo "bytes differ")
    /usr/bin/python3 - "$work/old.h5" "$work/new.h5" "$case $side" "$same" <<'PY'
import sys
import h5py
import numpy as np
def unit(path):
    with h5py.File(path, "r") as f:
        found = []
        f.visititems(lambda name, obj: found.append(name) if isinstance(obj, h5py.Dataset) and name.endswith("unit_displacement") else None)
        return np.asarray(f[found[0]])
a, b = unit(sys.argv[1]), unit(sys.argv[2])
largest = np.linalg.norm(a, axis=1).max()
diff = np.linalg.norm(b - a, axis=1).max()
print(f"{sys.argv[3]}: {len(a)} vertices, largest |du| / max |u| = {diff / largest:.3g} ({sys.argv[4]})")
PY
  done
done
