"""Driver run inside a real Blender window by tests/e2e/test_real_window.py
(tools/real_blender.py): what a user does on first use of the engine.

At start (Solid shading) it lists the engines the Render Engine dropdown
offers and picks ReSTIR GI, with the Properties editor on the Render tab;
it shows the Material tab of a mesh and reads the material's preview icon
REAL_PREVIEW_WAIT seconds later (material.png);
REAL_RENDERED seconds after start it switches every 3D view to Rendered
through the camera, overlays off; REAL_MOVE seconds after start it moves the
camera and a mesh from a timer and waits until a frame that includes both
edits is published and drawn (before_move.png, after_move.png); at
REAL_F12 seconds it renders F12 and
writes the image; then it opens the Preferences on Add-ons, renders a few
animation frames headless with ``blender -b FILE -E RESTIR_GI -a`` and
quits. It takes its own screenshots of the window (solid.png, rendered.png
just before F12, preferences.png) into REAL_OUT. Every step prints a line
starting with DRIVER, read back from blender.log (tools/real_blender_driver.py)."""

import faulthandler
import gc
import glob
import os
import signal
import subprocess
import sys
import threading
import time

import bpy

# tools/real_blender.py copies tools/real_blender_driver.py beside this script.
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from real_blender_driver import OUT, grab, say, say_versions, step

# Stacks for a viewport that stops following the edits (see followed): this
# process's threads, and the twin processes' (forked from it, they inherit
# the handler).
faulthandler.register(signal.SIGUSR1, all_threads=True)

RENDERED_AT = float(os.environ.get("REAL_RENDERED", "4"))
F12_AT = float(os.environ.get("REAL_F12", "14"))
MOVE_AT = float(os.environ.get("REAL_MOVE", "9"))
MOVE_WAIT = 25.0        # seconds to wait for the frame that shows the edits
STALL_DUMP = 8.0        # after this long without it, the stacks go to blender.log
PREVIEW_WAIT = float(os.environ.get("REAL_PREVIEW_WAIT", "5"))
ENGINE = "RESTIR_GI"


def areas(kind):
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == kind:
                yield window, area


def screenshot(name):
    """The whole screen as the user sees it, into OUT/name."""
    grab(name)
    say("screenshot", name)


@step
def pick_engine():
    scene = bpy.context.scene
    screenshot("solid.png")
    # The dropdown lists Blender's own engines and every registered RenderEngine.
    items = [getattr(cls, "bl_idname", cls.__name__) for cls in bpy.types.RenderEngine.__subclasses__()]
    say("dropdown", ",".join(items))
    scene.render.engine = ENGINE
    for _, area in areas("PROPERTIES"):
        area.spaces.active.context = "RENDER"
    say("engine", scene.render.engine)
    for window, area in areas("VIEW_3D"):
        say("area", area.x, area.y, area.width, area.height, window.height)


@step
def material_tab():
    """The Properties editor on the Material tab of a mesh with a material:
    its slot list shows the material's preview icon, which Blender asks the
    engine to render (bl_use_preview)."""
    ob = next(o for o in bpy.context.scene.objects if o.type == "MESH" and o.active_material is not None)
    bpy.context.view_layer.objects.active = ob
    ob.select_set(True)
    say("material", ob.name, ob.active_material.name)
    bpy.app.timers.register(show_material_tab, first_interval=1.0)    # tabs follow on the next redraw


@step
def show_material_tab():
    for _, area in areas("PROPERTIES"):
        area.spaces.active.context = "MATERIAL"
    mat = bpy.context.view_layer.objects.active.active_material
    mat.preview_ensure()
    started = time.time()

    seen = {}

    def filled():
        """When the icon and the large preview (the Preview panel's) first
        hold an image: how long the engine's previews took (the file stores
        none; Blender renders them in a job beside the UI)."""
        p = mat.preview
        for kind, pixels in (("icon", p.icon_pixels_float), ("image", p.image_pixels_float)):
            if kind not in seen and len(pixels) and sum(pixels) / len(pixels) > 0.02:
                seen[kind] = time.time() - started
                size = tuple(p.icon_size if kind == "icon" else p.image_size)
                say("preview_seconds", kind, f"{size[0]}x{size[1]}", f"{seen[kind]:.2f}")
        return 0.05 if len(seen) < 2 and time.time() - started < PREVIEW_WAIT else None
    bpy.app.timers.register(step(filled), first_interval=0.05)
    bpy.app.timers.register(material_preview, first_interval=PREVIEW_WAIT)


@step
def material_preview():
    mat = bpy.context.view_layer.objects.active.active_material
    icon = mat.preview.icon_pixels_float
    size = tuple(mat.preview.icon_size)
    mean = float(sum(icon) / max(len(icon), 1))
    screenshot("material.png")
    say("preview", f"{size[0]}x{size[1]}", f"{mean:.4f}")
    for _, area in areas("PROPERTIES"):
        area.spaces.active.context = "RENDER"


@step
def rendered_viewport():
    for _, area in areas("VIEW_3D"):
        space = area.spaces.active
        space.shading.type = "RENDERED"
        space.region_3d.view_perspective = "CAMERA"
        space.overlay.show_overlays = False
    say("viewport", "rendered")


def viewport_session():
    """The engine's ViewportSession (the engine's Python instance is not
    reachable from bpy)."""
    return next((o for o in gc.get_objects() if type(o).__name__ == "ViewportSession"), None)


motion = {}


@step
def move():
    """The camera turns a little and a mesh slides, as a user's edits do."""
    screenshot("before_move.png")
    session = viewport_session()
    motion["serial"] = session.frame_serial if session else -1
    scene = bpy.context.scene
    scene.camera.rotation_euler.z += 0.04
    ob = next(o for o in scene.objects if o.type == "MESH" and o.visible_get() and o.animation_data is None
              and o.dimensions.length < 3.0)
    ob.location.x += 0.3
    motion["object"] = ob.name
    motion["t"] = time.time()
    motion["published"] = []
    if session is not None:
        threading.Thread(target=watch_frames, args=(session, motion["published"]), daemon=True).start()
    bpy.app.timers.register(edits_queued, first_interval=0.5)


def watch_frames(session, published):
    """(a thread) When each frame generation was published: the main
    thread's timers can be held up by other steps (a screenshot), this
    thread only by the GIL."""
    last, end = None, time.time() + MOVE_WAIT
    while time.time() < end:
        generation = session.frame_generation
        if generation != last:
            published.append((time.time(), generation))
            last = generation
        time.sleep(0.005)


@step
def edits_queued():
    """Half a second on: view_update and view_draw have handed both edits to
    the session; from now on its generation covers them."""
    session = viewport_session()
    motion["generation"] = session.generation
    bpy.app.timers.register(followed, first_interval=0.05)


@step
def followed():
    session = viewport_session()
    waited = time.time() - motion["t"]
    if session.frame_generation < motion["generation"] and waited < MOVE_WAIT:
        if waited > STALL_DUMP and not motion.get("dumped"):
            motion["dumped"] = True
            dump_stacks()
        return 0.05
    time.sleep(0.3)     # the redraw watcher's tick and the draw (redraw.py), then the grab
    bpy.app.timers.register(step(after_move), first_interval=0.3)
    # The first frame that included both edits, as the watching thread saw it.
    waited = next((t for t, g in motion["published"] if g >= motion["generation"]), motion["t"] + waited) \
        - motion["t"]
    say("motion", f"{waited:.2f}", motion["object"], session.frame_serial - motion["serial"],
        session.frame_generation >= motion["generation"])
    return None


def dump_stacks():
    """Python stacks of this process and of its children into blender.log."""
    say("stalled: stacks follow")
    for stat in glob.glob("/proc/[0-9]*/stat"):
        try:
            with open(stat) as f:
                fields = f.read().split()
        except OSError:
            continue
        if int(fields[3]) == os.getpid():
            os.kill(int(fields[0]), signal.SIGUSR1)
    faulthandler.dump_traceback(all_threads=True)


def after_move():
    screenshot("after_move.png")


@step
def f12():
    scene = bpy.context.scene
    screenshot("rendered.png")
    scene.render.filepath = os.path.join(OUT, "f12.png")
    scene.render.image_settings.file_format = "PNG"
    for _, area in areas("VIEW_3D"):
        area.spaces.active.shading.type = "SOLID"     # the viewport's frames stop
    window = bpy.context.window_manager.windows[0]
    t = time.time()
    with bpy.context.temp_override(window=window):
        bpy.ops.render.render(write_still=True)
    say("f12", f"{time.time() - t:.2f}", os.path.isfile(scene.render.filepath))
    bpy.app.timers.register(preferences, first_interval=0.5)


@step
def preferences():
    ours = [name for name in bpy.context.preferences.addons.keys() if name.endswith(".restir_gi")]
    say("addon", ",".join(ours) or "missing")
    bpy.ops.screen.userpref_show(section="ADDONS")
    bpy.app.timers.register(step(lambda: screenshot("preferences.png")), first_interval=2.0)
    bpy.app.timers.register(batch, first_interval=3.0)


@step
def batch():
    blend = bpy.data.filepath
    pattern = os.path.join(OUT, "anim_####")
    t = time.time()
    proc = subprocess.run([bpy.app.binary_path, "-b", blend, "-E", ENGINE, "-o", pattern, "-F", "PNG",
                           "-s", "1", "-e", "3", "-a"], capture_output=True, text=True, timeout=240)
    with open(os.path.join(OUT, "batch.log"), "w") as fh:
        fh.write(proc.stdout + proc.stderr)
    frames = sorted(f for f in os.listdir(OUT) if f.startswith("anim_"))
    say("batch", proc.returncode, f"{time.time() - t:.2f}", ",".join(frames))
    # A farm's chunk: -s moves frame_start after the file is loaded; the
    # chunk still warms up from the file's first frame (state.animation_start).
    proc = subprocess.run([bpy.app.binary_path, "-b", blend, "-E", ENGINE, "-o", os.path.join(OUT, "chunk_####"),
                           "-F", "PNG", "-s", "3", "-e", "3", "-a"], capture_output=True, text=True, timeout=240)
    with open(os.path.join(OUT, "chunk.log"), "w") as fh:
        fh.write(proc.stdout + proc.stderr)
    frames = sorted(f for f in os.listdir(OUT) if f.startswith("chunk_"))
    warmed = [f for f in (1, 2) if f"chunk warm-up: frame {f} " in proc.stdout + proc.stderr]
    say("chunk", proc.returncode, ",".join(frames), ",".join(map(str, warmed)) or "-")
    say("quitting", "")
    bpy.ops.wm.quit_blender()


say_versions()
bpy.app.timers.register(pick_engine, first_interval=1.5)
bpy.app.timers.register(material_tab, first_interval=2.0)
bpy.app.timers.register(rendered_viewport, first_interval=RENDERED_AT)
bpy.app.timers.register(move, first_interval=MOVE_AT)
bpy.app.timers.register(f12, first_interval=F12_AT)
