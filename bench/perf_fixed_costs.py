#!/usr/bin/python3
"""CPU-seconds of a warm `pneuma run` by stage, the work done once a run (whatever the output grid)
apart from the work per voxel of it (#50; BENCHMARKS.md, "The 2 mm grid's fixed costs"), from a
`perf record -F HZ --call-graph dwarf` profile: each sample goes to the first stage (in this order)
whose pattern matches any frame of its stack (dwarf stacks: TBB's worker threads keep their frames).
Usage: perf script -F comm,tid,time,ip,sym,dso -i FILE.perf | bench/perf_fixed_costs.py HZ"""
import re
import sys
from collections import Counter

STAGES = [  # (stage, pattern on a frame); the first matching stage wins
 ("self-intersection check (check_no_fold)", r"check_no_fold|self_intersect|Box_intersection|Polygon_mesh_processing"),
 ("field cache read (field-*.h5)", r"load_field|load_or_compute|H5[A-Z]|hdf5"),
 ("label map: read + inflate", r"read_label_map|read_itk_image|NiftiImageIO|nifti_image_load|gzread|znzread"),
 ("label map: other scans in compile (edges_touched etc.)", r"edges_touched|SurfaceSource"),
 ("rest lungs' mask on the label map's grid (VoxelScene)", r"rest_lungs|VoxelScene::VoxelScene"),
 ("rest label map's lung volume (lung_volume_m3 of labels())", r"lung_volume_m3"),
 ("body field build (BodyMotion)", r"BodyMotion::BodyMotion|convolve|steepest_gradient"),
 ("compression (libdeflate)", r"libdeflate"),
 ("SHA-256", r"Sha256|SHA256|sha256"),
 ("body lookups (Frame)", r"BodyMotion::Frame"),
 ("rasterise: rest tets (forward + Jacobian)", r"rasterize_rest|forward_dvf_with_jacobian"),
 ("rasterise: deformed tets (pull-back)", r"pullback_dvf"),
 ("label warp", r"warp_labels"),
 ("Jacobian outside", r"jacobian"),
 ("writing files (fill, direct I/O)", r"write_nifti|write_dvf|write_image|DirectFile|WriteQueue"),
 ("compile (rest)", r"model::compile|make_model|runner::prepare"),
 ("physiology", r"physiology|CVODE|cvode|CV[A-Z]"),
 ("kernel", r"\[kernel"),
]
hz = float(sys.argv[1])
c = Counter()
stack = []
def flush():
    if not stack: return
    for name, pat in STAGES:
        if any(re.search(pat, f) for f in stack): c[name] += 1; break
    else: c["other"] += 1
    stack.clear()
for line in sys.stdin:
    if not line.strip(): flush()
    elif line.startswith(("\t", " ")): stack.append(line.strip())
flush()
ONCE = {  # the stages done once a run, whatever the output grid
    "self-intersection check (check_no_fold)", "field cache read (field-*.h5)", "label map: read + inflate",
    "label map: other scans in compile (edges_touched etc.)", "rest lungs' mask on the label map's grid (VoxelScene)",
    "rest label map's lung volume (lung_volume_m3 of labels())", "body field build (BodyMotion)", "compile (rest)",
    "physiology"}
tot = sum(c.values())
for name, _ in STAGES + [("other", "")]:
    print(f"  {'once ' if name in ONCE else '     '}{name:60} {c[name] / hz:6.2f} CPU-s")
once = sum(v for k, v in c.items() if k in ONCE)
print(f"  {'(once a run)':65} {once / hz:6.2f} CPU-s")
print(f"  {'(the rest: per voxel of the output grid)':65} {(tot - once) / hz:6.2f} CPU-s")
print(f"  {'(all samples)':65} {tot / hz:6.2f} CPU-s")
