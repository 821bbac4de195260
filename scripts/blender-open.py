"""Open a pneuma breathing.glb in Blender, ready to play: the whole breath in the timeline.

    blender --python scripts/blender-open.py -- out/demo/breathing.glb
    blender -b --python scripts/blender-open.py -- out/demo/breathing.glb --save breathing.blend

Why a script: glTF has no frame range, so Blender's importer leaves the scene at its own
(frames 1-250 at 24 fps, 10 s of a 60 s run); and Debian 12's Blender 3.4 fails on any glTF
imported with the default "Shading: Use Normal Data" (its importer calls numpy's removed np.bool).
This script reads the animation's extent from the file's scene extras (animation_duration_s,
frame_rate_hz, frame_count; docs/formats.md), sets the scene to the run's frame rate before the
import (one Blender frame per pneuma frame), imports with smooth shading (a lung is smooth; the
file's normals are those of a smooth surface too) and sets the timeline to the whole animation.
"""
import json
import struct
import sys

import bpy


def scene_extras(path):
    """The first scene's extras, read from the glb's JSON chunk (no Blender involved)."""
    with open(path, "rb") as f:
        magic, _version, _length = struct.unpack("<4sII", f.read(12))
        chunk_length, chunk_type = struct.unpack("<I4s", f.read(8))
        if magic != b"glTF" or chunk_type != b"JSON":
            raise SystemExit(f"{path}: not a binary glTF (.glb) file")
        document = json.loads(f.read(chunk_length))
    scenes = document.get("scenes") or [{}]
    return scenes[document.get("scene", 0)].get("extras", {})


def main(argv):
    args = argv[argv.index("--") + 1:] if "--" in argv else []
    if not args or args[0].startswith("-"):
        raise SystemExit("usage: blender [-b] --python blender-open.py -- FILE.glb [--save FILE.blend]")
    glb = args[0]
    save = args[args.index("--save") + 1] if "--save" in args[1:] else None
    extras = scene_extras(glb)

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    rate = float(extras.get("frame_rate_hz", 24.0))
    # Blender's importer places glTF time t at frame t * fps (an integer, fps_base ignored).
    scene.render.fps = max(1, round(rate))
    result = bpy.ops.import_scene.gltf(filepath=glb, import_shading="SMOOTH")
    if "FINISHED" not in result:
        raise SystemExit(f"{glb}: Blender could not import the file")

    # Shape-key values are clamped to their sliders (0..1 by default): widen them to the keys, so a
    # breath below the rest shape (negative weight) plays as written.
    for key in bpy.data.shape_keys:
        action = key.animation_data.action if key.animation_data else None
        for curve in action.fcurves if action else []:
            block = key.path_resolve(curve.data_path.rsplit(".", 1)[0])
            values = [point.co[1] for point in curve.keyframe_points]
            block.slider_min = min(0.0, min(values, default=0.0))
            block.slider_max = max(1.0, max(values, default=1.0))

    # At an integer frame rate, Blender's frame k is pneuma's frame k.
    if "animation_duration_s" in extras:
        last = round(float(extras["animation_duration_s"]) * scene.render.fps)
    else:
        ends = [a.frame_range[1] for a in bpy.data.actions]
        last = round(max(ends)) if ends else scene.frame_end
    scene.frame_start = 0
    scene.frame_end = last
    scene.frame_set(0)
    print(f"blender-open: {glb}: frames 0-{last} at {scene.render.fps} frames/s "
          f"({last / scene.render.fps:g} s)")
    if save:
        bpy.ops.wm.save_as_mainfile(filepath=save)


main(sys.argv)
