#!/usr/bin/env bash
# pneuma cohort against a bare loop of `pneuma run`: the same subjects x scenarios (6 phantom
# subjects: both lungs at 5, 6 and 8 mm; quiet breathing and a deep breath, 10 s at 10 Hz), each
# subject's field computed once in both (the loop gives each scenario the subject's field file as
# its cache: the first run computes it, the second reuses it). Prints the wall time of the cohort
# at 1 and 2 jobs at once, of the loop, and the per-job overhead: (cohort at 1 job - loop) / jobs
# (Snakemake: start, DAG, polling; pneuma: a process per field job and the cohort read per job).
# Usage: bench/cohort_runs.sh [build/release/cli/pneuma]   (needs snakemake)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
pneuma="$(realpath "${1:-$here/build/release/cli/pneuma}")"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
export PNEUMA_CONFIG_DIR="$here/configs"

mkdir -p "$work/scenarios"
common='frames: {rate: 10 Hz}
field: {tissue: healthy-upright}
outputs: {hdf5: false, png: false, gltf: false}'
printf 'name: quiet\nduration: 10 s\n%s\nphysiology: {preset: healthy-adult}\n' "$common" >"$work/scenarios/quiet.yaml"
printf 'name: deep\nduration: 10 s\n%s\nphysiology:\n  preset: healthy-adult\n  driver: {tidal_volume: 900 mL}\n' \
  "$common" >"$work/scenarios/deep.yaml"
subjects=""
for lung in right left; do
  for edge in 5 6 8; do subjects+="  ${lung}${edge}: {mesh: {phantom: $lung, edge: $edge mm}}"$'\n'; done
done
printf 'name: bench\nsubjects:\n%sscenarios: {quiet: scenarios/quiet.yaml, deep: scenarios/deep.yaml}\n' "$subjects" \
  >"$work/cohort.yaml"

seconds() { local start=$SECONDS; "$@" >/dev/null 2>&1; echo $((SECONDS - start)); }
now() { date +%s.%N; }

t0=$(now); "$pneuma" cohort "$work/cohort.yaml" -o "$work/c1" --jobs 1 >/dev/null 2>&1; t1=$(now)
"$pneuma" cohort "$work/cohort.yaml" -o "$work/c2" --jobs 2 >/dev/null 2>&1; t2=$(now)
# The bare loop: each scenario with the subject's mesh and the subject's field file as cache.
for lung in right left; do
  for edge in 5 6 8; do
    for scenario in quiet deep; do
      sed "s|^field: {tissue: healthy-upright}|mesh: {phantom: $lung, edge: $edge mm}\nfield: {tissue: healthy-upright, cache: $work/loop-fields/$lung$edge.h5}|" \
        "$work/scenarios/$scenario.yaml" >"$work/scenarios/loop.yaml"
      mkdir -p "$work/loop-fields"
      "$pneuma" --threads 1 run "$work/scenarios/loop.yaml" -o "$work/loop/$lung$edge/$scenario" --quiet
    done
  done
done
t3=$(now)
awk -v a="$t0" -v b="$t1" -v c="$t2" -v d="$t3" 'BEGIN {
  one = b - a; two = c - b; loop = d - c; jobs = 6 + 12
  printf "cohort, 1 job at once:  %6.1f s\ncohort, 2 jobs at once: %6.1f s (1 job / 2 jobs: %.2f)\n", one, two, one / two
  printf "bare pneuma run loop:   %6.1f s (12 runs, 6 fields)\nper-job overhead of the cohort: %.2f s (%d jobs)\n", loop, (one - loop) / jobs, jobs
}'
