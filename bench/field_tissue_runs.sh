#!/bin/bash
# `pneuma field` whole process with a uniform tissue and with healthy-upright, for one or more
# binaries in the same session (BENCHMARKS.md, "Speed on the user path (#35)").
# Usage: bench/field_tissue_runs.sh CT_MESH BINARY... (labels: the binaries' file names)
set -euo pipefail
ct=$1
shift
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cat >"$work/uniform.yaml" <<'YAML'
name: uniform
posture: upright
stiffness: {model: gradient, profile: linear, nondependent: 1 kPa, dependent: 1 kPa}
YAML
run() {  # label binary mesh [options]
  local label=$1 bin=$2 mesh=$3
  shift 3
  for t in "$work/uniform.yaml" healthy-upright; do
    /usr/bin/time -f "$label $(basename "$bin") $(basename "$t" .yaml) wall %e s cpu %U+%S s" \
      "$bin" field "$mesh" "$@" --tissue "$t" -o "$work/field.h5" -q
  done
}
for rep in 1 2; do
  for bin in "$@"; do
    run phantom-100k "$bin" phantom:right --edge 0.93mm
    run ct-1mm "$bin" "$ct"
    run phantom-346k "$bin" phantom:right --edge 0.5mm
  done
done
for bin in "$@"; do run phantom-1M "$bin" phantom:right --edge 0.294mm; done
