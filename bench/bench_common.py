"""Shared by the benchmarks: load the add-on from this tree, export a .blend,
render frames of a .blend through bpy as a user does (bench/equal_time.py)."""

import contextlib
import importlib.util
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "bench" / "out"
SCALE = 1.0         # render_frames renders at this multiple of each file's resolution


def load_addon():
    """bpy with the add-on registered from this source tree (as package restir_gi)."""
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="restir-bench-"))
    import bpy  # noqa: F401
    if "restir_gi" not in sys.modules:
        spec = importlib.util.spec_from_file_location("restir_gi", ROOT / "__init__.py",
                                                      submodule_search_locations=[str(ROOT)])
        module = importlib.util.module_from_spec(spec)
        sys.modules["restir_gi"] = module
        spec.loader.exec_module(module)
        module.register()
    return sys.modules["restir_gi"]


def median_ms(fn, repeats):
    """Median milliseconds of ``repeats`` calls of fn()."""
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return statistics.median(out) * 1000


def export_blend(path, scale=1.0):
    """core.Scene of a .blend file's scene at its resolution times ``scale``."""
    load_addon()
    import bpy
    from restir_gi.restir_addon.export import export_scene
    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    r = scene.render
    w = max(1, int(r.resolution_x * r.resolution_percentage / 100 * scale))
    h = max(1, int(r.resolution_y * r.resolution_percentage / 100 * scale))
    core_scene, _ = export_scene(bpy.context.evaluated_depsgraph_get(), w, h)
    return core_scene


# ---------------------------------------------------------------- renders through bpy

LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)


def luminance(img):
    return img[..., :3] @ LUMA


@contextlib.contextmanager
def captured_output(log_path):
    """Send what Blender prints (progress lines, reports) to ``log_path``
    (appended) instead of the terminal; yields a list that holds the report
    lines ("Error: ...", "Warning: ...") and tracebacks afterwards."""
    found = []
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    Path(log_path).parent.mkdir(parents=True, exist_ok=True)
    log = open(log_path, "ab")
    start = log.tell()
    os.dup2(log.fileno(), 1)
    os.dup2(log.fileno(), 2)
    try:
        yield found
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        for fd in (1, 2):
            os.dup2(saved[fd - 1], fd)
            os.close(saved[fd - 1])
        log.close()
        with open(log_path, "rb") as f:
            f.seek(start)
            text = f.read().decode(errors="replace")
        found += [line for line in text.splitlines()
                  if line.startswith(("Error", "Warning", "Traceback", "ERROR"))
                  or "Exception" in line or "render failed" in line]


def pin_camera(scene, frame):
    """Remove the scene camera's animation, leaving it at its pose of ``frame``."""
    scene.frame_set(frame)
    cam = scene.camera
    pose = cam.matrix_world.copy()
    cam.animation_data_clear()
    cam.matrix_world = pose
    scene.frame_set(frame)


def pin_objects(scene, frame):
    """Remove the animation of every object but the camera, leaving each at
    its pose of ``frame`` (renders that stand for independent samples of
    that frame's scene)."""
    import bpy
    scene.frame_set(frame)
    poses = {ob.name: ob.matrix_world.copy() for ob in bpy.data.objects
             if ob.animation_data is not None and ob != scene.camera}
    for name, pose in poses.items():
        ob = bpy.data.objects[name]
        ob.animation_data_clear()
        ob.matrix_world = pose
    scene.frame_set(frame)


def read_passes(path, names):
    """{name: (H, W, C) float32, bottom row first} of the passes ``names``
    (e.g. "Combined", "Denoising Albedo") of a multilayer EXR that Blender
    wrote: RGB(A) passes as RGB, vectors as XYZ, values as (H, W, 1)."""
    import OpenEXR
    out = {}
    with OpenEXR.File(str(path), separate_channels=True) as f:
        channels = {}
        for part in f.parts:
            channels.update(part.channels)
    for name in names:
        for ids in ("RGB", "XYZ", "Z", "V"):
            keys = [f"ViewLayer.{name}.{c}" for c in ids]
            if all(k in channels for k in keys):
                out[name] = np.stack([channels[k].pixels for k in keys], axis=2)[::-1].astype(np.float32)
                break
        else:
            raise ValueError(f"no pass {name!r} in {path}")
    return out


def render_frames(blend, frames, setup, pin=None, log_path=None, scene_start=None, passes=None,
                  hold=None):
    """Open ``blend``, optionally pin its camera at frame ``pin`` (and with
    ``hold`` every other animated object at that frame's pose), call
    ``setup(scene)``, and render ``frames`` (consecutive) as a user does:
    ``bpy.ops.render.render(animation=True)`` into 32-bit OpenEXR files. The
    scene's frame range becomes ``frames``, or with ``scene_start`` keeps its
    end and starts there while the job covers ``frames`` (as
    ``blender -f A..B``: a chunk of a farm render).

    Returns ({frame: (H, W, 3) linear image, bottom row first},
    {frame: seconds from render_pre to render_post}, [report lines]). With
    ``passes`` (pass names besides Combined) the files are multilayer and
    each frame's entry is {pass name: read_passes' array}, Combined included."""
    import bpy
    from restir_gi.core.camera.film import read_exr
    start, seconds = {}, {}

    def pre(sc, *_):
        start[sc.frame_current] = time.perf_counter()

    def post(sc, *_):
        seconds[sc.frame_current] = time.perf_counter() - start[sc.frame_current]

    log_path = log_path or OUT / "blender.log"
    OUT.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="restir-bench-") as tmp, \
            captured_output(log_path) as reports:
        bpy.ops.wm.open_mainfile(filepath=str(blend), load_ui=False)
        scene = bpy.context.scene
        if pin is not None:
            pin_camera(scene, pin)
        if hold is not None:
            pin_objects(scene, hold)
        setup(scene)
        if SCALE != 1.0:
            scene.render.resolution_percentage = max(1, round(scene.render.resolution_percentage * SCALE))
        if scene_start is None:
            scene.frame_start, scene.frame_end, scene.frame_step = frames[0], frames[-1], 1
        else:
            scene.frame_start, scene.frame_step = scene_start, 1
            scene.frame_end = max(scene.frame_end, frames[-1])
        r = scene.render
        r.use_file_extension, r.use_overwrite, r.use_placeholder = True, True, False
        s = r.image_settings
        if passes:
            s.media_type, s.file_format = 'MULTI_LAYER_IMAGE', 'OPEN_EXR_MULTILAYER'
            s.color_mode, s.color_depth = 'RGBA', '32'
        else:
            s.media_type, s.file_format, s.color_mode, s.color_depth = 'IMAGE', 'OPEN_EXR', 'RGB', '32'
        r.filepath = os.path.join(tmp, "frame_####")
        bpy.app.handlers.render_pre.append(pre)
        bpy.app.handlers.render_post.append(post)
        try:
            result = bpy.ops.render.render(animation=True, scene=scene.name,
                                           frame_start=frames[0], frame_end=frames[-1])
        finally:
            bpy.app.handlers.render_pre.remove(pre)
            bpy.app.handlers.render_post.remove(post)
        if result != {'FINISHED'}:
            raise RuntimeError(f"render of {blend} did not finish: {result}; see {log_path}")
        images = {}
        for f in frames:
            path = os.path.join(tmp, f"frame_{f:04d}.exr")
            if not os.path.isfile(path) or f not in seconds:
                raise RuntimeError(f"frame {f} of {blend} was not written; see {log_path}")
            images[f] = read_passes(path, ("Combined",) + tuple(passes)) if passes else read_exr(path)
            for name, img in (images[f].items() if passes else (("Combined", images[f]),)):
                if not np.isfinite(img).all():
                    raise RuntimeError(f"frame {f} of {blend} has non-finite pixels ({name})")
    return images, seconds, reports
