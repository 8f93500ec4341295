"""Peak resident memory of ReSTIR GI renders at large resolutions.

Each render runs in a process of its own (its peak is the process's maximum
resident set, from getrusage): an F12 still (one warm-up frame, as a quick
look) and an animation of --frames frames, through the add-on as a user
renders, on example_blends/room_indirect.blend in the biased mode. Printed
with the bytes per pixel of the state kept between frames (reservoirs,
G-buffer history, running means: core.restir.temporal.state_bytes_per_pixel).

    .venv/bin/python bench/bench_memory.py [--sizes 1920x1080 3840x2160] [--frames 10]
"""

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import OUT, ROOT, captured_output, load_addon

BLEND = ROOT / "example_blends" / "room_indirect.blend"


def child(width, height, frames, bounces):
    """Render in this process and print one JSON line of figures."""
    load_addon()
    import bpy
    from restir_gi.core.restir.temporal import state_bytes_per_pixel
    with captured_output(OUT / "bench_memory.log"), tempfile.TemporaryDirectory() as tmp:
        bpy.ops.wm.open_mainfile(filepath=str(BLEND), load_ui=False)
        scene = bpy.context.scene
        r = scene.render
        r.engine = "RESTIR_GI"
        r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
        s = scene.restir_gi
        s.mode, s.warmup_frames, s.samples, s.max_bounces = "RESTIR_BIASED", 1, 1, bounces
        r.image_settings.file_format = "OPEN_EXR"
        r.filepath = os.path.join(tmp, "f_####")
        t0 = time.perf_counter()
        if frames <= 1:
            bpy.ops.render.render()
        else:
            scene.frame_start, scene.frame_end = 1, frames
            bpy.ops.render.render(animation=True)
        seconds = time.perf_counter() - t0
        # (a still lets its state go when done: the figure, which
        # tests/addon/test_restir_memory.py checks against the arrays held)
        state_bytes = state_bytes_per_pixel() * width * height
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(json.dumps({"peak": peak, "state": state_bytes, "seconds": seconds}))


def measure(width, height, frames, bounces):
    cmd = [sys.executable, __file__, "--child", f"{width}x{height}", "--frames", str(frames),
           "--bounces", str(bounces)]
    out = subprocess.run(cmd, capture_output=True, text=True, check=False)
    for line in reversed(out.stdout.splitlines()):
        if line.startswith("{"):
            return json.loads(line)
    raise RuntimeError(f"{cmd} failed:\n{out.stdout[-2000:]}\n{out.stderr[-2000:]}")


def size(text):
    w, h = text.lower().split("x")
    return int(w), int(h)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", nargs="+", default=["1920x1080", "3840x2160"])
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--bounces", type=int, default=8)
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*size(args.child), args.frames, args.bounces)
        return
    OUT.mkdir(parents=True, exist_ok=True)
    print(f"{BLEND.name}, ReSTIR biased, max_bounces {args.bounces}")
    print("| render | size | peak RSS | state | state bytes/pixel | seconds |")
    print("|---|---|---:|---:|---:|---:|")
    gb = 1024.0 ** 3
    for text in args.sizes:
        w, h = size(text)
        for label, frames in (("still (1 warm-up)", 1), (f"animation, {args.frames} frames", args.frames)):
            m = measure(w, h, frames, args.bounces)
            print(f"| {label} | {w}x{h} | {m['peak'] / gb:.2f} GB | {m['state'] / gb:.2f} GB "
                  f"| {m['state'] / (w * h):.0f} | {m['seconds']:.1f} |", flush=True)


if __name__ == "__main__":
    main()
