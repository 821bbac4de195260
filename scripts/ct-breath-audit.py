#!/usr/bin/python3
"""Every check of #45 on the shared CT lungs, measured on the files a run writes.

    nice scripts/ct-breath-audit.py [--pneuma build/release/cli/pneuma] [--cases case004,...|phantom]
        [--tissue healthy-supine,healthy-upright] [--breath end_expiration,end_inspiration]
        [--spacing 4] [--interior 'poisson_ratio: 0.45'] [--keep DIR] [--json FILE]

For each case x tissue x breath (the scan's place on the breath, `mesh.breath`) it writes a
synthetic CT (lung -849.5 HU where the label map's nearest voxel is a lobe, 40 HU elsewhere, on
the label map's extent at 4 mm, as tests/runner/ct_breath_test.cpp makes it), runs `pneuma run`
at the test's settings (5 mm surfaces, 6 mm tets, 4 mm voxels, healthy-adult's 500 mL breath,
voxels at end_expiration, 1 s and end_inspiration) and measures, with nibabel, numpy and scipy on
the written files (each file's own affine; none of pneuma's arithmetic). `--spacing` sets the
voxels' (and the CT's) spacing in mm instead of 4, `--tets` and `--surfaces` the tets' and the
surfaces' edge instead of 6 and 5 mm; `--where` adds, per lung, where the torn voxels and the
neighbour pairs lie (torn_where: distance to the pleura, the vertical line through the lung and the
stretch the surface field alone imposes on it, the rest tets' nodes on the surface).

The case `phantom` is the built-in pair of phantom lungs (`mesh: {phantom: both}`) at the same
settings. It has no label map: its CT is made from the label map pneuma writes at the scan (a
run without a CT, its `labels-end_expiration` on the run's grid, a box around the lungs: the
rest tetrahedra as labels, right 1, left 2), lung -849.5 HU where that map is a lung and 40 HU
elsewhere, on that grid (as `VoxelsRun.TheWarpedCtsLungKeepsItsMass` makes the right lung's).

- interior: the inspiration's Jacobian 6 mm inside the scan's lungs, by finite differences of the
  forward DVF and as the written Jacobian image: the share below 0.95 and the smallest. With the
  scan at end-expiration the forward map to end-inspiration is the inspiration; with the scan at
  end-inspiration the forward map goes to end-expiration and the inspiration's Jacobian at a
  voxel is its inverse, 1 / J.
- the DIR-Lab profile: per lung, the mean |forward DVF| over the scan's lung voxels by fifth of
  the lung's height, relative to the lowest fifth, against 0.21 / 0.36 / 0.56 / 0.80 (Castillo
  et al. 2009), the largest offset (supine only: DIR-Lab's 4D-CTs are supine).
- no tear: at each time point off the scan, outside a 2-voxel band at the pleura of the warped
  label map (and off the grid's faces), the pull-back DVF's Jacobian: voxels outside [0.5, 2] in
  the body (outside the lungs) and the share of each lung's voxels; neighbours whose
  displacements differ by more than a voxel.
- mass: at each time point off the scan, per lung and for both, the sum of (HU + 1000) over the
  lung voxels showing parenchyma (-1000 to -500 HU) against the scan's that stays in view; the
  mean lung HU at the breath's other end against the mass-preserving prediction.
- the surface: per lung, the mediastinum's mean motion and the diaphragm's mean caudal motion
  over the breath (series.h5; the realism criteria of docs/realism.md: <= 1 mm, >= 8 mm).
- the reference: the lungs' volume (warped label voxels) at the breath's other end against the
  scan's plus or minus 500 mL.

One line per run is printed as it finishes (JSON with every number); `--json` collects them,
`--table FILE` prints the markdown table of docs/voxels.md from them.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import nibabel as nib
import numpy as np
from scipy import ndimage

ROOT = Path(__file__).resolve().parent.parent
CT_LOBES = Path(os.environ.get("PNEUMA_CT_LOBES", ROOT.parent / "shared" / "data" / "ct-lobes"))
CASES = ["case004", "case005", "case006", "case007", "case008", "case009"]
BREATH_ML = 500.0
DIRLAB = np.array([0.21, 0.36, 0.56, 0.80])
LOBES = {"right": [3, 4, 5], "left": [1, 2]}  # the shared lobe maps'
PHANTOM = {"right": [1], "left": [2]}  # the phantom's rest label map: lung i + 1, right then left
TAGS = ["end_expiration", "1.000s", "end_inspiration"]


def lungs_of(case):
    return PHANTOM if case == "phantom" else LOBES


def synthetic_ct(labels_file, out, spacing_mm):
    """The test's CT: the label map's extent at spacing_mm, lung where the nearest label voxel is a lobe."""
    src = nib.load(str(labels_file))
    labels = np.asarray(src.dataobj).squeeze()
    a = src.affine
    spacing = np.linalg.norm(a[:3, :3], axis=0)
    axes = a[:3, :3] / spacing
    corner = a[:3, :3] @ np.full(3, -0.5) + a[:3, 3]
    size = np.maximum(1, np.ceil(np.array(labels.shape[:3]) * spacing / spacing_mm - 1e-9)).astype(int)
    affine = np.eye(4)
    affine[:3, :3] = axes * spacing_mm
    affine[:3, 3] = corner + axes @ np.full(3, 0.5 * spacing_mm)
    ijk = np.indices(size).reshape(3, -1)
    centres = affine[:3, :3] @ ijk + affine[:3, 3:4]
    # The nearest voxel as pneuma and the test take it (floor(q + 0.5), not numpy's half to even: at 2 mm
    # every centre of case004's 1 mm slices lies half-way, and rint took the slice below pneuma's).
    q = np.floor(np.linalg.inv(a)[:3, :3] @ centres + np.linalg.inv(a)[:3, 3:4] + 0.5).astype(int)
    inside = np.all((q >= 0) & (q < np.array(labels.shape[:3])[:, None]), axis=0)
    label = np.zeros(q.shape[1], dtype=labels.dtype)
    label[inside] = labels[q[0, inside], q[1, inside], q[2, inside]]
    write_ct(np.where((label >= 1) & (label <= 5), -849.5, 40.0).reshape(size), affine, out)


def write_ct(ct, affine, out):
    img = nib.Nifti1Image(ct.astype(np.float32), affine)
    img.set_qform(affine, code=1)
    img.set_sform(affine, code=1)
    nib.save(img, str(out))


def phantom_ct(pneuma, spacing_mm, work):
    """The phantom's CT: lung where pneuma's label map at the scan (its rest tetrahedra on the
    run's grid) is a lung, 40 HU elsewhere, on that grid. The grid and the rest lungs do not
    depend on the tissue or on the scan's place on the breath, so one CT serves every run."""
    probe = work / "probe.yaml"
    probe.write_text(
        "duration: 8 s\nframes: {rate: 5 Hz}\nmesh: {phantom: both, edge: 5 mm}\n"
        "field: {tissue: healthy-supine, interior: {edge: 6 mm}}\nphysiology: {preset: healthy-adult}\n"
        "outputs: {gltf: false, report: false, hdf5: false, physiology_csv: false,\n"
        f"  voxels: {{at: [end_expiration], spacing: {spacing_mm:g} mm}}}}\n")
    p = subprocess.run([str(pneuma), "run", str(probe), "-o", str(work / "probe"), "--quiet"], capture_output=True,
                       text=True)
    if p.returncode != 0:
        raise SystemExit(f"{probe}: the run for the phantom's label map failed: {p.stderr.strip()}")
    img = nib.load(str(work / "probe" / "voxels" / "labels-end_expiration.nii.gz"))
    labels = np.asarray(img.dataobj).squeeze()
    write_ct(np.where(labels > 0, -849.5, 40.0), img.affine, work / "ct.nii.gz")


def load(d, name):
    img = nib.load(f"{d}/{name}.nii.gz")
    return img, np.asarray(img.dataobj).squeeze().astype(np.float64)


def to_lps(img):
    """The index -> LPS matrix of a file (ITK's DVFs are LPS displacements)."""
    return np.diag([-1.0, -1.0, 1.0]) @ img.affine[:3, :3]


def jacobian(img, v):
    g = np.stack([np.stack(np.gradient(v[..., c]), -1) for c in range(3)], -2)  # d v_c / d index_a
    return np.linalg.det(np.eye(3) + g @ np.linalg.inv(to_lps(img)))


def in_view(img, u):
    q = np.indices(u.shape[:3]).transpose(1, 2, 3, 0) + u @ np.linalg.inv(to_lps(img)).T
    return np.all((q >= -0.5) & (q <= np.array(u.shape[:3]) - 0.5), axis=-1)


def lung_mask(labels, side, lungs):
    return labels > 0 if side == "both" else np.isin(labels, lungs[side])


def measure(d, input_ct, reference, lungs):
    other = "end_inspiration" if reference == "end_expiration" else "end_expiration"
    rimg, rest_labels = load(d, f"labels-{reference}")
    spacing = np.array(rimg.header.get_zooms()[:3], dtype=float)
    voxel_ml = float(np.prod(spacing)) * 1e-3
    _, ct_rest = load(d, f"ct-{reference}")
    r = {}
    # Interior, on the scan's lungs 6 mm inside.
    rest = rest_labels > 0
    deep = ndimage.distance_transform_edt(rest, sampling=spacing) > 6.0
    deep[[0, -1], :, :] = deep[:, [0, -1], :] = deep[:, :, [0, -1]] = False
    fimg, forward = load(d, f"dvf-forward-{other}")
    _, jimage = load(d, f"jacobian-{other}")
    jf, ji = jacobian(fimg, forward)[deep], jimage[deep]
    if reference == "end_inspiration":  # the inspiration is the inverse of the map to end-expiration
        jf, ji = 1.0 / jf, 1.0 / ji
    r["deep_voxels"] = int(deep.sum())
    r["deep_below_095"] = float((jf < 0.95).mean())
    r["deep_min_j"] = float(jf.min())
    r["deep_max_j"] = float(jf.max())
    r["image_below_095"] = float((ji < 0.95).mean())
    r["image_min_j"] = float(ji.min())
    # The DIR-Lab profile per lung: |forward| over the scan's lung voxels by height fifth.
    z = (rimg.affine[:3, :3] @ np.indices(rest.shape).reshape(3, -1) + rimg.affine[:3, 3:4])[2].reshape(rest.shape)
    magnitude = np.linalg.norm(forward, axis=-1)
    r["profile"] = {}
    for side in lungs:
        m = lung_mask(rest_labels, side, lungs)
        h = (z[m] - z[m].min()) / (z[m].max() - z[m].min())
        fifth = np.clip(((1.0 - h) * 5.0).astype(int), 0, 4)
        mean = np.array([magnitude[m][fifth == f].mean() for f in range(5)])
        r["profile"][side] = [float(x) for x in mean / mean[4]] + [float(mean[4])]
    r["profile_offset"] = float(max(np.abs(np.array(p[:4]) - DIRLAB).max() for p in r["profile"].values()))
    # No tear and mass at each time point off the scan.
    r["tear"], r["mass"] = {}, {}
    for tag in TAGS:
        if tag == reference:
            continue
        _, labels = load(d, f"labels-{tag}")
        pimg, pullback = load(d, f"dvf-pullback-{tag}")
        lung = labels > 0
        ok = ~(ndimage.binary_dilation(lung, iterations=2) & ~ndimage.binary_erosion(lung, iterations=2))
        ok[[0, -1], :, :] = ok[:, [0, -1], :] = ok[:, :, [0, -1]] = False
        jp = jacobian(pimg, pullback)
        torn = ok & ((jp < 0.5) | (jp > 2.0))
        voxel = spacing.min()
        pairs, widest = 0, 0.0
        for a in range(3):
            lo = [slice(None)] * 3
            hi = [slice(None)] * 3
            lo[a], hi[a] = slice(0, -1), slice(1, None)
            both = ok[tuple(lo)] & ok[tuple(hi)]
            apart = np.linalg.norm(pullback[tuple(lo)] - pullback[tuple(hi)], axis=-1)[both]
            pairs += int((apart > voxel).sum())
            widest = max(widest, float(apart.max()))
        t = {"body_torn": int((torn & ~lung).sum()), "pull_min": float(jp[ok].min()), "pull_max": float(jp[ok].max()),
             "pairs": pairs, "widest_mm": widest}
        for side in lungs:
            m = lung_mask(labels, side, lungs) & ok
            t[f"{side}_torn"] = int((torn & m).sum())
            t[f"{side}_torn_share"] = float((torn & m).sum() / m.sum())
        t["lung_torn_share"] = float((torn & lung).sum() / (ok & lung).sum())
        r["tear"][tag] = t
        view = in_view(*load(d, f"dvf-forward-{tag}"))
        _, ct = load(d, f"ct-{tag}")
        parenchyma, rest_parenchyma = (ct >= -1000.0) & (ct < -500.0), (ct_rest >= -1000.0) & (ct_rest < -500.0)
        mass = {}
        for side in ("both", "right", "left"):
            now = lung_mask(labels, side, lungs)
            then = lung_mask(rest_labels, side, lungs) & view
            ratio = float(((ct + 1000.0) * (parenchyma & now)).sum() / ((ct_rest + 1000.0) * (rest_parenchyma & then)).sum())
            rest_mean = float(ct_rest[then & rest_parenchyma].mean())
            mean = float(ct[now & parenchyma].mean())
            predicted = -1000.0 + (rest_mean + 1000.0) * then.sum() / now.sum()
            mass[side] = {"ratio": ratio, "mean_hu": mean, "predicted_hu": float(predicted),
                          "volume_ml": float(now.sum() * voxel_ml)}
        r["mass"][tag] = mass
    r["worst_mass"] = max((m["ratio"] for t in r["mass"].values() for m in t.values()), key=lambda x: abs(x - 1.0))
    r["hu_offset"] = max((m["mean_hu"] - m["predicted_hu"] for m in r["mass"][other].values()), key=abs)
    r["worst_tear"] = {k: max(t[k] for t in r["tear"].values())
                       for k in ("body_torn", "pairs", "lung_torn_share", "right_torn", "left_torn", "pull_max")}
    r["worst_tear"]["pull_min"] = min(t["pull_min"] for t in r["tear"].values())
    # The reference: the other end's volume against the scan's -/+ the breath.
    scan_ml = float(rest.sum() * voxel_ml)
    other_ml = r["mass"][other]["both"]["volume_ml"]
    expected = scan_ml - BREATH_ML if reference == "end_inspiration" else scan_ml + BREATH_ML
    r["scan_ml"], r["other_ml"], r["volume_error"] = scan_ml, other_ml, other_ml / expected - 1.0
    r["rest_changed"] = int((np.abs(ct_rest - np.asarray(nib.load(str(input_ct)).dataobj).squeeze()) > 0.01).sum())
    r["smallest_image_j"] = min(float(load(d, f"jacobian-{t}")[1].min()) for t in TAGS)
    return r


def surface_motion(series):
    """Per lung, the surface's motion over the breath (the run's smallest to largest scale) by
    region (series.h5's labels), area-weighted: the mediastinum's mean |motion| and the
    diaphragm's mean caudal motion, in mm (docs/realism.md's criteria: <= 1 mm, >= 8 mm)."""
    import h5py
    out = {}
    with h5py.File(series, "r") as f:
        for side in ("right", "left"):
            g = f[side]
            x, t = g["rest/positions"][:], g["rest/triangles"][:]
            u, region, scale = g["field/unit_displacement"][:], g["rest/region"][:], g["frames/scale"][:]
            area = np.zeros(len(x))
            a = 0.5 * np.linalg.norm(np.cross(x[t[:, 1]] - x[t[:, 0]], x[t[:, 2]] - x[t[:, 0]]), axis=1)
            for c in range(3):
                np.add.at(area, t[:, c], a / 3.0)
            motion = (scale.max() - scale.min()) * u * 1e3
            def mean(values, where):
                return float((values * area)[where].sum() / area[where].sum())
            out[side] = {"mediastinum_mm": mean(np.linalg.norm(motion, axis=1), region == 3),
                         "diaphragm_caudal_mm": mean(-motion[:, 2], region == 2)}
    return out


def torn_where(out, reference, lungs):
    """Where the lungs' tears lie at the breath's other end (docs/voxels.md, "The lungs' own inside
    at 2 mm voxels"). Per lung, for the voxels outside the band whose pull-back J leaves [0.5, 2]
    ("torn") and the first voxel of each neighbour pair more than a voxel apart ("pairs"): the
    warped distance to the pleura; through each one's rest point (the pull-back's) the vertical line
    across the rest surface (field-<side>.h5's triangles, ray-triangle): its length and the mean
    vertical stretch that the surface field alone imposes on it, 1 + s (u_top - u_bottom)_z / length
    (s the time point's scale, voxels.csv); and how many of the rest tetrahedron's nodes lie on the
    surface (4: the surface field's own motion, whatever the inside does)."""
    import csv
    import h5py
    d = out / "voxels"
    other = "end_inspiration" if reference == "end_expiration" else "end_expiration"
    with open(d / "voxels.csv") as fh:
        scales = {row["time_point"]: [float(x) for x in row["scales"].split()] for row in csv.DictReader(fh)}[other]
    pimg, pullback = load(d, f"dvf-pullback-{other}")
    _, labels = load(d, f"labels-{other}")
    lps = to_lps(pimg)
    origin = np.diag([-1.0, -1.0, 1.0]) @ pimg.affine[:3, 3]
    lung = labels > 0
    ok = ~(ndimage.binary_dilation(lung, iterations=2) & ~ndimage.binary_erosion(lung, iterations=2))
    ok[[0, -1], :, :] = ok[:, [0, -1], :] = ok[:, :, [0, -1]] = False
    jp = jacobian(pimg, pullback)
    spacing = np.array(pimg.header.get_zooms()[:3], dtype=float)
    pleura = ndimage.distance_transform_edt(lung, sampling=spacing)
    result = {}
    for k, side in enumerate(lungs):  # voxels.csv's scales: right, then left
        s = scales[k] if len(scales) == len(lungs) else scales[0]
        mask = lung_mask(labels, side, lungs) & ok
        found = {"torn": np.argwhere(mask & ((jp < 0.5) | (jp > 2.0)))}
        paired = []
        for ax in range(3):
            lo, hi = [slice(None)] * 3, [slice(None)] * 3
            lo[ax], hi[ax] = slice(0, -1), slice(1, None)
            apart = np.linalg.norm(pullback[tuple(lo)] - pullback[tuple(hi)], axis=-1)
            paired.append(np.argwhere(mask[tuple(lo)] & ok[tuple(hi)] & (apart > spacing.min())))
        found["pairs"] = np.concatenate(paired)
        if not any(len(v) for v in found.values()):
            continue
        with h5py.File(out / f"field-{side}.h5", "r") as f:
            x = f["rest/positions"][:] * 1e3
            tri = f["rest/triangles"][:].astype(np.int64)
            u = f["field/unit_displacement"][:] * 1e3
            nodes = f["interior/nodes"][:] * 1e3
            tets = f["interior/tets"][:].astype(np.int64)
            on_surface = np.zeros(len(nodes), bool)
            on_surface[f["interior/boundary_nodes"][:]] = True
        a, e1, e2 = x[tri[:, 0]], x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]]
        corners = nodes[tets]
        edges = np.stack([corners[:, i] - corners[:, 0] for i in (1, 2, 3)], -1)
        centres = corners.mean(1)

        def crossing(p, direction):  # the nearest crossing of the ray p + t direction (t > 0): (t, u there)
            h = np.cross(direction, e2)
            det = (e1 * h).sum(1)
            inv = 1.0 / np.where(np.abs(det) > 1e-12, det, np.inf)
            q = p - a
            b1 = inv * (q * h).sum(1)
            r = np.cross(q, e1)
            b2 = inv * (r @ direction)
            t = inv * (e2 * r).sum(1)
            hit = np.where((b1 >= 0) & (b2 >= 0) & (b1 + b2 <= 1) & (t > 0))[0]
            if len(hit) == 0:
                return None
            j = hit[np.argmin(t[hit])]
            return t[j], (1 - b1[j] - b2[j]) * u[tri[j, 0]] + b1[j] * u[tri[j, 1]] + b2[j] * u[tri[j, 2]]

        def surface_nodes(p):  # of the rest tet holding p
            for t in np.argsort(np.linalg.norm(centres - p, axis=1))[:64]:
                b = np.linalg.solve(edges[t], p - corners[t, 0])
                if b.min() > -1e-9 and b.sum() < 1 + 1e-9:
                    return int(on_surface[tets[t]].sum())
            return -1

        result[side] = {}
        for name, voxels in found.items():
            if len(voxels) == 0:
                continue
            rows = []
            for v in voxels:
                p = lps @ v + origin + pullback[tuple(v)]
                above, below = crossing(p, np.array([0.0, 0.0, 1.0])), crossing(p, np.array([0.0, 0.0, -1.0]))
                if above is None or below is None:
                    continue
                length = above[0] + below[0]
                rows.append([float(jp[tuple(v)]), float(pleura[tuple(v)]), length,
                             1.0 + s * (above[1][2] - below[1][2]) / length, surface_nodes(p), *p])
            r = np.array(rows)
            result[side][name] = {
                "count": int(len(voxels)), "pull_j": [float(r[:, 0].min()), float(r[:, 0].max())],
                "to_pleura_mm": [float(r[:, 1].min()), float(np.median(r[:, 1])), float(r[:, 1].max())],
                "line_mm": [float(r[:, 2].min()), float(np.median(r[:, 2])), float(r[:, 2].max())],
                "surface_stretch": [float(r[:, 3].min()), float(np.median(r[:, 3])), float(r[:, 3].max())],
                "tet_surface_nodes": [int((r[:, 4] == n).sum()) for n in range(5)],
                "rest_lps_mm": [[float(r[:, c].min()), float(r[:, c].max())] for c in (5, 6, 7)]}
    return result


def run(pneuma, case, tissue, breath, work, spacing_mm, tets_mm=6.0, surfaces_mm=5.0, where=False, interior=""):
    work.mkdir(parents=True, exist_ok=True)
    ct = work / "ct.nii.gz"
    if case == "phantom":
        mesh = "phantom: both"
        if not ct.exists():
            phantom_ct(pneuma, spacing_mm, work)
    else:
        labels = CT_LOBES / f"{case}_lobes.nii.gz"
        mesh = f"labels: {labels}, lungs: {{right: [3, 4, 5], left: [1, 2]}}"
        if not ct.exists():
            synthetic_ct(labels, ct, spacing_mm)
    scenario = work / f"{tissue}-{breath}.yaml"
    scenario.write_text(
        "duration: 8 s\nframes: {rate: 5 Hz}\n"
        f"mesh: {{{mesh}, edge: {surfaces_mm:g} mm, breath: {breath}}}\n"
        f"field: {{tissue: {tissue}, interior: {{edge: {tets_mm:g} mm{', ' + interior if interior else ''}}}}}\n"
        "physiology: {preset: healthy-adult}\n"
        "outputs: {gltf: false, report: false, hdf5: true, physiology_csv: false,\n"
        f"  voxels: {{at: [end_expiration, 1 s, end_inspiration], spacing: {spacing_mm:g} mm, image: ct.nii.gz}}}}\n")
    out = work / f"{tissue}-{breath}"
    start = time.time()
    p = subprocess.run([str(pneuma), "run", str(scenario), "-o", str(out), "--quiet"], capture_output=True, text=True)
    result = {"case": case, "tissue": tissue, "breath": breath, "spacing_mm": spacing_mm, "tets_mm": tets_mm,
              "surfaces_mm": surfaces_mm, "exit": p.returncode,
              **({"interior": interior} if interior else {}),
              "run_s": round(time.time() - start, 1)}
    if p.returncode != 0:
        result["error"] = p.stderr.strip()
        return result
    # The run's warnings (a deflation no step of the ladder makes clean says so) and each lung's
    # deflation smoothing (the manifest's facts; absent where the field was kept as it is).
    result["warnings"] = [line for line in p.stderr.splitlines() if "warning" in line.lower()]
    facts = json.loads((out / "manifest.json").read_text()).get("facts", {})
    result["deflation_smoothing_mm"] = {side: round(1e3 * float(facts[f"lungs.{side}.deflation_smoothing_m"]), 3)
                                        for side in ("right", "left") if f"lungs.{side}.deflation_smoothing_m" in facts}
    result.update(measure(out / "voxels", ct, breath, lungs_of(case)))
    result["surface"] = surface_motion(out / "series.h5")
    if where:
        result["where"] = torn_where(out, breath, lungs_of(case))
    return result


def table(results):
    """The docs' table (docs/voxels.md, "The issue's checks, measured"): one row per run."""
    rows = ["| case | tissue | scan at | deep J < 0.95, % (differences / image) | smallest deep J (differences / image) "
            "| DIR-Lab, largest offset | pull-back J outside the band | outside [0.5, 2]: body / lungs (R / L) "
            "| pairs | mass, farthest from 1 | mean HU - prediction | the other end's volume | smallest J image "
            "| mediastinum, mm (R / L) |",
            "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in results:
        spacing = r.get("spacing_mm", 4.0)
        settings = ([] if spacing == 4.0 else [f"{spacing:g} mm voxels"]) + \
            ([] if r.get("tets_mm", 6.0) == 6.0 else [f"{r['tets_mm']:g} mm tets"]) + \
            ([] if r.get("surfaces_mm", 5.0) == 5.0 else [f"{r['surfaces_mm']:g} mm surfaces"]) + \
            ([f"interior {{{r['interior']}}}"] if r.get("interior") else [])
        case = r["case"] + (f" ({', '.join(settings)})" if settings else "")
        head = f"| {case} | {r['tissue']} | {r['breath']} |"
        if r["exit"] != 0:
            rows.append(head + f" exit {r['exit']}: {r.get('error', '')} |" + " |" * 10)
            continue
        t = r["worst_tear"]
        # In brackets where DIR-Lab's supine patients' profile is not asked: upright, and the phantom.
        applies = r["tissue"] != "healthy-upright" and r["case"] != "phantom"
        profile = f"{r['profile_offset']:.2f}" if applies else f"({r['profile_offset']:.2f})"
        rows.append(head + f" {100 * r['deep_below_095']:.3f} / {100 * r['image_below_095']:.2f} |"
                    f" {r['deep_min_j']:.2f} / {r['image_min_j']:.2f} | {profile} |"
                    f" {t['pull_min']:.2f}-{t['pull_max']:.2f} | {t['body_torn']} / {t['right_torn']} / {t['left_torn']} |"
                    f" {t['pairs']} | {100 * (r['worst_mass'] - 1):+.2f} % | {r['hu_offset']:+.2f} |"
                    f" {100 * r['volume_error']:+.2f} % | {r['smallest_image_j']:.2f} |"
                    + (f" {r['surface']['right']['mediastinum_mm']:.2f} / {r['surface']['left']['mediastinum_mm']:.2f} |"
                       if "surface" in r else " - |"))
    return "\n".join(rows)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pneuma", default=str(ROOT / "build" / "release" / "cli" / "pneuma"))
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--tissue", default="healthy-supine,healthy-upright")
    ap.add_argument("--breath", default="end_expiration,end_inspiration")
    ap.add_argument("--spacing", type=float, default=4.0, help="the voxels' spacing in mm (default 4, the test's)")
    ap.add_argument("--tets", type=float, default=6.0, help="field.interior's edge in mm (default 6, the test's)")
    ap.add_argument("--surfaces", type=float, default=5.0, help="mesh.edge in mm (default 5, the test's)")
    ap.add_argument("--interior", default="",
                    help="more field.interior keys, YAML flow (e.g. 'poisson_ratio: 0.45'; default: none)")
    ap.add_argument("--where", action="store_true",
                    help="also say where the lungs' torn voxels and pairs lie (torn_where)")
    ap.add_argument("--keep", help="keep the runs' folders here (default: a temporary folder)")
    ap.add_argument("--json", help="write every run's numbers here")
    ap.add_argument("--table", help="print the docs' table of --json files (comma-separated), and run nothing")
    args = ap.parse_args()
    if args.table:
        print(table([r for f in args.table.split(",") for r in json.loads(Path(f).read_text())]))
        return 0
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(args.keep) if args.keep else Path(tmp)
        for case in args.cases.split(","):
            for tissue in args.tissue.split(","):
                for breath in args.breath.split(","):
                    work = base / (case if args.spacing == 4.0 else f"{case}-{args.spacing:g}mm")
                    r = run(args.pneuma, case, tissue, breath, work, args.spacing, args.tets, args.surfaces, args.where,
                            args.interior)
                    results.append(r)
                    print(json.dumps(r), flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    return 0 if all(r["exit"] == 0 for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
