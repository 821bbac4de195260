#!/usr/bin/python3
"""CPU-seconds per voxel stage from a `perf record -F HZ -g` profile of `pneuma run` (#50;
BENCHMARKS.md): each sample goes to the first stage whose pattern matches a frame of its stack,
searched from the leaf up; the samples times 1/HZ are CPU-seconds.
Usage: perf script -i FILE.perf | bench/perf_stages.py HZ"""
import re
import sys
from collections import Counter

STAGES = [  # (stage, pattern on a frame's symbol or library), first match from the leaf wins
    ("compression (libdeflate, gzip members)", r"libdeflate|gzip|deflate"),
    ("SHA-256 of the files (manifest.json's digests)", r"libcrypto|sha256|Sha256|EVP_Digest"),
    ("body pull-back: lattice (inverse_field)", r"inverse_field"),
    ("body pull-back: per-voxel inverse", r"BodyMotion::Frame::inverse"),
    ("body field lookups (Frame::displacement)", r"BodyMotion::Frame::displacement"),
    ("the CT's rest lungs, mass-preserving (mass_preserving_ct)", r"mass_preserving_ct"),
    ("the rest tets: forward DVF, Jacobian inside (once a run since the fifth round)",
     r"rasterize_rest|rasterize<pneuma::voxels::forward_dvf|rasterize<pneuma::voxels::jacobian_image"),
    ("rasterising the deformed tets (pull-back), the rest lungs' masks", r"rasterize"),
    ("Jacobian image outside the lungs", r"jacobian_image\(|jacobian_outside"),
    ("CT warp (warp_image)", r"warp_image"),
    ("label warp, lung tissue masks (and the fused warp's CT: warp_labels_and_image)", r"warp_labels|lung_tissue|across_corners"),
    ("the warped lungs' volume (voxels.csv)", r"lung_volume"),
    # Before "converting fields": image/'s own convert (int16 -> int32 / float) would match it.
    ("reading the label map and the CT (image/: inflate, convert)", r"read_itk_image|read_nifti_voxels|image::detail"),
    ("converting fields for files", r"to_file|convert|nifti|Nifti|write_"),
]
KERNEL = r"\[kernel|kallsyms"  # a sample in the kernel (page faults, page-cache writes) is its own stage


def main():
    hz = float(sys.argv[1])
    counts = Counter()
    stack = []

    def flush():
        if not stack:
            return
        if re.search(KERNEL, stack[0]):
            counts["kernel"] += 1
            stack.clear()
            return
        for name, pattern in STAGES:
            if any(re.search(pattern, frame) for frame in stack):
                counts[name] += 1
                break
        else:
            counts["other"] += 1
        stack.clear()

    for line in sys.stdin:
        if not line.strip():
            flush()
        elif line.startswith((" ", "\t")):
            stack.append(line.strip())
    flush()
    total = sum(counts.values())
    for name, _ in STAGES + [("kernel", ""), ("other", "")]:
        print(f"  {name:52} {counts[name] / hz:7.2f} CPU-s")
    print(f"  {'(all samples)':52} {total / hz:7.2f} CPU-s")


if __name__ == "__main__":
    main()
