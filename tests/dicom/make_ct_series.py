#!/usr/bin/python3
"""A DICOM CT series (pydicom) and the same voxels as NIfTI (nibabel), made from a label map, for
tests/dicom: the checks of pneuma's DICOM reader against an independent writer.

make_ct_series.py LABELS.nii.gz OUT_FOLDER OUT.nii.gz [--step N] [--descending] [--oblique DEG]
                  [--damage KIND]

The label map is subsampled by --step along each axis and turned into Hounsfield units (0 -> -1000,
label l -> -850 + 10 l: lungs at lung density), stored unsigned with RescaleIntercept -1024. The
NIfTI holds the same HU on the same grid. --descending writes the files and instance numbers from
the last slice to the first; --oblique rotates the whole grid (ImageOrientationPatient and the
NIfTI affine) by DEG degrees about an axis that is not a coordinate axis. --damage KIND spoils the
series: missing_slice, mixed_series, not_ct, truncated, no_pixels, gantry_tilt, uneven.
"""
import argparse
import math
import os

import nibabel
import numpy
import pydicom
from pydicom.dataset import Dataset, FileMetaDataset
from pydicom.uid import ExplicitVRLittleEndian, generate_uid

CT_IMAGE_STORAGE = "1.2.840.10008.5.1.4.1.1.2"


def rotation(degrees):
    axis = numpy.array([1.0, 2.0, 3.0])
    axis /= numpy.linalg.norm(axis)
    a = math.radians(degrees)
    k = numpy.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return numpy.eye(3) + math.sin(a) * k + (1 - math.cos(a)) * k @ k


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("labels")
    parser.add_argument("folder")
    parser.add_argument("nifti")
    parser.add_argument("--step", type=int, default=4)
    parser.add_argument("--descending", action="store_true")
    parser.add_argument("--oblique", type=float, default=0.0)
    parser.add_argument("--damage", default="")
    args = parser.parse_args()

    image = nibabel.load(args.labels)
    labels = numpy.asarray(image.dataobj)[:: args.step, :: args.step, :: args.step].astype(numpy.int32)
    hu = numpy.where(labels > 0, -850 + 10 * labels, -1000).astype(numpy.int16)
    # The subsampled grid in LPS millimetres: NIfTI's RAS+ affine with its first two rows negated.
    affine_ras = image.affine.copy()
    affine_ras[:3, :3] = affine_ras[:3, :3] * args.step
    lps = numpy.diag([-1.0, -1.0, 1.0, 1.0]) @ affine_ras
    if args.oblique:
        turn = numpy.eye(4)
        turn[:3, :3] = rotation(args.oblique)
        lps = turn @ lps
    # DICOM's slice frame needs orthogonal in-plane axes; the shared cases have them.
    axes = lps[:3, :3]
    spacing = numpy.linalg.norm(axes, axis=0)
    row_dir, column_dir = axes[:, 0] / spacing[0], axes[:, 1] / spacing[1]
    nibabel.save(nibabel.Nifti1Image(hu, numpy.diag([-1.0, -1.0, 1.0, 1.0]) @ lps), args.nifti)

    os.makedirs(args.folder, exist_ok=True)
    study, series, frame = generate_uid(), generate_uid(), generate_uid()
    nk = hu.shape[2]
    order = list(range(nk))[::-1] if args.descending else list(range(nk))
    for number, k in enumerate(order, start=1):
        meta = FileMetaDataset()
        meta.MediaStorageSOPClassUID = CT_IMAGE_STORAGE
        meta.MediaStorageSOPInstanceUID = generate_uid()
        meta.TransferSyntaxUID = ExplicitVRLittleEndian
        ds = Dataset()
        ds.file_meta = meta
        ds.SOPClassUID = CT_IMAGE_STORAGE
        ds.SOPInstanceUID = meta.MediaStorageSOPInstanceUID
        ds.Modality = "CT"
        ds.PatientName = "Test^Case"
        ds.PatientID = "case004"
        ds.StudyInstanceUID = study
        ds.SeriesInstanceUID = series
        ds.FrameOfReferenceUID = frame
        ds.InstanceNumber = number
        ds.ImageType = ["ORIGINAL", "PRIMARY", "AXIAL"]
        position = lps[:3, :3] @ numpy.array([0.0, 0.0, float(k)]) + lps[:3, 3]
        ds.ImagePositionPatient = [f"{v:.6f}" for v in position]
        ds.ImageOrientationPatient = [f"{v:.8f}" for v in list(row_dir) + list(column_dir)]
        ds.PixelSpacing = [f"{spacing[1]:.6f}", f"{spacing[0]:.6f}"]
        ds.SliceThickness = f"{spacing[2]:.6f}"
        ds.Rows, ds.Columns = hu.shape[1], hu.shape[0]
        ds.SamplesPerPixel = 1
        ds.PhotometricInterpretation = "MONOCHROME2"
        ds.BitsAllocated, ds.BitsStored, ds.HighBit, ds.PixelRepresentation = 16, 12, 11, 0
        ds.RescaleIntercept, ds.RescaleSlope = "-1024", "1"
        # Rows are j, columns i: DICOM's pixel (row r, column c) is voxel (c, r).
        ds.PixelData = (hu[:, :, k].T.astype(numpy.int32) + 1024).astype("<u2").tobytes()
        damage = args.damage
        middle = number == nk // 2
        if damage == "not_ct" and middle:
            ds.Modality = "MR"
        if damage == "no_pixels" and middle:
            del ds.PixelData
        if damage == "mixed_series" and middle:
            ds.SeriesInstanceUID = generate_uid()
        if damage == "gantry_tilt":
            ds.GantryDetectorTilt = "15"
        if damage == "uneven" and number > nk // 2:
            ds.ImagePositionPatient = [f"{v:.6f}" for v in position + 0.3 * lps[:3, 2]]
        if damage == "missing_slice" and middle:
            continue
        path = os.path.join(args.folder, f"slice{number:04d}.dcm")
        ds.is_little_endian, ds.is_implicit_VR = True, False
        ds.save_as(path, write_like_original=False)
        if damage == "truncated" and middle:
            size = os.path.getsize(path)
            with open(path, "r+b") as f:
                f.truncate(size - hu.shape[0] * hu.shape[1])


if __name__ == "__main__":
    main()
