"""Driver run inside a real Blender window by bench/viewport_window.py
(tools/real_blender.py): what a user sees of the rendered viewport.

REAL_MODE=viewport (default): the engine REAL_ENGINE (RESTIR_GI or CYCLES)
is picked, the largest 3D view looks through the camera, fitted to the view
(View > Frame Camera Bounds), overlays, gizmos and tool shelf off; the camera frame's rectangle in
screen pixels is printed, and a crop of it saved (before.png). Then the
view switches to Rendered and a shell, independent of Blender's main
thread, takes screenshots of the whole screen REAL_SHOTS seconds
(comma-separated) after the switch (shot_<s>.png, with their times) and
crops of the camera frame every POLL seconds for POLL_SECONDS (poll_<i>.png
and poll.times: bench/viewport_window.py finds the first image among them);
then Blender quits. With ReSTIR GI the viewport session's own counters are
read too, from a thread (the session is found through the garbage
collector: the engine instance of a viewport is not reachable from bpy):
the time of its first frame, of its first full-resolution frame, and of
each change of stage.

REAL_MODE=reference: renders the file's camera with Cycles in ``blender -b``
at REAL_SIZE (WxH) with REAL_SAMPLES samples, saved through the file's view
transform as reference.png, and quits.

Every step prints a line starting with DRIVER, read back from blender.log
(tools/real_blender_driver.py).
"""

import gc
import os
import subprocess
import sys
import threading
import time
import traceback

import bpy

# tools/real_blender.py copies tools/real_blender_driver.py beside this script.
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from real_blender_driver import OUT, grab, say, say_versions, step

MODE = os.environ.get("REAL_MODE", "viewport")
ENGINE = os.environ.get("REAL_ENGINE", "RESTIR_GI")
SHOTS = [float(s) for s in os.environ.get("REAL_SHOTS", "5,10,20").split(",")]
POLL = 0.25            # seconds between crops of the camera frame (time to first image)
POLL_SECONDS = 6.0
state = {}


def view3d():
    """(window, area, region) of the largest 3D view."""
    best = None
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D" and (best is None or area.width * area.height > best[1].width * best[1].height):
                best = (window, area)
    window, area = best
    region = next(r for r in area.regions if r.type == "WINDOW")
    return window, area, region


def camera_rect(region, rv3d):
    """(x0, y0, x1, y1) of the camera frame in window pixels (origin bottom left)."""
    from bpy_extras.view3d_utils import location_3d_to_region_2d
    scene = bpy.context.scene
    cam = scene.camera
    corners = [cam.matrix_world @ v for v in cam.data.view_frame(scene=scene)]
    pts = [location_3d_to_region_2d(region, rv3d, c) for c in corners]
    xs, ys = [p.x for p in pts], [p.y for p in pts]
    return (region.x + min(xs), region.y + min(ys), region.x + max(xs), region.y + max(ys))


@step
def setup():
    scene = bpy.context.scene
    scene.render.engine = ENGINE
    if ENGINE == "CYCLES":
        scene.cycles.device = "CPU"
    window, area, region = view3d()
    space = area.spaces.active
    space.region_3d.view_perspective = "CAMERA"
    space.overlay.show_overlays = False
    space.show_gizmo = False                # the navigation gizmo and the tool shelf
    space.show_region_toolbar = False       # would lie over the camera frame
    space.shading.type = "SOLID"
    with bpy.context.temp_override(window=window, area=area, region=region):
        bpy.ops.view3d.view_center_camera()
    say("engine", scene.render.engine, scene.frame_current)
    bpy.app.timers.register(measure_rect, first_interval=1.0)


@step
def measure_rect():
    window, area, region = view3d()
    x0, y0, x1, y1 = camera_rect(region, area.spaces.active.region_3d)
    state["rect"] = (x0, y0, x1, y1)
    state["crop"] = (int(x1 - x0), int(y1 - y0), int(x0), int(window.height - y1))
    say("rect", f"{x0:.2f}", f"{y0:.2f}", f"{x1:.2f}", f"{y1:.2f}", window.width, window.height)
    say("region", region.x, region.y, region.width, region.height)
    grab("before.png", state["crop"])
    grab("solid.png")
    bpy.app.timers.register(switch, first_interval=0.5)


@step
def switch():
    """Rendered, and at the same moment a shell that takes the screenshots:
    Blender's timers run on its main thread, which the first sync and the
    render thread's Python can hold up for seconds."""
    _, area, _ = view3d()
    shots = " ".join(
        f"( sleep {s:g}; date +%s.%N > {OUT}/shot_{s:g}.t; import -window root {OUT}/shot_{s:g}.png; date +%s.%N >> {OUT}/shot_{s:g}.t ) &"
        for s in SHOTS)
    w, h, x, y = state["crop"]
    script = (f"{shots} i=0; while [ $i -lt {int(POLL_SECONDS / POLL)} ]; do "
              f"import -window root -crop {w}x{h}+{x}+{y} {OUT}/poll_$i.png; "
              f"echo $i $(date +%s.%N) >> {OUT}/poll.times; i=$((i+1)); sleep {POLL}; done; wait")
    state["t_switch"] = time.time()
    area.spaces.active.shading.type = "RENDERED"
    state["shell"] = subprocess.Popen(["bash", "-c", script])
    say("switched", f"{state['t_switch']:.3f}")
    if ENGINE == "RESTIR_GI":
        threading.Thread(target=watch_session, daemon=True).start()
    bpy.app.timers.register(finish, first_interval=max(SHOTS) + 0.5)


def since():
    return time.time() - state["t_switch"]


def drawn_serial(session):
    """The serial of the session's frame the 3D view last drew (the add-on's
    redraw watcher, restir_addon/viewport/redraw.py, records it); 0 before
    the first draw."""
    module = next((m for name, m in list(sys.modules.items()) if name.endswith("restir_addon.viewport.redraw")), None)
    entry = None if module is None else module.REDRAWS._sessions.get(id(session))
    return entry[1][0] if entry and entry[1] else 0


def watch_session():
    """ReSTIR GI: the session's first frame and first full-resolution frame
    (a thread of the driver: it runs while the main thread is busy)."""
    try:
        session = None
        while session is None and since() < 60:
            session = next((o for o in gc.get_objects() if type(o).__name__ == "ViewportSession"), None)
            time.sleep(0.02)
        state["session"] = session
        while session is not None and since() < max(SHOTS) + 1:
            t = since()
            if "first_frame" not in state and session.frame_serial > 0:
                state["first_frame"] = t
                say("first_frame", f"{t:.2f}", *session.render_size)
            if "first_drawn" not in state and drawn_serial(session) > 0:
                state["first_drawn"] = t
                say("first_drawn", f"{t:.2f}")
            if "full_res" not in state and session.frame_serial > 0 and session.progress.divisor == 1:
                state["full_res"] = t
                say("full_res", f"{t:.2f}", *session.render_size)
            status = session.status()
            if status.split("|")[0] != state.get("status", "").split("|")[0]:
                say("status", f"{t:.2f}", status)
            state["status"] = status
            time.sleep(0.01)
    except Exception:  # noqa: BLE001 -- a thread that only watches: print and stop
        traceback.print_exc()


@step
def finish():
    if state["shell"].poll() is None:
        return 0.2
    for s in SHOTS:
        with open(os.path.join(OUT, f"shot_{s:g}.t")) as fh:      # the grab's start and end
            start, end = (float(v) - state["t_switch"] for v in fh.read().split())
        say("shot", f"{s:g}", f"{start:.2f}-{end:.2f}")
    session = state.get("session")
    if session is not None:
        say("frames", session.work.frames, session.status())
    say("quitting", "")
    bpy.ops.wm.quit_blender()


@step
def reference():
    """Cycles, converged, at the camera frame's size in the window."""
    width, height = (int(v) for v in os.environ["REAL_SIZE"].split("x"))
    samples = int(os.environ.get("REAL_SAMPLES", "1024"))
    expr = ("import bpy; s = bpy.context.scene; s.render.engine = 'CYCLES'; s.cycles.device = 'CPU'; "
            f"s.render.resolution_x = {width}; s.render.resolution_y = {height}; "
            f"s.render.resolution_percentage = 100; s.cycles.samples = {samples}; "
            "s.cycles.use_adaptive_sampling = False; s.cycles.use_denoising = False; "
            "s.render.image_settings.file_format = 'PNG'; s.render.image_settings.color_depth = '16'")
    t = time.time()
    proc = subprocess.run([bpy.app.binary_path, "-b", bpy.data.filepath, "--python-expr", expr,
                           "-o", os.path.join(OUT, "reference_#"), "-F", "PNG",
                           "-f", str(bpy.context.scene.frame_current)], capture_output=True, text=True)
    with open(os.path.join(OUT, "reference.log"), "w") as fh:
        fh.write(proc.stdout + proc.stderr)
    frame = bpy.context.scene.frame_current
    os.replace(os.path.join(OUT, f"reference_{frame}.png"), os.path.join(OUT, "reference.png"))
    say("reference", proc.returncode, f"{time.time() - t:.1f}", f"{width}x{height}", samples)
    say("quitting", "")
    bpy.ops.wm.quit_blender()


say_versions()
if MODE == "reference":
    bpy.app.timers.register(reference, first_interval=1.0)
else:
    bpy.app.timers.register(setup, first_interval=2.0)
