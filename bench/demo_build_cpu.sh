#!/usr/bin/env bash
# CPU-seconds per translation unit of a clean build of what `make demo` builds.
# Usage: bench/demo_build_cpu.sh BUILD_DIR [JOBS (default 2)] [extra cmake -D options...]
# Configures BUILD_DIR as `make demo` does (release preset, tests and benchmarks off,
# PNEUMA_PHANTOM_ONLY=ON; pass -DPNEUMA_PHANTOM_ONLY=OFF for the whole engine), with every
# compile and link step run through a wrapper that records its wall, user and system seconds
# (/usr/bin/time) instead of ccache (CCACHE_DISABLE=1 too), then builds the `pneuma` target
# under `nice` and prints the whole build's CPU and the slowest steps. BUILD_DIR must not exist:
# a clean build is the point. Other work on the machine shows in wall time, not in CPU seconds.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:?usage: bench/demo_build_cpu.sh BUILD_DIR [JOBS] [cmake options...]}
jobs=${2:-2}
shift $(( $# >= 2 ? 2 : 1 ))
if [ -e "$build" ]; then
  echo "demo_build_cpu: $build exists (a clean build is measured: remove it first)" >&2
  exit 2
fi
mkdir -p "$build"
build=$(realpath "$build")
log=$build/step-times.txt
wrapper=$build/time-step
# The wrapper replaces ccache as the compiler launcher (find_program keeps a cached
# CCACHE_PROGRAM) and is the linker launcher: one line per step, "wall user system output".
cat >"$wrapper" <<WRAP
#!/bin/sh
out=?
prev=
for a in "\$@"; do [ "\$prev" = -o ] && out=\$a; prev=\$a; done
exec /usr/bin/time -a -o "$log" -f "%e %U %S \$out" "\$@"
WRAP
chmod +x "$wrapper"
export CCACHE_DISABLE=1
t0=$(date +%s.%N)
/usr/bin/time -o "$build/configure-time.txt" -f "%e %U %S" \
  cmake --preset release -B "$build" -DPNEUMA_BUILD_TESTS=OFF -DPNEUMA_BUILD_BENCH=OFF -DPNEUMA_PHANTOM_ONLY=ON \
  -DCCACHE_PROGRAM="$wrapper" -DCMAKE_CXX_LINKER_LAUNCHER="$wrapper" "$@" >/dev/null
/usr/bin/time -o "$build/build-time.txt" -f "%e %U %S" \
  nice ninja -C "$build" -j "$jobs" pneuma >"$build/build-output.txt"
t1=$(date +%s.%N)
read -r cw cu cs <"$build/configure-time.txt"
read -r bw bu bs <"$build/build-time.txt"
steps=$(wc -l <"$log")
echo "configure: ${cw} s wall, $(echo "$cu + $cs" | bc) CPU-s"
echo "build: ${bw} s wall, ${bu} s user + ${bs} s system = $(echo "$bu + $bs" | bc) CPU-s, ${steps} timed steps (-j ${jobs})"
echo "load average at the end: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "slowest steps (CPU-s = user + system, wall s, output):"
awk '{printf "%8.1f %8.1f %s\n", $2 + $3, $1, $4}' "$log" | sort -rn | head -"${TOP:-20}"
