#!/usr/bin/env bash
# Whole-run time of `pneuma run` per sink: 60 s of breathing at 30 frames/s (1801 frames),
# right-lung phantom at ~100k and ~1M vertices (--edge), one sink per run (no physiology CSV).
# The field is computed once per size into a cache beside the scenarios, so every timed run
# reuses it (the "field (cached)" stage is the load). Prints one TSV line per run: the runner's
# own stage timings and the process's wall and CPU time (/usr/bin/time).
# Disk: at most one run's outputs exist at a time (~2.2 GB, PLY at 1M); all deleted afterwards.
#   bench/runner_runs.sh [PNEUMA_BINARY] [WORK_DIR] [SIZES: "100k 1M"]
set -euo pipefail
pneuma=$(realpath "${1:-build/release/cli/pneuma}")
work=${2:-$(mktemp -d /tmp/pneuma-runner-bench.XXXXXX)}
sizes=${3:-"100k 1M"}
mkdir -p "$work"
trap 'rm -rf "$work"/out "$work"/*.h5' EXIT

edge_for() { case $1 in 100k) echo 0.93mm ;; 1M) echo 0.295mm ;; esac; }

# scenario NAME DURATION OUTPUTS_YAML
scenario() {
  cat >"$work/$1.yaml" <<EOF
name: runner-bench-$1
duration: $2
frames:
  rate: 30 Hz
mesh:
  phantom: right
  edge: 4 mm
  share: 55 %
field:
  tissue: healthy-upright
  cache: field-$size.h5
physiology:
  preset: healthy-adult
  output_rate: 100 Hz
outputs:
  physiology_csv: false
$3
EOF
}

printf 'size\tsink\tvertices\tframes\twall_s\tcpu_s\tstages\n'
for size in $sizes; do
  edge=$(edge_for "$size")
  # Sequence: every 10th frame at 100k (181 files, ~0.65 GB), every 30th at 1M (61, ~2.2 GB).
  every=10; [ "$size" = 1M ] && every=30
  # HDF5 with positions stores 24 B per vertex and frame: 4.3 GB at 100k and 43 GB at 1M for
  # 60 s, so that run is shorter (20 s = 601 frames at 100k, 2 s = 61 frames at 1M, ~1.5 GB).
  h5dur="20 s"; [ "$size" = 1M ] && h5dur="2 s"
  none="  gltf: false
  hdf5: false"
  scenario warmup "1 s" "$none"
  scenario none "60 s" "$none"
  scenario gltf "60 s" "  gltf: true
  hdf5: false"
  scenario hdf5 "60 s" "  gltf: false
  hdf5: {positions: false}"
  scenario hdf5-positions "$h5dur" "  gltf: false
  hdf5: {positions: true}"
  scenario hdf5-positions-none "$h5dur" "$none"
  scenario ply "60 s" "$none
  mesh_sequence: {format: ply, every: $every}"
  scenario png "60 s" "$none
  png: {width: 640, height: 480, camera: anterior, every: 30}"
  for name in warmup none gltf hdf5 hdf5-positions-none hdf5-positions ply png; do
    rm -rf "$work/out"
    log="$work/$name-$size.log"
    /usr/bin/time -f 'TIME %e %U %S' "$pneuma" run "$work/$name.yaml" -o "$work/out" --edge "$edge" >"$log" 2>&1 ||
      { cat "$log" >&2; exit 1; }
    du -sh "$work/out" | cut -f1 >"$work/$name-$size.du"
    rm -rf "$work/out"
    wall=$(awk '/^TIME/ {print $2}' "$log")
    cpu=$(awk '/^TIME/ {print $3 + $4}' "$log")
    vertices=$(sed -n 's/.*mesh of \([0-9]*\) vertices.*/\1/p' "$log")
    frames=$(sed -n 's/.*: \([0-9]*\) frames at.*/\1/p' "$log")
    stages=$(awk '/^  [a-z].* s$/ {sub(/^  /, ""); sub(/ s$/, ""); gsub(/  +/, "="); printf "%s; ", $0}' "$log")
    printf '%s\t%s\t%s\t%s\t%s\t%s\t%s (disk %s)\n' "$size" "$name" "$vertices" "$frames" "$wall" "$cpu" "$stages" \
      "$(cat "$work/$name-$size.du")"
  done
done
