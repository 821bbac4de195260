#!/usr/bin/python3
"""Write the inputs of scenarios/4d-slicer.yaml: a spherical target and a fiducials CSV for case004.

    python3 scripts/make-4d-slicer-inputs.py [case004_lobes.nii.gz] [out_folder]

Defaults: ../shared/data/ct-lobes/case004_lobes.nii.gz beside the checkout, and scenarios/.
Nothing is copied from anywhere: the target is a made-up tumour, a ball of radius 12 mm centred at
the centroid of the lowest right-lung lobe (labels 3, 4, 5: the one whose voxels lie lowest on
average), on its own 2 mm grid (axis-aligned LPS, 40 x 40 x 40 voxels around the ball), written as
4d-slicer-target.nii.gz (uint8, 1 inside: a voxel whose centre lies within the radius).
4d-slicer-fiducials.csv holds four named points in LPS millimetres: the target's centre, the centroid
of the left lung's lowest lobe (labels 1, 2), a point 40 mm below the right lung's lowest voxel
(in the abdomen, moving with the body) and the right lung's lowest voxel centre itself.
The same inputs give the same bytes.
"""
import os
import sys

import nibabel as nib
import numpy as np

RADIUS_MM = 12.0
SPACING_MM = 2.0
SIZE = 40


def lps_centres(img, mask):
    """Voxel centres of `mask` in LPS mm."""
    ijk = np.argwhere(mask)
    ras = nib.affines.apply_affine(img.affine, ijk)
    return ras * [-1, -1, 1]


def lowest_lobe_centroid(img, labels, values):
    best = None
    for v in values:
        p = lps_centres(img, labels == v)
        if len(p) and (best is None or p[:, 2].mean() < best[:, 2].mean()):
            best = p
    return best.mean(axis=0)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    source = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "../../shared/data/ct-lobes/case004_lobes.nii.gz")
    out = sys.argv[2] if len(sys.argv) > 2 else os.path.join(here, "../scenarios")
    img = nib.load(source)
    labels = np.asarray(img.dataobj).astype(np.int32)
    centre = lowest_lobe_centroid(img, labels, [3, 4, 5])
    left = lowest_lobe_centroid(img, labels, [1, 2])
    right = lps_centres(img, np.isin(labels, [3, 4, 5]))
    lowest = right[np.argmin(right[:, 2])]

    # The target's grid: LPS axes, 2 mm, the ball in its middle; NIfTI's affine is RAS.
    origin_lps = centre - SPACING_MM * (SIZE - 1) / 2.0
    i, j, k = np.indices((SIZE, SIZE, SIZE))
    lps = origin_lps + SPACING_MM * np.stack([i, j, k], axis=-1)
    target = (np.linalg.norm(lps - centre, axis=-1) <= RADIUS_MM).astype(np.uint8)
    affine = np.diag([-SPACING_MM, -SPACING_MM, SPACING_MM, 1.0])
    affine[:3, 3] = origin_lps * [-1, -1, 1]
    image = nib.Nifti1Image(target, affine)
    image.header.set_qform(affine, code=1)
    image.header.set_sform(affine, code=1)
    image.header["descrip"] = b"pneuma made-up target: 12 mm ball (scripts/make-4d-slicer-inputs.py)"
    # gzip without a time stamp: the same bytes each time.
    raw = image.to_bytes()
    import gzip
    with open(os.path.join(out, "4d-slicer-target.nii.gz"), "wb") as f:
        f.write(gzip.compress(raw, mtime=0))

    with open(os.path.join(out, "4d-slicer-fiducials.csv"), "w") as f:
        f.write("name,x_mm,y_mm,z_mm\n")
        for name, p in [("target_centre", centre), ("left_lower_lobe", left),
                        ("abdomen", lowest - [0, 0, 40.0]), ("right_lung_lowest_voxel", lowest)]:
            f.write(f"{name},{p[0]:.3f},{p[1]:.3f},{p[2]:.3f}\n")


if __name__ == "__main__":
    main()
