#!/usr/bin/env bash
# Peak memory (max RSS) and wall time of `pneuma mesh from-labels` on the six CT lobe maps, both
# lungs, against `pneuma mesh from-labels` never getting past reading (a label absent from the
# file: the read and decompression alone). Data: ../shared/data/ct-lobes (CC BY 4.0, see its
# README.md) or $PNEUMA_CT_LOBES. Usage: bench/labels_memory.sh [build/release/cli/pneuma]
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
pneuma="${1:-$here/build/release/cli/pneuma}"
data="${PNEUMA_CT_LOBES:-$here/../shared/data/ct-lobes}"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
printf "case lung read_s read_MiB extract_s extract_MiB\n"
for c in 004 005 006 007 008 009; do
  f="$data/case${c}_lobes.nii.gz"
  [ -f "$f" ] || { echo "no $f (set PNEUMA_CT_LOBES)" >&2; exit 1; }
  read -r rs rm < <(/usr/bin/time -f "%e %M" "$pneuma" mesh from-labels "$f" --labels 99 -o "$out/x.ply" 2>&1 >/dev/null | tail -1)
  for lung in right left; do
    labels=3,4,5; [ $lung = left ] && labels=1,2
    read -r es em < <(/usr/bin/time -f "%e %M" "$pneuma" mesh from-labels "$f" --labels $labels -o "$out/$lung.ply" 2>&1 >/dev/null | tail -1)
    awk -v c="$c" -v l=$lung -v rs="$rs" -v rm="$rm" -v es="$es" -v em="$em" 'BEGIN { printf "case%s %s %s %.0f %s %.0f\n", c, l, rs, rm / 1024, es, em / 1024 }'
  done
done
