"""pneuma.simulate and load_scenario against the CLI's physiology CSV for the same scenario."""
import numpy as np
import pytest
import yaml

import pneuma
from conftest import SOURCE_DIR, read_csv, run_cli

QUIET = SOURCE_DIR / "scenarios" / "quiet-breathing.yaml"
VENTILATED = SOURCE_DIR / "scenarios" / "ventilated-patient.yaml"


def cli_csv(scenario, tmp_path):
    csv = tmp_path / "p.csv"
    code, _, err = run_cli("simulate", scenario, "-o", csv, "--quiet")
    assert code == 0, err
    return read_csv(csv), read_csv(tmp_path / "p-breaths.csv")


def assert_matches_csv(sim, series, breaths):
    # The CSV holds 9 significant digits (time: 6 decimals).
    assert list(sim.columns) == list(series)
    np.testing.assert_allclose(sim.time_s, series["time_s"], rtol=0, atol=5e-7)
    for name, values in series.items():
        if name == "time_s":
            continue
        scale = np.abs(values).max()
        np.testing.assert_allclose(sim.columns[name], values, rtol=1e-8, atol=1e-8 * scale, err_msg=name)
    assert list(sim.breaths) == list(breaths)
    for name, values in breaths.items():
        if sim.breaths[name].dtype.kind == "U":
            # A text column whose every cell is empty (no trigger in spontaneous breaths) reads as NaN.
            expected = list(values) if values.dtype.kind == "U" else ["" if np.isnan(v) else v for v in values]
            assert list(sim.breaths[name]) == expected, name
        else:
            np.testing.assert_allclose(sim.breaths[name], values, rtol=1e-8, atol=1e-6, equal_nan=True, err_msg=name)


@pytest.mark.parametrize("scenario", [QUIET, VENTILATED], ids=["quiet", "ventilated"])
def test_simulate_matches_cli_csv(scenario, tmp_path):
    series, breaths = cli_csv(scenario, tmp_path)
    sim = pneuma.simulate(str(scenario))
    assert len(sim) == len(series["time_s"])
    assert_matches_csv(sim, series, breaths)
    # The named attributes are the columns.
    np.testing.assert_array_equal(sim.volume_mL, sim.columns["volume_mL"])
    assert sim.flow_L_per_s.dtype == np.float64 and sim.flow_L_per_s.shape == (len(sim),)


def test_dict_scenario_matches_the_yaml_file(tmp_path):
    series, breaths = cli_csv(QUIET, tmp_path)
    as_dict = yaml.safe_load(QUIET.read_text())
    sim = pneuma.simulate(as_dict)
    assert_matches_csv(sim, series, breaths)
    scenario = pneuma.load_scenario(as_dict)
    assert scenario.file == "<dict>" and scenario.name == "quiet-breathing"
    assert scenario.duration_s == 60.0 and scenario.frame_rate_hz == 30.0 and scenario.output_rate_hz == 100.0


def test_output_rate_resamples_the_same_solution(tmp_path):
    # At 10 Hz the samples are every tenth of the 100 Hz ones (CVODE integrates the same way).
    series, _ = cli_csv(QUIET, tmp_path)
    sim = pneuma.simulate(pneuma.load_scenario(QUIET), output_rate_hz=10.0)
    np.testing.assert_allclose(sim.time_s, series["time_s"][::10], atol=5e-7)
    np.testing.assert_allclose(sim.volume_mL, series["volume_mL"][::10], rtol=1e-6, atol=1e-6)


def test_numbers_without_units_name_the_key_and_the_unit():
    with pytest.raises(pneuma.InputError) as e:
        pneuma.simulate({"duration": "10 s", "physiology": {"preset": "healthy-adult", "compliance": 0.1}})
    assert str(e.value) == "<dict>: physiology.compliance: expected a compliance such as '0.1 L/cmH2O', got '0.1'"
    assert e.value.exit_code == 3
    assert isinstance(e.value, pneuma.Error)


def test_unknown_dict_key_lists_the_known_ones():
    with pytest.raises(pneuma.InputError) as e:
        pneuma.load_scenario({"duration": "4 s", "mesh": {"phantom": "right", "egde": "4 mm"},
                              "physiology": {"preset": "healthy-adult"}})
    assert str(e.value) == ("<dict>: mesh.egde: unknown key; expected one of: breath, edge, file, labels, lungs, "
                            "phantom, reference_volume, share")


def test_a_bad_file_gives_the_cli_message(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("duration: 4 s\nframes: {rate: 30 mL}\nphysiology: {preset: healthy-adult}\n")
    code, _, err = run_cli("simulate", bad, "-o", tmp_path / "p.csv")
    assert code == 3
    with pytest.raises(pneuma.InputError) as e:
        pneuma.simulate(bad)  # a pathlib.Path
    assert str(e.value) + "\n" == err
    assert str(e.value).startswith(f"{bad}:2:")
    assert e.value.exit_code == code


def test_wrong_types_raise():
    with pytest.raises(TypeError):
        pneuma.simulate(42)
    with pytest.raises(pneuma.ValueError) as e:
        pneuma.load_scenario({"duration": "4 s", "physiology": {"preset": object()}})
    assert str(e.value) == "<dict>: physiology.preset: expected a number, string, bool, list or dict, got object"
    assert isinstance(e.value, ValueError)  # also the builtin
