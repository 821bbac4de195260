#!/usr/bin/python3
"""Checks a run's DICOM outputs (outputs.voxels.dicom) with tools independent of pneuma, for
tests/dicom: plastimatch reads each phase's CT series and RTSTRUCT back, pydicom reads every file.

check_dicom_outputs.py RUN_FOLDER WORK_FOLDER STRUCTURES_JSON [--study UID --frame UID]

STRUCTURES_JSON maps each ROI name to the label values it must hold ({"lung_right": [3, 4, 5]}).
For each dicom/ct-<tag> series: plastimatch's CT against pneuma's voxels/ct-<tag>.nii.gz (the same
voxel centres within 0.01 mm, HU within 1), each structure's mask rasterised by plastimatch
against voxels/labels-<tag>.nii.gz (Dice >= 0.95); then pydicom: one StudyInstanceUID and one
FrameOfReferenceUID over all files (the given ones if any), one SeriesInstanceUID per series, the
RTSTRUCT's contour images exactly its series' SOPInstanceUIDs. Prints one line per phase and
structure; exits 1 with the reasons on a failure.
"""
import argparse
import glob
import json
import os
import subprocess
import sys

import nibabel
import numpy
import pydicom

failures = []


def fail(text):
    failures.append(text)


def same_grid_index(a, b):
    """Index map from a's voxels to b's (integers), or None when the centres differ by > 0.01 mm."""
    shape = a.shape
    corners = numpy.array([[i, j, k, 1.0] for i in (0, shape[0] - 1) for j in (0, shape[1] - 1) for k in (0, shape[2] - 1)]).T
    world = a.affine @ corners
    index = numpy.linalg.inv(b.affine) @ world
    rounded = numpy.round(index)
    back = b.affine @ rounded
    if numpy.abs(back - world).max() > 0.01:
        return None
    return numpy.linalg.inv(b.affine) @ a.affine


def resampled(target, source):
    """`source`'s voxels on `target`'s grid (the same centres, possibly reordered axes)."""
    m = same_grid_index(target, source)
    if m is None:
        return None
    i, j, k = numpy.meshgrid(*[numpy.arange(n) for n in target.shape[:3]], indexing="ij")
    ijk = numpy.stack([i.ravel(), j.ravel(), k.ravel(), numpy.ones(i.size)])
    src = numpy.round(m @ ijk).astype(int)
    data = numpy.asarray(source.dataobj)
    return data[src[0], src[1], src[2]].reshape(target.shape[:3])


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("run")
    parser.add_argument("work")
    parser.add_argument("structures")
    parser.add_argument("--study", default="")
    parser.add_argument("--frame", default="")
    args = parser.parse_args()
    structures = json.loads(args.structures)
    os.makedirs(args.work, exist_ok=True)
    studies, frames, series_uids = set(), set(), []
    tags = sorted(os.path.basename(p)[3:] for p in glob.glob(os.path.join(args.run, "dicom", "ct-*")))
    if not tags:
        fail("no dicom/ct-* series")
    for tag in tags:
        series = os.path.join(args.run, "dicom", "ct-" + tag)
        rtstruct = os.path.join(args.run, "dicom", "rtstruct-" + tag + ".dcm")
        ct_out = os.path.join(args.work, f"ct-{tag}.nii.gz")
        prefix = os.path.join(args.work, f"ss-{tag}")
        subprocess.run(["plastimatch", "convert", "--input", series, "--output-img", ct_out], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        subprocess.run(["plastimatch", "convert", "--input", rtstruct, "--referenced-ct", series, "--output-prefix",
                        prefix, "--prefix-format", "nii.gz"], check=True, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
        mine = nibabel.load(os.path.join(args.run, "voxels", f"ct-{tag}.nii.gz"))
        theirs = nibabel.load(ct_out)
        if theirs.shape[:3] != mine.shape[:3]:
            fail(f"{tag}: plastimatch's CT is {theirs.shape}, pneuma's {mine.shape}")
            continue
        ct = resampled(mine, theirs)
        if ct is None:
            fail(f"{tag}: plastimatch's CT voxel centres are not pneuma's within 0.01 mm")
            continue
        hu = numpy.abs(ct.astype(float) - numpy.asarray(mine.dataobj, dtype=float)).max()
        if hu > 1.0:
            fail(f"{tag}: CT differs by up to {hu} HU")
        labels_image = nibabel.load(os.path.join(args.run, "voxels", f"labels-{tag}.nii.gz"))
        labels = numpy.asarray(labels_image.dataobj)
        for name, values in structures.items():
            path = os.path.join(prefix, name + ".nii.gz")
            if not os.path.exists(path):
                fail(f"{tag}: no structure {name} in the RTSTRUCT")
                continue
            mask = resampled(labels_image, nibabel.load(path))
            if mask is None:
                fail(f"{tag}: {name}'s mask is not on the CT's grid")
                continue
            mask = mask > 0
            truth = numpy.isin(labels, values)
            dice = 2.0 * numpy.logical_and(mask, truth).sum() / (mask.sum() + truth.sum())
            print(f"{tag} {name}: Dice {dice:.4f} ({truth.sum()} voxels), CT max |dHU| {hu:g}")
            if not dice >= 0.95:
                fail(f"{tag}: {name}: Dice {dice:.4f} < 0.95")
        # pydicom: every file, the UIDs they share and reference.
        sop_uids = []
        for f in sorted(glob.glob(os.path.join(series, "*.dcm"))):
            ds = pydicom.dcmread(f)
            studies.add(ds.StudyInstanceUID)
            frames.add(ds.FrameOfReferenceUID)
            sop_uids.append(ds.SOPInstanceUID)
            series_uids.append(ds.SeriesInstanceUID)
        rt = pydicom.dcmread(rtstruct)
        studies.add(rt.StudyInstanceUID)
        frames.add(rt.ReferencedFrameOfReferenceSequence[0].FrameOfReferenceUID)
        referenced = rt.ReferencedFrameOfReferenceSequence[0].RTReferencedStudySequence[0].RTReferencedSeriesSequence[0]
        if referenced.SeriesInstanceUID not in series_uids:
            fail(f"{tag}: the RTSTRUCT references another series")
        if sorted(i.ReferencedSOPInstanceUID for i in referenced.ContourImageSequence) != sorted(sop_uids):
            fail(f"{tag}: the RTSTRUCT's contour images are not its series' slices")
        for roi in rt.ROIContourSequence:
            for contour in getattr(roi, "ContourSequence", []):
                if contour.ContourImageSequence[0].ReferencedSOPInstanceUID not in sop_uids:
                    fail(f"{tag}: a contour references an image outside its series")
                    break
    if len(studies) != 1 or len(frames) != 1:
        fail(f"{len(studies)} StudyInstanceUIDs and {len(frames)} FrameOfReferenceUIDs: expected one of each")
    if args.study and studies != {args.study}:
        fail(f"StudyInstanceUID {studies}: expected the input's {args.study}")
    if args.frame and frames != {args.frame}:
        fail(f"FrameOfReferenceUID {frames}: expected the input's {args.frame}")
    if len(set(series_uids)) != len(tags):
        fail(f"{len(set(series_uids))} SeriesInstanceUIDs for {len(tags)} series")
    print(f"{len(tags)} phases, study {studies}, frame of reference {frames}")
    if failures:
        print("\n".join(failures), file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
