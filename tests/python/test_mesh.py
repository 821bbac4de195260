"""pneuma.load_mesh and pneuma.phantom against the CLI's files and numpy measures."""
import numpy as np
import pytest

import pneuma
from conftest import enclosed_volume, run_cli


def test_load_mesh_reads_the_cli_phantom(tmp_path):
    ply = tmp_path / "lung.ply"
    code, _, err = run_cli("phantom", "--lung", "left", "--edge", "10mm", "-o", ply)
    assert code == 0, err
    mesh = pneuma.load_mesh(ply)
    direct = pneuma.phantom("left", edge_m=0.010)
    assert mesh.vertex_count == direct.vertex_count and mesh.triangle_count == direct.triangle_count
    # The file records its unit (mm): read back in metres, to the file's float precision.
    np.testing.assert_allclose(mesh.vertices, direct.vertices, rtol=0, atol=1e-7)
    np.testing.assert_array_equal(mesh.triangles, direct.triangles)
    assert mesh.volume_m3 == pytest.approx(enclosed_volume(mesh.vertices, mesh.triangles), rel=1e-12)
    # Adult left lung at FRC: between 1 and 2 litres.
    assert 1e-3 < mesh.volume_m3 < 2e-3


def test_unit_overrides_the_recorded_one(tmp_path):
    ply = tmp_path / "lung.ply"
    assert run_cli("phantom", "--lung", "right", "--edge", "12mm", "-o", ply)[0] == 0
    in_mm = pneuma.load_mesh(ply)
    in_cm = pneuma.load_mesh(ply, unit="cm")  # the same numbers read as centimetres: 10x larger
    np.testing.assert_allclose(in_cm.vertices, 10.0 * in_mm.vertices, rtol=1e-12)


def test_mesh_from_arrays_measures_a_cube():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    t = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                  [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    cube = pneuma.Mesh(v * 0.1, t)
    assert cube.volume_m3 == pytest.approx(1e-3, rel=1e-12)
    assert cube.area_m2 == pytest.approx(0.06, rel=1e-12)


def test_bad_file_gives_the_cli_message(tmp_path):
    bad = tmp_path / "broken.stl"
    bad.write_bytes(b"\x00" * 80 + b"\xff\xff\x00\x00" + b"\x01" * 20)  # claims 65535 triangles
    code, _, err = run_cli("mesh", "info", bad)
    with pytest.raises(pneuma.InputError) as e:
        pneuma.load_mesh(bad)
    assert str(e.value).startswith(f"{bad}: ")
    assert str(e.value) + "\n" == err and e.value.exit_code == code == 3


def test_missing_file_is_an_io_error(tmp_path):
    with pytest.raises(pneuma.IoError) as e:
        pneuma.load_mesh(tmp_path / "nowhere.stl")
    assert str(tmp_path / "nowhere.stl") in str(e.value)
    with pytest.raises(pneuma.ValueError):
        pneuma.phantom("middle")


def test_an_edge_below_a_tenth_of_a_millimetre_is_refused_in_the_words_of_the_cli(tmp_path):
    with pytest.raises(pneuma.ValueError) as e:
        pneuma.phantom("right", edge_m=5e-5)
    assert str(e.value) == "edge_m: expected an edge of at least 0.1 mm, got 0.05 mm"
    code, out, err = run_cli("phantom", "--lung", "right", "--edge", "0.05mm", "-o", tmp_path / "p.ply")
    assert (code, out) == (2, "")
    assert err == "pneuma: --edge: expected an edge of at least 0.1 mm, got 0.05 mm\n"
