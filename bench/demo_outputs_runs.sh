#!/usr/bin/env bash
# The demo's heavy outputs (#35): `make demo`'s scenario (scenarios/quiet-breathing.yaml: the
# right-lung phantom at 4 mm, 5,292 vertices, 1801 frames) run with one output set at a time,
# alternating the binaries, REPS times. The field is computed once into WORK/field.h5 and
# reused (`field.cache`; a first run per binary, not printed), so the sets differ only in their
# outputs. Prints one TSV line per run: binary, output set, the runner's seconds for each output
# (manifest.json's timings_s), and the process's wall, user and system seconds (/usr/bin/time).
# The baseline set is physiology_csv alone: a set's CPU minus the baseline's is its outputs' cost.
#   [PNG_SETTINGS='{...}'] bench/demo_outputs_runs.sh REPS WORK_DIR BINARY...
set -euo pipefail
reps=$1
work=$2
shift 2
root=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$work"
trap 'rm -rf "$work"/out-*' EXIT

# set_of NAME OUTPUTS_YAML: the demo scenario with the shared field cache and these outputs.
set_of() {
  sed -e '/^outputs:/,$d' -e "s|^  tissue: healthy-upright|&\n  cache: $work/field.h5|" \
    "$root/scenarios/quiet-breathing.yaml" >"$work/$1.yaml"
  printf 'outputs:\n  report: false\n  physiology_csv: true\n%s' "$2" >>"$work/$1.yaml"
}
# PNG_SETTINGS: the png output's settings (default: the demo's, e.g. with antialiasing: fxaa; pass
# '{width: 480, height: 360, camera: anterior, every: 15}' to compare with a binary older than
# that key: MSAA 4x, the default).
png_settings=${PNG_SETTINGS:-$(sed -n 's/^  png: //p' "$root/scenarios/quiet-breathing.yaml")}
png="  png: $png_settings
"
set_of baseline '  gltf: false
  hdf5: false
'
set_of hdf5 '  gltf: false
  hdf5: true
'
set_of gltf '  gltf: true
  hdf5: false
'
set_of png "  gltf: false
  hdf5: false
$png"
set_of all3 "  gltf: true
  hdf5: true
$png"

timing() {
  /usr/bin/python3 -c "import json, sys; print(json.load(open(sys.argv[1]))['timings_s'].get('output ' + sys.argv[2], '-'))" \
    "$1/manifest.json" "$2"
}
for bin in "$@"; do "$bin" run "$work/baseline.yaml" -o "$work/out-warm" --quiet; done
printf 'binary\tset\thdf5_s\tgltf_s\tpng_s\twall_s\tuser_s\tsys_s\n'
for ((r = 0; r < reps; ++r)); do
  for set in baseline hdf5 gltf png all3; do
    for bin in "$@"; do
      out="$work/out-$set"
      /usr/bin/time -f '%e %U %S' -o "$work/time" "$bin" run "$work/$set.yaml" -o "$out" --quiet
      read -r wall user sys <"$work/time"
      printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$bin" "$set" "$(timing "$out" hdf5)" "$(timing "$out" gltf)" \
        "$(timing "$out" png)" "$wall" "$user" "$sys"
    done
  done
done
