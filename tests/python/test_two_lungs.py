"""Two lungs (`phantom: both`) through pneuma.Animation against the files `pneuma run` (the CLI,
a separate compile) writes: every frame of each lung bit for bit, and each lung's volume."""
import h5py
import numpy as np
import pytest

import pneuma
from conftest import SMALL_SCENARIO, enclosed_volume, run_cli

BOTH = SMALL_SCENARIO.replace("mesh: {phantom: right, edge: 12 mm, share: 55 %}", "mesh: {phantom: both, edge: 12 mm}")


def test_two_lung_frames_are_the_cli_frames_bit_for_bit(tmp_path):
    assert BOTH != SMALL_SCENARIO
    scenario = tmp_path / "both.yaml"
    scenario.write_text(BOTH)
    code, _, err = run_cli("run", scenario, "-o", tmp_path / "cli", "--quiet")
    assert code == 0, err
    animation = pneuma.Animation(scenario)  # its own compile, no cache
    assert not animation.field_reused and len(animation) == 41
    assert animation.lungs == ["right", "left"]
    assert set(animation.vertices) == {"right", "left"}
    assert animation.share == {"right": pytest.approx(0.55), "left": pytest.approx(0.45)}
    with h5py.File(tmp_path / "cli" / "series.h5", "r") as h5:
        assert h5.attrs["lungs"] in ("right,left", b"right,left")
        for k in (0, 9, 40):
            frame = animation.frame(k)
            for lung in ("right", "left"):
                np.testing.assert_array_equal(frame[lung], h5[f"/{lung}/frames/positions/{k:06d}"][...])
        for lung in ("right", "left"):
            np.testing.assert_array_equal(animation.scales[lung], h5[f"/{lung}/frames/scale"][...])
            np.testing.assert_array_equal(animation.triangles[lung], h5[f"/{lung}/rest/triangles"][...])
    # Each lung encloses rest + share * V, by numpy's own volume.
    k = int(np.argmax(animation.volume_mL))
    frame = animation.frame(k)
    for lung in ("right", "left"):
        target = animation.rest_volume_m3[lung] + animation.share[lung] * animation.volume_mL[k] * 1e-6
        assert enclosed_volume(frame[lung], animation.triangles[lung]) == pytest.approx(target, rel=1e-10)


def test_xdmf_shows_both_lungs_at_every_step(tmp_path):
    scenario = tmp_path / "both.yaml"
    scenario.write_text(BOTH.replace("duration: 4 s", "duration: 1 s"))
    code, _, err = run_cli("run", scenario, "-o", tmp_path / "out", "--quiet")
    assert code == 0, err
    import xml.etree.ElementTree as ET
    root = ET.parse(tmp_path / "out" / "series.xdmf").getroot()
    steps = root.find("Domain").find("Grid").findall("Grid")
    assert len(steps) == 11
    with h5py.File(tmp_path / "out" / "series.h5", "r") as h5:
        for step in steps:
            assert step.get("CollectionType") == "Spatial"
            names = [g.get("Name") for g in step.findall("Grid")]
            assert names == ["right", "left"]
            for grid in step.findall("Grid"):
                item = grid.find("Geometry").find("DataItem").text
                path = item.split(":", 1)[1]
                assert h5[path].shape == (int(grid.find("Geometry").find("DataItem").get("Dimensions").split()[0]), 3)
    # Each lung alone, for meshio (it reads no nested collections): every step that lung's frame.
    meshio = pytest.importorskip("meshio")
    with h5py.File(tmp_path / "out" / "series.h5", "r") as h5:
        for lung in ("right", "left"):
            with meshio.xdmf.TimeSeriesReader(tmp_path / "out" / f"series-{lung}.xdmf") as reader:
                points, cells = reader.read_points_cells()
                np.testing.assert_array_equal(cells[0].data, h5[f"/{lung}/rest/triangles"][...])
                assert reader.num_steps == 11
                for k in (0, 10):
                    t, point_data, _ = reader.read_data(k)
                    assert t == pytest.approx(0.1 * k)
                    np.testing.assert_array_equal(point_data["position"], h5[f"/{lung}/frames/positions/{k:06d}"][...])
