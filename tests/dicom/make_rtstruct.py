#!/usr/bin/python3
"""An RT Structure Set drawn by pydicom on a CT series, for tests/dicom: the checks of pneuma's
RTSTRUCT reader against shapes whose voxels are known.

make_rtstruct.py CT_FOLDER [--wrong-frame] [--between-slices]

Writes CT_FOLDER/rtstruct.dcm, on the series' slices 10 to 13 (in the order along the slice
normal), in the slices' own (row, column) frame centred on the middle pixel (cx, cy) in mm:
  "square": the square [cx - 20.3, cx + 20.9] x [cy - 18.1, cy + 22.6] mm;
  "frame":  that square with the hole [cx - 8.2, cx + 9.1] x [cy - 7.7, cy + 8.8] mm drawn as a
            second contour of the same ROI (slices 10 and 11 only);
  "disc":   a circle of radius 30 mm about (cx + 60, cy), 128 points, apart from the others.
--wrong-frame gives the structure set another FrameOfReferenceUID; --between-slices moves the
disc's contours half a slice along the normal.
"""
import argparse
import glob
import math
import os

import numpy
import pydicom
from pydicom.dataset import Dataset, FileMetaDataset
from pydicom.sequence import Sequence
from pydicom.uid import ImplicitVRLittleEndian, generate_uid


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("folder")
    parser.add_argument("--wrong-frame", action="store_true")
    parser.add_argument("--between-slices", action="store_true")
    args = parser.parse_args()
    slices = [pydicom.dcmread(f) for f in sorted(glob.glob(os.path.join(args.folder, "*.dcm")))]
    o = numpy.array(slices[0].ImageOrientationPatient, dtype=float)
    row, col = o[:3], o[3:]
    normal = numpy.cross(row, col)
    slices.sort(key=lambda s: float(numpy.dot(numpy.array(s.ImagePositionPatient, dtype=float), normal)))
    step = float(numpy.dot(numpy.array(slices[1].ImagePositionPatient, dtype=float) -
                           numpy.array(slices[0].ImagePositionPatient, dtype=float), normal))
    dy, dx = (float(v) for v in slices[0].PixelSpacing)  # row spacing, column spacing
    cx, cy = (slices[0].Columns // 2) * dx, (slices[0].Rows // 2) * dy

    def point(s, u, v, shift=0.0):
        origin = numpy.array(s.ImagePositionPatient, dtype=float)
        return origin + u * row + v * col + shift * normal

    def rect(s, u0, u1, v0, v1):
        return [point(s, u, v) for u, v in ((u0, v0), (u1, v0), (u1, v1), (u0, v1))]

    rois = {"square": [], "frame": [], "disc": []}
    for k in range(10, 14):
        s = slices[k]
        outer = rect(s, cx - 20.3, cx + 20.9, cy - 18.1, cy + 22.6)
        rois["square"].append((s, outer))
        if k < 12:
            rois["frame"].append((s, outer))
            rois["frame"].append((s, rect(s, cx - 8.2, cx + 9.1, cy - 7.7, cy + 8.8)))
        shift = 0.5 * step if args.between_slices else 0.0
        rois["disc"].append((s, [point(s, cx + 60 + 30 * math.cos(t), cy + 30 * math.sin(t), shift)
                                 for t in numpy.linspace(0, 2 * math.pi, 128, endpoint=False)]))

    ds = Dataset()
    ds.file_meta = FileMetaDataset()
    ds.file_meta.MediaStorageSOPClassUID = "1.2.840.10008.5.1.4.1.1.481.3"
    ds.file_meta.MediaStorageSOPInstanceUID = generate_uid()
    ds.file_meta.TransferSyntaxUID = ImplicitVRLittleEndian
    ds.SOPClassUID, ds.SOPInstanceUID = ds.file_meta.MediaStorageSOPClassUID, ds.file_meta.MediaStorageSOPInstanceUID
    ds.Modality = "RTSTRUCT"
    ds.PatientName, ds.PatientID = slices[0].PatientName, slices[0].PatientID
    ds.StudyInstanceUID, ds.SeriesInstanceUID = slices[0].StudyInstanceUID, generate_uid()
    frame_uid = generate_uid() if args.wrong_frame else slices[0].FrameOfReferenceUID
    ds.FrameOfReferenceUID = frame_uid
    ds.StructureSetLabel = "test"
    frame = Dataset()
    frame.FrameOfReferenceUID = frame_uid
    ds.ReferencedFrameOfReferenceSequence = Sequence([frame])
    ds.StructureSetROISequence = Sequence()
    ds.ROIContourSequence = Sequence()
    for number, (name, contours) in enumerate(rois.items(), start=1):
        roi = Dataset()
        roi.ROINumber, roi.ROIName, roi.ReferencedFrameOfReferenceUID = number, name, frame_uid
        ds.StructureSetROISequence.append(roi)
        item = Dataset()
        item.ReferencedROINumber = number
        item.ContourSequence = Sequence()
        for s, points in contours:
            contour = Dataset()
            image = Dataset()
            image.ReferencedSOPClassUID, image.ReferencedSOPInstanceUID = s.SOPClassUID, s.SOPInstanceUID
            contour.ContourImageSequence = Sequence([image])
            contour.ContourGeometricType = "CLOSED_PLANAR"
            contour.NumberOfContourPoints = len(points)
            contour.ContourData = [f"{v:.4f}" for p in points for v in p]
            item.ContourSequence.append(contour)
        ds.ROIContourSequence.append(item)
    ds.is_little_endian, ds.is_implicit_VR = True, True
    ds.save_as(os.path.join(args.folder, "rtstruct.dcm"), write_like_original=False)


if __name__ == "__main__":
    main()
