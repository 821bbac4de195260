#!/bin/sh
# The frame update against numpy's `rest + s*u` (issue #35's baseline), alternated in one session:
# frame_kernel_bench's copy, fused and tabulated updates at ~240k and ~1M vertices, then numpy 's
# add on (n, 3) float64 arrays of the same sizes (median of 5 x 50 calls), ROUNDS times.
# Usage: bench/frame_vs_numpy.sh [BUILD_DIR] [ROUNDS]
set -eu
build=${1:-build/release}
rounds=${2:-2}
python=${PYTHON:-/usr/bin/python3}
i=0
while [ "$i" -lt "$rounds" ]; do
  i=$((i + 1))
  echo "== round $i: pneuma"
  "$build/bench/frame_kernel_bench" --benchmark_filter='BM_(Copy|FusedKernel|TabulatedUpdate)/[12]' \
    --benchmark_format=console 2>/dev/null | grep -E 'median|^BM_.*_median' || true
  echo "== round $i: numpy rest + s*u"
  "$python" - <<'PY'
import timeit, numpy as np
for n in (239854, 1003704):
    rng = np.random.default_rng(1)
    rest, u = rng.random((n, 3)), rng.random((n, 3))
    t = timeit.Timer(lambda: rest + 0.7 * u).repeat(5, 50)
    print(f"numpy n={n}: median {sorted(t)[2] / 50 * 1e6:.0f} us")
PY
done
