#!/bin/bash
# `pneuma field MESH` whole process with healthy-upright against a uniform tissue, both from the
# same mesh file (no phantom construction in the timing), alternated, REPEATS times each (default
# 5); prints the median wall and CPU seconds of each arm and their ratio, per binary and mesh
# (BENCHMARKS.md, "The field with a realistic tissue at the speed of its solve (#50)").
# Usage: [REPEATS=5] bench/field_tissue_ratio.sh BINARY... -- MESH...
# Make the meshes beforehand, e.g. `pneuma phantom --lung right --edge 0.294mm -o right-1M.ply`,
# `pneuma mesh from-labels case004_lobes.nii.gz --labels 3,4,5 --edge 1.4mm -o ct-right.ply`.
set -euo pipefail
repeats=${REPEATS:-5}
binaries=()
while [[ $# -gt 0 && $1 != -- ]]; do
  binaries+=("$1")
  shift
done
[[ $# -gt 1 ]] || {
  echo "usage: bench/field_tissue_ratio.sh BINARY... -- MESH..." >&2
  exit 2
}
shift
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cat >"$work/uniform.yaml" <<'YAML'
name: uniform
posture: upright
stiffness: {model: gradient, profile: linear, nondependent: 1 kPa, dependent: 1 kPa}
YAML
median() { sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }
printf '%-28s %-24s %8s %8s %8s %8s %7s %7s\n' mesh binary "uni wall" "uni cpu" "hu wall" "hu cpu" "wall x" "cpu x"
for mesh in "$@"; do
  for bin in "${binaries[@]}"; do
    : >"$work/uniform.t"
    : >"$work/healthy.t"
    for ((rep = 0; rep < repeats; ++rep)); do
      for arm in uniform healthy; do
        tissue=$([[ $arm == uniform ]] && echo "$work/uniform.yaml" || echo healthy-upright)
        /usr/bin/time -f "%e %U %S" -a -o "$work/$arm.t" "$bin" field "$mesh" --tissue "$tissue" -o "$work/f.h5" -q
      done
    done
    uw=$(awk '{print $1}' "$work/uniform.t" | median)
    uc=$(awk '{print $2 + $3}' "$work/uniform.t" | median)
    hw=$(awk '{print $1}' "$work/healthy.t" | median)
    hc=$(awk '{print $2 + $3}' "$work/healthy.t" | median)
    printf '%-28s %-24s %8.2f %8.2f %8.2f %8.2f %7.2f %7.2f\n' "$(basename "$mesh")" "$(basename "$bin")" \
      "$uw" "$uc" "$hw" "$hc" "$(echo "$hw / $uw" | bc -l)" "$(echo "$hc / $uc" | bc -l)"
  done
done
