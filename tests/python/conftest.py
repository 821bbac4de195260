"""Shared helpers for the Python module's tests: the CLI (the oracle for most numbers), the
source tree, small scenarios and an enclosed-volume computation independent of the engine."""
import os
import pathlib
import subprocess

import numpy as np
import pytest

SOURCE_DIR = pathlib.Path(os.environ.get("PNEUMA_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
PNEUMA_EXE = os.environ.get("PNEUMA_EXE", str(SOURCE_DIR / "build" / "release" / "cli" / "pneuma"))

# 4 s of quiet breathing at 10 frames/s on a 12 mm right-lung phantom (as tests/runner). The
# ratio is quoted: PyYAML (YAML 1.1) would read 1:2 as the base-60 integer 62.
SMALL_SCENARIO = """name: small
duration: 4 s
frames: {rate: 10 Hz}
mesh: {phantom: right, edge: 12 mm, share: 55 %}
field: {tissue: healthy-upright}
physiology:
  preset: healthy-adult
  driver: {mode: spontaneous, rate: 15 /min, ie_ratio: '1:2', tidal_volume: 500 mL}
outputs:
  gltf: false
  motion_csv: false
  hdf5: {positions: float64}
"""


def run_cli(*args):
    """Runs `pneuma ARGS...`; returns (exit code, stdout, stderr)."""
    r = subprocess.run([PNEUMA_EXE, *map(str, args)], capture_output=True, text=True, check=False)
    return r.returncode, r.stdout, r.stderr


def enclosed_volume(positions, triangles):
    """Enclosed volume (m^3) by the divergence theorem: the sum of signed tetrahedra a.(b x c)/6."""
    p = np.asarray(positions, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64)
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def read_csv(path):
    """A CSV with a header row as a dict of columns (floats, or strings where not numeric)."""
    lines = pathlib.Path(path).read_text().splitlines()
    names = lines[0].split(",")
    rows = [line.split(",") for line in lines[1:]]
    out = {}
    for i, name in enumerate(names):
        values = [row[i] for row in rows]
        try:
            out[name] = np.array([float(v) if v != "" else np.nan for v in values])
        except ValueError:
            out[name] = np.array(values)
    return out


@pytest.fixture
def small_scenario(tmp_path):
    path = tmp_path / "small.yaml"
    path.write_text(SMALL_SCENARIO)
    return path
