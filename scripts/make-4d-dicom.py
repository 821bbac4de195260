#!/usr/bin/python3
"""Makes scenarios/4d-dicom.yaml and the planning CT it reads, from a shared case.

    scripts/make-4d-dicom.py [--case case004] [--out out/4d-dicom-input]

The shared cases (../shared/data/ct-lobes) are lobe label maps without their CT; this script makes
a stand-in planning CT from one, as a DICOM CT series a scanner could have written (pydicom): the
label map's grid subsampled by 2 in-plane (1.37 mm pixels, 1 mm slices), lung parenchyma at
-850 HU (lobe l at -850 + 5 l, so that the lobes can be told apart), everything else soft tissue
at 40 HU; patient "Case^004" HFS, a study and frame of reference with UIDs derived from the case's
name (the same files run after run). Then it writes scenarios/4d-dicom.yaml: that series as
`voxels.image`, the lobe map as the lungs, ten phase bins over four breaths, each bin written as a
DICOM CT series with an RTSTRUCT (lungs and lobes) in out/4d-dicom/dicom/ by
`pneuma run scenarios/4d-dicom.yaml -o out/4d-dicom`.
Data: acreegan/lung_modelling, example_data/covid_lung_lobe_segmentation.zip (Coronacases_004),
dataset DOI 10.21227/3qe9-e178, CC BY 4.0 (../shared/data/ct-lobes/LICENSE.txt).
"""
import argparse
import os

import nibabel
import numpy
from pydicom.dataset import Dataset, FileMetaDataset
from pydicom.uid import ExplicitVRLittleEndian, generate_uid

CT_IMAGE_STORAGE = "1.2.840.10008.5.1.4.1.1.2"
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

SCENARIO = """# A 10-phase DICOM 4D-CT with structures per phase, for a radiotherapy planning system (README,
# "pneuma for a 4D-CT in your planning system"; docs/formats.md, "DICOM"). Made by
# scripts/make-4d-dicom.py, which also writes the planning CT this reads ({ct}, a stand-in made
# from the lobe label map of {case}: run the script first). The lobes breathe quietly for four
# whole cycles; the frames are binned by phase (0 % = end-inspiration, as Varian RPM marks it) and
# each bin, at its mean volume, is written as a CT series (dicom/ct-bin_NN/, "CT 20%" ...,
# mass-preserving HU) with an RTSTRUCT (dicom/rtstruct-bin_NN.dcm: lung_right, lung_left and the
# five lobes as closed planar contours on that series' slices), all in the planning CT's study
# and frame of reference; import out/4d-dicom/dicom/ as one study.
# Data: acreegan/lung_modelling, example_data/covid_lung_lobe_segmentation.zip (Coronacases_004),
# dataset DOI 10.21227/3qe9-e178, CC BY 4.0 (../shared/data/ct-lobes/LICENSE.txt); every output of
# this scenario is derived from it and keeps that attribution.
name: 4d-dicom
description: A 10-phase DICOM 4D-CT (CT series and RTSTRUCT per phase bin) of both lungs of {case}.
duration: 24 s
frames:
  rate: 10 Hz
mesh:
  labels: ../../shared/data/ct-lobes/{case}_lobes.nii.gz
  lungs:
    right: [3, 4, 5]
    left: [1, 2]
  edge: 4 mm
field:
  tissue: healthy-supine
  interior: {{edge: 5 mm, mesher: lattice, unfold: 1 L}}
physiology:
  preset: healthy-adult
outputs:
  gltf: false
  hdf5: false
  phases: {{bins: 10}}
  voxels:
    at: [phases]
    spacing: 3 mm
    image: {ct}
    jacobian: false
    dicom: true
"""


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", default="case004")
    parser.add_argument("--out", default=os.path.join(ROOT, "out", "4d-dicom-input"))
    args = parser.parse_args()
    source = os.path.join(ROOT, "..", "shared", "data", "ct-lobes", args.case + "_lobes.nii.gz")
    image = nibabel.load(source)
    labels = numpy.asarray(image.dataobj)[::2, ::2, :].astype(numpy.int32)
    hu = numpy.where(labels > 0, -850 + 5 * labels, 40).astype(numpy.int16)
    affine = image.affine.copy()
    affine[:3, :2] *= 2
    lps = numpy.diag([-1.0, -1.0, 1.0, 1.0]) @ affine
    spacing = numpy.linalg.norm(lps[:3, :3], axis=0)
    row_dir, column_dir = lps[:3, 0] / spacing[0], lps[:3, 1] / spacing[1]

    folder = os.path.join(args.out, "ct")
    os.makedirs(folder, exist_ok=True)
    for old in os.listdir(folder):
        os.remove(os.path.join(folder, old))
    uid = lambda what: generate_uid(entropy_srcs=["pneuma make-4d-dicom", args.case, what])
    study, series, frame = uid("study"), uid("series"), uid("frame")
    for k in range(hu.shape[2]):
        meta = FileMetaDataset()
        meta.MediaStorageSOPClassUID = CT_IMAGE_STORAGE
        meta.MediaStorageSOPInstanceUID = uid(f"slice {k}")
        meta.TransferSyntaxUID = ExplicitVRLittleEndian
        ds = Dataset()
        ds.file_meta = meta
        ds.SpecificCharacterSet = "ISO_IR 100"
        ds.SOPClassUID, ds.SOPInstanceUID = CT_IMAGE_STORAGE, meta.MediaStorageSOPInstanceUID
        ds.Modality = "CT"
        ds.PatientName, ds.PatientID, ds.PatientBirthDate, ds.PatientSex = "Case^004", args.case, "", "O"
        ds.StudyInstanceUID, ds.SeriesInstanceUID, ds.FrameOfReferenceUID = study, series, frame
        ds.StudyDate, ds.StudyTime, ds.StudyID, ds.AccessionNumber = "20200101", "120000", "1", ""
        ds.ReferringPhysicianName, ds.StudyDescription = "", "Planning CT (stand-in from the lobe labels)"
        ds.SeriesNumber, ds.InstanceNumber, ds.PatientPosition = 1, k + 1, "HFS"
        ds.PositionReferenceIndicator = ""
        ds.ImageType = ["DERIVED", "SECONDARY", "AXIAL"]
        position = lps[:3, 3] + k * lps[:3, 2]
        ds.ImagePositionPatient = [f"{v:.4f}" for v in position]
        ds.ImageOrientationPatient = [f"{v:.6f}" for v in list(row_dir) + list(column_dir)]
        ds.PixelSpacing = [f"{spacing[1]:.6f}", f"{spacing[0]:.6f}"]
        ds.SliceThickness = f"{spacing[2]:.4f}"
        ds.Rows, ds.Columns = hu.shape[1], hu.shape[0]
        ds.SamplesPerPixel, ds.PhotometricInterpretation = 1, "MONOCHROME2"
        ds.BitsAllocated, ds.BitsStored, ds.HighBit, ds.PixelRepresentation = 16, 16, 15, 1
        ds.RescaleIntercept, ds.RescaleSlope = "0", "1"
        ds.PixelData = hu[:, :, k].T.astype("<i2").tobytes()
        ds.is_little_endian, ds.is_implicit_VR = True, False
        ds.save_as(os.path.join(folder, f"CT{k + 1:04d}.dcm"), write_like_original=False)
    ct = os.path.relpath(folder, os.path.join(ROOT, "scenarios")) + "/"
    with open(os.path.join(ROOT, "scenarios", "4d-dicom.yaml"), "w") as f:
        f.write(SCENARIO.format(case=args.case, ct=ct))
    print(f"{hu.shape[2]} slices of {hu.shape[0]} x {hu.shape[1]} in {folder}; scenarios/4d-dicom.yaml")


if __name__ == "__main__":
    main()
