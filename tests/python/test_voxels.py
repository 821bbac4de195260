"""Voxel outputs from Python (Animation.voxels) against the NIfTI files `pneuma run` (the CLI, a
separate compile) writes: the same displacement fields and warped label map, read back with
nibabel (LPS millimetres in the files, metres here)."""
import nibabel as nib
import numpy as np
import pytest

import pneuma
from conftest import SMALL_SCENARIO, run_cli

VOXELS = SMALL_SCENARIO.replace("  hdf5: {positions: float64}\n",
                                "  hdf5: false\n  voxels: {at: [end_inspiration], spacing: 4 mm}\n")


def test_voxels_are_the_cli_files(tmp_path):
    assert VOXELS != SMALL_SCENARIO
    scenario = tmp_path / "voxels.yaml"
    scenario.write_text(VOXELS)
    code, _, err = run_cli("run", scenario, "-o", tmp_path / "cli", "--quiet")
    assert code == 0, err
    animation = pneuma.Animation(scenario)
    k = int(np.argmax(animation.volume_mL))
    tag = "end_inspiration"  # named as asked in `at`, not by its time
    assert not (tmp_path / "cli" / "voxels" / f"labels-{animation.time_s[k]:.3f}s.nii.gz").exists()
    out = animation.voxels(k)
    folder = tmp_path / "cli" / "voxels"
    for key, name in (("forward_m", "dvf-forward"), ("pullback_m", "dvf-pullback")):
        image = nib.load(folder / f"{name}-{tag}.nii.gz")
        stored = np.asarray(image.dataobj)[:, :, :, 0, :]  # (nx, ny, nz, 1, 3) float32, LPS mm
        assert stored.shape == out[key].shape
        np.testing.assert_allclose(out[key] * 1e3, stored, atol=1e-4)  # float32 in the file
        assert np.abs(out[key]).max() > 5e-3  # the lung moves by millimetres at end-inspiration
    labels = nib.load(folder / f"labels-{tag}.nii.gz")
    np.testing.assert_array_equal(out["labels"], np.asarray(labels.dataobj))
    # The grid: NIfTI's RAS+ affine is diag(-1, -1, 1) times the LPS one, in mm.
    ras = np.diag([-1.0, -1.0, 1.0, 1.0]) @ out["ijk_to_lps"]
    ras[:3, :] *= 1e3
    np.testing.assert_allclose(labels.affine, ras, atol=1e-6)
    # The warped lung, counted by numpy, is its rest volume plus the lung's share of the breath.
    rest = animation.voxels(int(np.argmin(animation.volume_mL)))
    voxel_m3 = abs(np.linalg.det(out["ijk_to_lps"][:3, :3]))
    grown = (np.count_nonzero(out["labels"]) - np.count_nonzero(rest["labels"])) * voxel_m3
    breath = animation.share * (animation.volume_mL[k] - animation.volume_mL.min()) * 1e-6
    assert grown == pytest.approx(breath, rel=0.15)
    assert out["lung_volume_m3"] == pytest.approx(np.count_nonzero(out["labels"]) * voxel_m3)
    assert out["min_jacobian"] > 0 and out["folded_tets"] == 0


def test_voxels_need_the_output(tmp_path):
    scenario = tmp_path / "plain.yaml"
    scenario.write_text(SMALL_SCENARIO)
    with pytest.raises(ValueError, match="outputs: voxels"):
        pneuma.Animation(scenario).voxels(0)


def test_trajectories_follow_the_frames_and_the_cli(tmp_path):
    """Animation.trajectories: a point at a rest vertex follows that vertex in every frame (the
    surface frames, an independent path: Frame/advance), and every point's positions are the CLI's
    voxels/trajectories.csv (4 decimals of a mm)."""
    animation = pneuma.Animation(VOXELS_SCENARIO(tmp_path, None))
    rest = animation.vertices
    k = int(np.argmax(animation.volume_mL))
    vertex = len(rest) // 3
    points = np.array([rest[vertex], rest[:, :].mean(axis=0), rest[vertex] - [0, 0, 0.3]])
    out = animation.trajectories(points)
    assert out["positions_m"].shape == (len(animation), 3, 3)
    assert out["moves_with"][0].endswith("surface"), out["moves_with"]
    assert out["moves_with"][2] == "body"
    for i in (0, k, len(animation) - 1):
        np.testing.assert_allclose(out["positions_m"][i, 0], animation.frame(i)[vertex], atol=1e-9)
    assert np.linalg.norm(out["positions_m"][k, 0] - rest[vertex]) > 1e-3  # it moved millimetres
    csv = tmp_path / "points.csv"
    csv.write_text("name,x_mm,y_mm,z_mm\n" + "".join(
        f"p{i},{p[0] * 1e3:.7f},{p[1] * 1e3:.7f},{p[2] * 1e3:.7f}\n" for i, p in enumerate(points)))
    scenario = VOXELS_SCENARIO(tmp_path, csv)
    code, _, err = run_cli("run", scenario, "-o", tmp_path / "cli", "--quiet")
    assert code == 0, err
    rows = [line.split(",") for line in (tmp_path / "cli/voxels/trajectories.csv").read_text().splitlines()[1:]]
    assert len(rows) == 3 * len(animation)
    for row in rows:
        p, frame = int(row[0][1:]), int(row[2])
        np.testing.assert_allclose([float(v) for v in row[5:8]], out["positions_m"][frame, p] * 1e3, atol=2e-4)


def VOXELS_SCENARIO(tmp_path, points):
    text = VOXELS if points is None else VOXELS.replace("spacing: 4 mm}", f"spacing: 4 mm, points: {points}}}")
    path = tmp_path / ("voxels.yaml" if points is None else "voxels-points.yaml")
    path.write_text(text)
    return path


def test_structures_are_the_cli_files(tmp_path):
    """Animation.structures: a ball mask in the lung (written with nibabel, RAS affine) at the CLI's
    two time points gives, per frame, the warped mask voxel for voxel as the CLI's
    structure-ball-<tag>.nii.gz, the volume and centroid of voxels/structures.csv, the ITV as
    itv-ball.nii.gz and the mid-ventilation and mean of structures-summary.csv; the volume is also
    numpy's count of the mask's voxels."""
    rest = pneuma.Animation(VOXELS_SCENARIO(tmp_path, None)).vertices
    centre = rest.mean(axis=0) * 1e3  # LPS mm
    h, n = 1.5, 24
    lps_origin = centre - h * (n - 1) / 2
    # NIfTI's RAS+ affine of the LPS grid i, j, k along x, y, z.
    affine = np.diag([-h, -h, h, 1.0])
    affine[:3, 3] = [-lps_origin[0], -lps_origin[1], lps_origin[2]]
    ijk = np.indices((n, n, n)).reshape(3, -1).T
    points = lps_origin + h * ijk
    ball = (np.linalg.norm(points - centre, axis=1) <= 15.0).reshape(n, n, n).astype(np.uint8)
    nib.save(nib.Nifti1Image(ball, affine), tmp_path / "ball.nii.gz")
    text = VOXELS.replace("at: [end_inspiration], spacing: 4 mm}",
                          "at: [end_expiration, end_inspiration], spacing: 4 mm, structures: {ball: ball.nii.gz}}")
    assert text != VOXELS
    scenario = tmp_path / "structures.yaml"
    scenario.write_text(text)
    code, _, err = run_cli("run", scenario, "-o", tmp_path / "cli", "--quiet")
    assert code == 0, err
    animation = pneuma.Animation(scenario)
    frames = {"end_expiration": int(np.argmin(animation.volume_mL)),
              "end_inspiration": int(np.argmax(animation.volume_mL))}
    tags = sorted(frames, key=lambda t: frames[t])  # in time order, as the CLI computes them
    out = animation.structures([frames[t] for t in tags])["ball"]
    folder = tmp_path / "cli" / "voxels"
    rows = {r[1]: r for r in (line.split(",") for line in (folder / "structures.csv").read_text().splitlines()[1:])}
    assert set(rows) == set(tags)
    voxel_m3 = 4e-3 ** 3
    for t, tag in enumerate(tags):
        written = np.asarray(nib.load(folder / f"structure-ball-{tag}.nii.gz").dataobj) != 0
        assert out["masks"][t].shape == written.shape
        np.testing.assert_array_equal(out["masks"][t], written)
        assert out["volume_m3"][t] == pytest.approx(np.count_nonzero(out["masks"][t]) * voxel_m3, rel=1e-9)
        assert out["volume_m3"][t] * 1e6 == pytest.approx(float(rows[tag][2]), rel=1e-5)
        np.testing.assert_allclose(out["centroid_m"][t] * 1e3, [float(v) for v in rows[tag][3:6]], atol=1e-4)
        assert float(rows[tag][6]) == out["weights"][t] == 1.0
    assert np.count_nonzero(out["masks"][0]) > 100  # the ball: (30 mm)^3 pi / 6 on 4 mm voxels
    assert not np.array_equal(out["masks"][0], out["masks"][1])  # it moved
    itv = np.asarray(nib.load(folder / "itv-ball.nii.gz").dataobj) != 0
    np.testing.assert_array_equal(out["itv"], itv)
    np.testing.assert_array_equal(out["itv"], out["masks"].any(axis=0))
    summary = (folder / "structures-summary.csv").read_text().splitlines()[1].split(",")
    assert summary[0] == "ball"
    assert out["itv_volume_m3"] * 1e6 == pytest.approx(float(summary[1]), rel=1e-5)
    assert tags[out["midventilation"]] == summary[2]
    np.testing.assert_allclose(out["midventilation_m"] * 1e3, [float(v) for v in summary[3:6]], atol=1e-4)
    np.testing.assert_allclose(out["mean_m"] * 1e3, [float(v) for v in summary[6:9]], atol=1e-4)
    with pytest.raises(ValueError, match="weights"):
        animation.structures([0, 1], weights=[1.0])
