"""pneuma.Field: frames against volumes computed in numpy, and field files against h5py."""
import h5py
import numpy as np
import pytest

import pneuma
from conftest import enclosed_volume, run_cli


def text(attribute):
    return attribute.decode() if isinstance(attribute, bytes) else str(attribute)


@pytest.fixture(scope="module")
def cli_field(tmp_path_factory):
    """The field of the 12 mm right phantom as `pneuma field` writes it."""
    path = tmp_path_factory.mktemp("field") / "field.h5"
    code, _, err = run_cli("field", "phantom:right", "--edge", "12mm", "--tissue", "healthy-upright", "-o", path,
                           "--quiet")
    assert code == 0, err
    return path


@pytest.fixture(scope="module")
def field():
    return pneuma.Field(pneuma.phantom("right", edge_m=0.012), tissue="healthy-upright")


def test_load_matches_h5py(cli_field):
    f = pneuma.Field.load(cli_field)
    with h5py.File(cli_field, "r") as h5:
        np.testing.assert_array_equal(f.vertices, h5["/rest/positions"][...])
        np.testing.assert_array_equal(f.triangles, h5["/rest/triangles"][...])
        np.testing.assert_array_equal(f.unit_displacement, h5["/field/unit_displacement"][...])
        np.testing.assert_array_equal(f.force, h5["/field/force"][...])
        np.testing.assert_array_equal(f.shear_modulus_pa, h5["/field/shear_modulus_pa"][...])
        assert f.area_unit_m2 == h5["/field"].attrs["area_unit_m2"]
        assert f.metadata["tissue"] == text(h5.attrs["tissue"]) == "healthy-upright"
        assert f.metadata["key"] == text(h5.attrs["key"])
    assert f.vertices.shape == (f.mesh.vertex_count, 3) and f.triangles.dtype == np.uint32


def test_computed_field_is_the_cli_field(field, cli_field):
    # Same mesh, tissue and solver: the same numbers as the file `pneuma field` wrote.
    with h5py.File(cli_field, "r") as h5:
        np.testing.assert_array_equal(field.vertices, h5["/rest/positions"][...])
        np.testing.assert_array_equal(field.unit_displacement, h5["/field/unit_displacement"][...])
        assert field.metadata["key"] == text(h5.attrs["key"])


@pytest.mark.parametrize("volume_mL", [-150.0, 0.0, 100.0, 400.0])
def test_frame_encloses_the_requested_volume(field, volume_mL):
    rest = enclosed_volume(field.vertices, field.triangles)
    assert rest == pytest.approx(field.rest_volume_m3, rel=1e-12)
    positions = field.frame(volume_mL=volume_mL)
    assert positions.shape == field.vertices.shape and positions.dtype == np.float64
    assert enclosed_volume(positions, field.triangles) == pytest.approx(rest + volume_mL * 1e-6, rel=1e-10, abs=1e-15)


def test_frame_at_is_rest_plus_scale_times_u(field):
    np.testing.assert_array_equal(field.frame_at(0.0), field.vertices)
    s = 37.5
    np.testing.assert_allclose(field.frame_at(s), field.vertices + s * field.unit_displacement, rtol=0, atol=1e-15)
    # The volume cubic agrees with the numpy volume of that frame.
    c0, c1, c2, c3 = field.volume_coefficients
    assert c0 + s * (c1 + s * (c2 + s * c3)) == pytest.approx(enclosed_volume(field.frame_at(s), field.triangles),
                                                              rel=1e-12)
    assert field.volume_mL(s) * 1e-6 == pytest.approx(enclosed_volume(field.frame_at(s), field.triangles)
                                                       - field.rest_volume_m3, rel=1e-9)


def test_save_round_trips_through_h5py(field, tmp_path):
    path = tmp_path / "saved.h5"
    field.save(path)
    with h5py.File(path, "r") as h5:
        np.testing.assert_array_equal(h5["/field/unit_displacement"][...], field.unit_displacement)
        np.testing.assert_array_equal(h5["/rest/triangles"][...], field.triangles)
    np.testing.assert_array_equal(pneuma.Field.load(path).frame(volume_mL=100.0), field.frame(volume_mL=100.0))


def test_field_from_arrays_equals_field_from_mesh(field):
    again = pneuma.Field(field.vertices, field.triangles.astype(np.int64), tissue="healthy-upright")
    np.testing.assert_array_equal(again.unit_displacement, field.unit_displacement)


def test_errors(field, tmp_path):
    with pytest.raises(pneuma.ValueError) as e:
        pneuma.Field(field.vertices, np.array([[0, 1, 10**6]]))
    assert str(e.value) == f"triangles: row 0 has vertex index 1000000, expected 0 to {len(field.vertices) - 1}"
    with pytest.raises(pneuma.ValueError) as e:
        pneuma.Field(field.vertices[:, :2], field.triangles)
    assert str(e.value) == f"vertices: expected an array of shape (V, 3), got shape ({len(field.vertices)}, 2)"
    with pytest.raises(pneuma.ValueError) as e:
        pneuma.Field(field.mesh, solver="cg", clique_hops=2)
    assert str(e.value) == "clique_hops: the cg solver takes 1 only, got 2"
    # The rules and words of `pneuma field --tol` and `--clique` (core/include/pneuma/core/parameters.h).
    with pytest.raises(pneuma.ValueError) as e:
        pneuma.Field(field.mesh, tolerance=1e-13)
    assert str(e.value) == "tolerance: expected a tolerance from 1e-12 to below 1, got 1e-13"
    with pytest.raises(pneuma.ValueError) as e:
        pneuma.Field(field.mesh, tolerance=1.0)
    assert str(e.value) == "tolerance: expected a tolerance from 1e-12 to below 1, got 1"
    with pytest.raises(pneuma.ValueError) as e:
        pneuma.Field(field.mesh, solver="shot", clique_hops=5)
    assert str(e.value) == "clique_hops: expected a clique size from 1 to 4 hops, got 5 hops"
    with pytest.raises(pneuma.ValueError) as e:
        pneuma.Field(field.mesh, area_unit_m2=0.0)
    assert str(e.value) == "area_unit_m2: expected an area unit above 0 cm^2, got 0 cm^2"
    with pytest.raises(pneuma.ValueError) as e:
        pneuma.Field(field.mesh, solver="magic")
    assert str(e.value) == "unknown solver 'magic' (expected shot, sweep, direct or cg)"
    not_ours = tmp_path / "other.h5"
    with h5py.File(not_ours, "w") as h5:
        h5["x"] = np.zeros(3)
    with pytest.raises(pneuma.InputError) as e:
        pneuma.Field.load(not_ours)
    assert str(e.value).startswith(f"{not_ours}: not a pneuma field file: ")
    with pytest.raises(pneuma.IoError) as e:
        pneuma.Field.load(tmp_path / "missing.h5")
    assert str(tmp_path / "missing.h5") in str(e.value) and e.value.exit_code == 4
