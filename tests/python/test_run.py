"""pneuma.run and pneuma.Animation against the files the run writes (h5py, json, csv)."""
import json

import h5py
import numpy as np
import pytest

import pneuma
from conftest import enclosed_volume, read_csv


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    scenario = out / "small.yaml"
    from conftest import SMALL_SCENARIO
    scenario.write_text(SMALL_SCENARIO)
    result = pneuma.run(scenario, out / "out")
    return scenario, out / "out", result


def test_run_result_matches_the_manifest(run_dir):
    scenario, out, result = run_dir
    manifest = json.loads((out / "manifest.json").read_text())
    assert result.files[-1] == "manifest.json"
    for f in result.files:
        assert (out / f).is_file(), f
    assert "field.h5" in result.files and "series.h5" in result.files
    assert result.frame_count == 41  # 4 s at 10 Hz, both ends
    facts = json.dumps(manifest)
    assert str(result.vertex_count) in facts
    assert not result.field_reused
    assert list(result.timings_s)[0] == "physiology"
    with h5py.File(out / "series.h5", "r") as h5:
        scales = h5["/frames/scale"][...]
    assert len(scales) == result.frame_count
    assert result.min_scale == scales.min() and result.max_scale == scales.max()


def test_run_physiology_csv_is_simulate(run_dir):
    scenario, out, _ = run_dir
    csv = read_csv(out / "physiology.csv")
    sim = pneuma.simulate(scenario)
    np.testing.assert_allclose(sim.volume_mL, csv["volume_mL"], rtol=1e-8, atol=1e-8 * np.abs(csv["volume_mL"]).max())


def test_animation_frames_are_the_run_frames(run_dir):
    scenario, out, _ = run_dir
    animation = pneuma.Animation(scenario, out)  # reuses the run's field.h5
    assert animation.field_reused and len(animation) == 41
    with h5py.File(out / "series.h5", "r") as h5:
        np.testing.assert_array_equal(animation.vertices, h5["/rest/positions"][...])
        np.testing.assert_array_equal(animation.time_s, h5["/frames/time_s"][...])
        np.testing.assert_array_equal(animation.scales, h5["/frames/scale"][...])
        for k in (0, 7, 40):
            np.testing.assert_array_equal(animation.frame(k), h5[f"/frames/positions/{k:06d}"][...])
        mesh_volume = h5["/frames/mesh_volume_m3"][...]
    # The frame encloses rest + share * (V - reference), by numpy's own volume.
    k = int(np.argmax(animation.scales))
    target = animation.rest_volume_m3 + animation.share * (animation.volume_mL[k] - animation.reference_volume_mL) * 1e-6
    assert enclosed_volume(animation.frame(k), animation.triangles) == pytest.approx(target, rel=1e-10)
    assert mesh_volume[k] == pytest.approx(target, rel=1e-10)
    np.testing.assert_array_equal(animation.frame_at_time(0.71), animation.frame(7))
    assert animation.index_at_time(0.75) in (7, 8) and animation.index_at_time(4.0) == 40
    with pytest.raises(pneuma.ValueError):
        animation.frame_at_time(5.0)
    with pytest.raises(pneuma.ValueError):
        animation.frame(41)


def test_the_cli_and_the_module_compile_the_same_frames(tmp_path):
    # `pneuma run` (the CLI) and pneuma.Animation each compile the scenario on their own (no
    # shared cache: the CLI's is in its folder, the Animation has none) through the same
    # model::compile: every frame must be the same bits.
    from conftest import SMALL_SCENARIO, run_cli
    scenario = tmp_path / "small.yaml"
    scenario.write_text(SMALL_SCENARIO)
    code, _, err = run_cli("run", scenario, "-o", tmp_path / "cli", "--quiet")
    assert code == 0, err
    animation = pneuma.Animation(scenario)
    assert not animation.field_reused
    with h5py.File(tmp_path / "cli" / "series.h5", "r") as h5:
        assert h5["/frames/scale"].shape[0] == len(animation) == 41
        np.testing.assert_array_equal(animation.vertices, h5["/rest/positions"][...])
        np.testing.assert_array_equal(animation.scales, h5["/frames/scale"][...])
        for k in range(len(animation)):
            np.testing.assert_array_equal(animation.frame(k), h5[f"/frames/positions/{k:06d}"][...])


def test_animation_without_output_dir_caches_nothing(tmp_path, monkeypatch):
    from conftest import SMALL_SCENARIO
    import yaml
    monkeypatch.chdir(tmp_path)
    animation = pneuma.Animation(yaml.safe_load(SMALL_SCENARIO), edge_m=0.015)
    assert not animation.field_reused and len(animation) == 41
    assert list(tmp_path.iterdir()) == []


def test_run_errors_are_the_cli_line(tmp_path):
    from conftest import SMALL_SCENARIO, run_cli
    (tmp_path / "broken.stl").write_text("solid broken\nfacet normal 0 0 1\nendsolid\n")
    scenario = tmp_path / "broken.yaml"
    scenario.write_text(SMALL_SCENARIO.replace("mesh: {phantom: right, edge: 12 mm, share: 55 %}",
                                               "mesh: {file: broken.stl, unit: mm, edge: 12 mm, share: 55 %}"))
    code, _, err = run_cli("run", scenario, "-o", tmp_path / "cli", "--quiet")
    with pytest.raises(pneuma.InputError) as e:
        pneuma.run(scenario, tmp_path / "py")
    assert str(e.value) + "\n" == err and e.value.exit_code == code == 3
    assert str(e.value).startswith(f"{tmp_path / 'broken.stl'}: ")
    # Nothing of the failed run is left in its output folder (the stage is removed).
    assert list((tmp_path / "py").iterdir()) == []


def test_a_dict_run_records_its_yaml(tmp_path):
    import hashlib
    from conftest import SMALL_SCENARIO
    import yaml
    as_dict = yaml.safe_load(SMALL_SCENARIO)
    scenario = pneuma.load_scenario(as_dict)
    result = pneuma.run(scenario, tmp_path / "out", edge_m=0.015)
    written = tmp_path / "out" / "scenario.yaml"
    assert written.read_text() == scenario.yaml
    # The file is the same scenario for pneuma itself (PyYAML would misread 1:2, a YAML 1.1 integer).
    again = pneuma.load_scenario(written)
    assert (again.name, again.duration_s, again.frame_rate_hz) == ("small", 4.0, 10.0)
    np.testing.assert_array_equal(pneuma.simulate(written).volume_mL, pneuma.simulate(as_dict).volume_mL)
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert manifest["scenario"]["file"] == str(written)
    assert manifest["scenario"]["sha256"] == hashlib.sha256(written.read_bytes()).hexdigest()
    assert result.frame_count == 41


def test_a_scenario_without_mesh_uses_the_default_phantom():
    # No `mesh` section: the right phantom at 4 mm with its 55 % share, as `mesh: {phantom: right}`.
    bare = pneuma.Animation({"duration": "1 s", "frames": {"rate": "4 Hz"}, "physiology": {"preset": "healthy-adult"}})
    explicit = pneuma.Animation({"duration": "1 s", "frames": {"rate": "4 Hz"}, "mesh": {"phantom": "right"},
                                 "physiology": {"preset": "healthy-adult"}})
    np.testing.assert_array_equal(bare.vertices, explicit.vertices)
    np.testing.assert_array_equal(bare.frame(4), explicit.frame(4))
    assert bare.share == explicit.share == 0.55
