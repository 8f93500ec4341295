"""The still viewport's error over time, headless: the session of
restir_addon/viewport/session.py on the example room through its camera, frames
rendered one after another (as its render thread does), each frame's
display values (the file's view transform, 8 bits, bilinear upscaling
as drawn) compared with a converged reference.

    .venv/bin/python bench/viewport_refine.py [--size 1044x587] [--seconds 41]
        [--clock 1.0,0.45,1.45,5.0] [--reference PNG]

The reference defaults to bench/out/viewport_window/reference_ours.png
(ReSTIR GI unbiased, converged, written by bench/viewport_window.py at the
camera frame's size in the real window: 1044x587, the default --size).
Prints, per frame, the time, the stage and size, and the MSE in 8-bit
values; then the MSE of the frame shown at 5, 10, 20, 30 and 40 s. Tunes
what bench/viewport_window.py measures in the real window without one: with
--clock the frames are timed by the window's frame times (the real window
runs slower than this headless loop: it draws, and its export runs on the
main thread), so settings are compared frame for frame at the times the
window would show them.
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import OUT, ROOT, load_addon

BLEND = ROOT / "example_blends" / "room_animated.blend"


def srgb(x):
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", default="1044x587")
    parser.add_argument("--seconds", type=float, default=41.0)
    parser.add_argument("--reference", default=str(OUT / "viewport_window" / "reference_ours.png"))
    parser.add_argument("--mode", default="RESTIR_BIASED")
    parser.add_argument("--step-frames", type=int, help="viewport_progress.STEP_FRAMES instead of its value")
    parser.add_argument("--carry-frames", type=int, help="resize.CARRY_FRAMES instead of its value")
    parser.add_argument("--clock", help="START,Q,H,F: time the frames by a simulated clock instead of the "
                        "machine's: START seconds to the first frame, then Q, H and F seconds per frame at 1/4, "
                        "1/2 and full resolution (e.g. the real window's, from bench/viewport_window.py's "
                        "blender.log), so a setting can be judged by the window's times on a different machine")
    parser.add_argument("--save", help="write the last frame's display values (8-bit, as compared) to this .npy")
    args = parser.parse_args(argv)
    clock = None
    if args.clock:
        start, *per_frame = (float(v) for v in args.clock.split(","))
        clock = {"t": start, 4: per_frame[0], 2: per_frame[1], 1: per_frame[2]}
    width, height = (int(v) for v in args.size.split("x"))
    load_addon()
    import bpy
    from restir_gi.restir_addon.viewport import draw, session as vp
    from restir_gi.restir_addon.viewport import progress as viewport_progress
    from restir_gi.core.restir import resize
    from restir_gi.core.restir.resize import upscale_bilinear     # as the viewport draws a coarse frame
    if args.step_frames is not None:
        viewport_progress.STEP_FRAMES = args.step_frames
    if args.carry_frames is not None:
        resize.resize_stream.__defaults__ = (args.carry_frames,)
    print(f"STEP_FRAMES {viewport_progress.STEP_FRAMES}, CARRY_FRAMES {resize.resize_stream.__defaults__[0]}")
    ref_img = bpy.data.images.load(args.reference)
    ref_img.colorspace_settings.name = "Non-Color"   # the file's values (a 16-bit PNG reads as linear)
    ref = np.empty(ref_img.size[0] * ref_img.size[1] * 4, np.float32)
    ref_img.pixels.foreach_get(ref)
    ref = ref.reshape(ref_img.size[1], ref_img.size[0], 4)[..., :3]
    assert ref.shape[:2] == (height, width), ref.shape
    ref8 = np.round(ref * 255.0)
    bpy.ops.wm.open_mainfile(filepath=str(BLEND))
    scene = bpy.context.scene
    scene.render.engine = "RESTIR_GI"
    scene.restir_gi.mode = args.mode
    session = vp.ViewportSession(**draw.session_settings(scene))
    session.resize(width, height)
    t0 = time.perf_counter()
    session.sync(bpy.context.evaluated_depsgraph_get())
    shown = []
    while (clock["t"] if clock else time.perf_counter() - t0) < args.seconds:
        if not session.render_step():
            break
        if clock:
            clock["t"] += clock[session.progress.divisor]
        t = clock["t"] if clock else time.perf_counter() - t0
        frame = upscale_bilinear(session.frame[..., :3], width, height)
        err = float(np.mean((np.round(srgb(frame) * 255.0) - ref8) ** 2))
        shown.append((t, err))
        print(f"{t:6.2f} s  {session.status():55s} MSE {err:7.1f}", flush=True)
    if args.save and shown:
        np.save(args.save, np.round(srgb(frame) * 255.0).astype(np.uint8))
    session.close()
    for mark in (5.0, 10.0, 20.0, 30.0, 40.0):
        before = [e for t, e in shown if t <= mark]
        print(f"at {mark:g} s: MSE {before[-1]:.1f}" if before else f"at {mark:g} s: no frame yet")


if __name__ == "__main__":
    main()
