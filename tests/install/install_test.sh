#!/usr/bin/env bash
# cmake --install into a temporary prefix, then the installed `pneuma run` of the demo scenario
# from a folder outside the build and source trees, with neither on any search path (a clean
# environment: PATH=/usr/bin:/bin, no PNEUMA_CONFIG_DIR, LD_LIBRARY_PATH or PYTHONPATH into them).
# Oracles: the manifest against the files (each listed file there with its SHA-256 by sha256sum),
# the frame count from the scenario's duration and rate, the Python module's physiology against
# the CLI's physiology.csv, and the presets: moved out of the prefix, both fail naming the prefix's
# folder (so neither falls back to the source tree compiled into it); the build tree's binary
# still finds the source tree's presets.
# Usage: install_test.sh BUILD_DIR SOURCE_DIR HAS_PYTHON(0|1)
set -euo pipefail
build=$(realpath "$1")
source=$(realpath "$2")
has_python=$3
fail() { echo "install_test: $*" >&2; exit 1; }

tmp=$(mktemp -d /tmp/pneuma-install.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
prefix=$tmp/prefix
work=$tmp/work
mkdir "$work"
cmake --install "$build" --prefix "$prefix" >/dev/null

for f in bin/pneuma share/pneuma/configs/physiology/healthy-adult.yaml share/pneuma/configs/tissue/healthy-upright.yaml; do
  [ -e "$prefix/$f" ] || fail "cmake --install did not install $f"
done
python_dir=$prefix/lib/python3/dist-packages
if [ "$has_python" = 1 ]; then
  [ -e "$python_dir/pneuma/__init__.py" ] || fail "the Python module is not installed"
fi
# Nothing in the binary points at the build tree for libraries.
if readelf -d "$prefix/bin/pneuma" | grep -E 'R(UN)?PATH' | grep -qF "$build"; then
  fail "bin/pneuma has an RPATH into the build tree"
fi

cp "$source/scenarios/quiet-breathing.yaml" "$work/"
cd "$work"
clean=(env -i "PATH=/usr/bin:/bin" "HOME=$work" "LANG=C.UTF-8" "TMPDIR=$tmp")
"${clean[@]}" "$prefix/bin/pneuma" run quiet-breathing.yaml -o out --quiet || fail "the installed pneuma run failed"

/usr/bin/python3 - "$work" <<'PY' || fail "the outputs do not match the manifest"
import hashlib, json, re, sys
from pathlib import Path
work = Path(sys.argv[1])
out = work / "out"
manifest = json.loads((out / "manifest.json").read_text())
listed = {f["path"]: f for f in manifest["files"]}
for name in ("breathing.glb", "series.h5", "series.xdmf", "physiology.csv", "motion.csv", "report.html"):
    assert name in listed, f"{name} not in the manifest"
for path, f in listed.items():
    data = (out / path).read_bytes()
    assert len(data) == f["bytes"] and hashlib.sha256(data).hexdigest() == f["sha256"], path
on_disk = {str(p.relative_to(out)) for p in out.rglob("*") if p.is_file()} - {"manifest.json"}
assert on_disk == set(listed), sorted(on_disk ^ set(listed))
text = (work / "quiet-breathing.yaml").read_text()
duration = float(re.search(r"^duration: ([0-9.]+) s$", text, re.M).group(1))
rate = float(re.search(r"^  rate: ([0-9.]+) Hz$", text, re.M).group(1))
assert manifest["facts"]["frames"] == str(round(duration * rate) + 1), manifest["facts"]["frames"]
assert manifest["scenario"]["name"] == "quiet-breathing", manifest["scenario"]
print("install_test:", len(listed), "files,", manifest["facts"]["frames"], "frames")
PY

if [ "$has_python" = 1 ]; then
  "${clean[@]}" "PYTHONPATH=$python_dir" /usr/bin/python3 - "$prefix" <<'PY' || fail "the installed Python module failed"
import csv, sys
import pneuma
assert pneuma.__file__.startswith(sys.argv[1]), pneuma.__file__
sim = pneuma.simulate("quiet-breathing.yaml")
with open("out/physiology.csv") as f:
    rows = list(csv.DictReader(f))
assert len(rows) == len(sim.time_s), (len(rows), len(sim.time_s))
assert abs(float(rows[-1]["volume_mL"]) - sim.volume_mL[-1]) <= 1e-3 * max(1.0, abs(sim.volume_mL[-1]))
PY
fi

# Without its presets the installed binary fails and names where they belong: it never reads the
# source tree's configs/ compiled into it.
mv "$prefix/share/pneuma/configs" "$tmp/configs-away"
expected="$prefix/share/pneuma/configs/"
set +e
err=$("${clean[@]}" "$prefix/bin/pneuma" run quiet-breathing.yaml -o out2 --quiet 2>&1 >/dev/null)
code=$?
set -e
[ "$code" = 3 ] || fail "without presets: exit $code, expected 3 ($err)"
[[ "$err" == *"$expected"* ]] || fail "without presets: '$err' does not name $expected"
if [ "$has_python" = 1 ]; then
  err=$("${clean[@]}" "PYTHONPATH=$python_dir" /usr/bin/python3 -c 'import pneuma; pneuma.simulate("quiet-breathing.yaml")' 2>&1 || true)
  [[ "$err" == *"$expected"* ]] ||
    fail "Python without presets: '$err' does not name the prefix's presets"
fi
# The build tree's own binary, in the same clean environment, still reads the source tree's presets.
"${clean[@]}" "$build/cli/pneuma" simulate quiet-breathing.yaml -o sim.csv --quiet ||
  fail "the build tree's pneuma does not find the source tree's presets"
echo "install_test: ok"
