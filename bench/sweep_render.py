#!/usr/bin/env python3
"""One render of bench/sweep.py, in a Python subprocess of its own that imports bpy.

    python bench/sweep_render.py SPEC

SPEC is a JSON object bench/sweep.py writes: the .blend, the mode, the size,
the warm-up frames, the extension package and the user folder it is
installed into, and where the outcome goes. The package is installed (or
enabled) as ``tools/render.py`` does; with ``install_only`` that is all.
Otherwise the file is opened, the engine selected and the still rendered;
the outcome (status, the render's seconds, the pixels with NaN or Inf per
pass) is written as JSON to the spec's ``result``.
"""

from __future__ import annotations

import json
import os
import re
import sys
import time

REPO_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TOOLS = os.path.join(REPO_ROOT, "tools")

GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD", "VOLUME"}
# Blender's default camera: looking down from the front right.
DEFAULT_CAMERA_ROTATION = (1.1093, 0.0, 0.8149)


def visible_corners(bpy, depsgraph):
    """World-space corners of the bounding boxes of all visible geometry (N, 3)."""
    import numpy as np
    corners = []
    for inst in depsgraph.object_instances:
        ob = inst.object
        if ob.type not in GEOMETRY_TYPES or ob.original.hide_render:
            continue
        box = np.array([tuple(c) for c in ob.bound_box], float)
        m = np.array(inst.matrix_world, float)
        corners.append(box @ m[:3, :3].T + m[:3, 3])
    if not corners:
        return np.zeros((0, 3))
    pts = np.concatenate(corners)
    return pts[np.isfinite(pts).all(axis=1)]


def frame_camera(bpy, scene) -> str:
    """Make the scene camera frame every visible object; what was done, in words."""
    import numpy as np
    from mathutils import Euler
    depsgraph = bpy.context.evaluated_depsgraph_get()
    pts = visible_corners(bpy, depsgraph)
    cam = scene.camera
    if cam is None or cam.type != 'CAMERA':
        data = bpy.data.cameras.new("SweepCamera")
        cam = bpy.data.objects.new("SweepCamera", data)
        scene.collection.objects.link(cam)
        cam.rotation_euler = Euler(DEFAULT_CAMERA_ROTATION)
        cam.location = (7.36, -6.93, 4.96)
        scene.camera = cam
        what = "added a camera"
    else:
        # Keep where it looks, drop what would move it at render time.
        world = cam.matrix_world.copy()
        cam.parent = None
        cam.constraints.clear()
        cam.animation_data_clear()
        cam.data.animation_data_clear()
        cam.matrix_world = world
        what = "moved the scene camera"
    if len(pts) == 0:
        return what + " (no visible geometry to frame)"
    bpy.context.view_layer.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    location, scale = cam.camera_fit_coords(depsgraph, [float(x) for x in pts.ravel()])
    cam.location = location
    if cam.data.type == 'ORTHO':
        cam.data.ortho_scale = scale
    bpy.context.view_layer.update()
    forward = -np.array(cam.matrix_world.to_3x3().col[2], float)
    depth = (pts - np.array(cam.matrix_world.translation, float)) @ forward
    near, far = float(depth.min()), float(depth.max())
    size = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) or 1.0
    cam.data.clip_end = max(cam.data.clip_end, 1.5 * far + 0.1 * size)
    cam.data.clip_start = min(cam.data.clip_start, max(0.5 * near, 1e-4 * size, 1e-5))
    return what


def non_finite(path: str) -> tuple[int, int, int, dict]:
    """Pixels of a multilayer EXR with NaN, with Inf and with either in any
    pass, and the passes that hold them ({pass: pixels})."""
    import numpy as np
    import OpenEXR
    shape, nan, inf, per_pass = None, None, None, {}    # per pixel of the first part
    with OpenEXR.File(path, separate_channels=True) as exr:
        for part in exr.parts:
            for name, channel in part.channels.items():
                values = np.asarray(channel.pixels, np.float32)
                if nan is None:
                    shape = values.shape
                    nan, inf = np.zeros(shape, bool), np.zeros(shape, bool)
                if values.shape == shape:
                    nan |= np.isnan(values)
                    inf |= np.isinf(values)
                count = int((~np.isfinite(values)).sum())
                if count:
                    layer_pass = name.rsplit(".", 1)[0]
                    per_pass[layer_pass] = max(per_pass.get(layer_pass, 0), count)
    if nan is None:
        return 0, 0, 0, {}
    return int(nan.sum()), int(inf.sum()), int((nan | inf).sum()), per_pass


def worker(spec: dict) -> int:
    """Render spec['blend'] in spec['mode']; write the outcome to spec['result']."""
    sys.path.insert(0, TOOLS)
    import render as render_tool  # tools/render.py: the installation as `make render` does it

    user_resources = spec["user_resources"]
    os.environ["BLENDER_USER_RESOURCES"] = user_resources
    site_packages = render_tool.extension_site_packages(user_resources)
    os.makedirs(site_packages, exist_ok=True)
    sys.path.insert(0, site_packages)
    import bpy
    with render_tool.install_lock(user_resources):
        pkg_id = render_tool.extension_id_and_zip()[0]
        render_tool.install_or_enable(bpy, pkg_id, spec["package"], user_resources)
    if spec.get("install_only"):
        return 0

    def finish(outcome: dict) -> None:
        with open(spec["result"] + ".tmp", "w") as fh:
            json.dump(outcome, fh)
        os.replace(spec["result"] + ".tmp", spec["result"])

    try:
        bpy.ops.wm.open_mainfile(filepath=spec["blend"], load_ui=False)
    except RuntimeError as exc:
        # Errors while reading (e.g. sequencer strips Blender drops) raise
        # here although the file was opened; `blender -b` carries on too.
        if os.path.normcase(os.path.abspath(bpy.data.filepath)) != os.path.normcase(spec["blend"]):
            finish({"status": "failed", "error": "could not open the file: {}".format(
                str(exc).strip().splitlines()[0])})
            return 1
        print("[sweep] opened with errors: {}".format(exc), flush=True)
    scene = bpy.context.scene
    render = scene.render
    render.engine = render_tool.ENGINE_ID
    render.resolution_x, render.resolution_y = spec["size"]
    render.resolution_percentage = 100
    settings = scene.restir_gi
    settings.mode = spec["mode"]
    settings.warmup_frames = spec["warmup"]
    if spec["samples"]:
        settings.samples = spec["samples"]
    if spec["threads"]:
        render.threads_mode = 'FIXED'
        render.threads = spec["threads"]
    camera = frame_camera(bpy, scene) if spec["camera"] else None
    if camera:
        print("[sweep] " + camera, flush=True)

    t0 = [time.perf_counter()]

    # A Python exception escaping the engine is printed by Blender, which
    # carries on with an empty image: count it as a failure and stop.
    default_hook = sys.excepthook

    def excepthook(exc_type, exc, tb):
        default_hook(exc_type, exc, tb)
        finish({"status": "failed", "error": "{}: {}".format(exc_type.__name__, exc).splitlines()[0],
                "seconds": round(time.perf_counter() - t0[0], 2)})
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(1)

    sys.excepthook = excepthook
    t0[0] = time.perf_counter()
    try:
        bpy.ops.render.render(write_still=False)
    except RuntimeError as exc:
        # Blender joins the engine's ERROR reports into the message: "Error: ...".
        lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
        first = re.sub(r"^Error:\s*", "", lines[0]) if lines else "render failed"
        finish({"status": "failed", "error": first,
                "seconds": round(time.perf_counter() - t0[0], 2)})
        return 1
    finally:
        sys.excepthook = default_hook
    seconds = round(time.perf_counter() - t0[0], 2)

    # Every pass of the result, as a 32-bit float multilayer EXR, read back
    # for NaN and Inf.
    image_settings = render.image_settings
    if hasattr(image_settings, "media_type"):       # Blender 5.0 and newer
        image_settings.media_type = 'MULTI_LAYER_IMAGE'
    image_settings.file_format = 'OPEN_EXR_MULTILAYER'
    image_settings.color_depth = '32'
    result_image = bpy.data.images['Render Result']
    result_image.save_render(spec["image"], scene=scene)
    if spec["png"]:
        if hasattr(image_settings, "media_type"):
            image_settings.media_type = 'IMAGE'
        image_settings.file_format = 'PNG'
        image_settings.color_depth = '8'
        result_image.save_render(spec["png"], scene=scene)
    nan, inf, bad, bad_passes = non_finite(spec["image"])
    outcome = {"status": "nan" if bad else "rendered", "seconds": seconds,
               "nan_pixels": nan, "inf_pixels": inf, "bad_pixels": bad}
    if bad_passes:
        outcome["bad_passes"] = bad_passes
    if camera:
        outcome["camera"] = camera
    finish(outcome)
    return 0


if __name__ == "__main__":
    sys.exit(worker(json.loads(sys.argv[1])))
