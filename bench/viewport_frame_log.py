"""Frame log of the viewport under edits: where the time from an edit to the
next frame goes.

    .venv/bin/python bench/viewport_frame_log.py [--edit camera|move] [--edits 10] [--no-twin]

Drives restir_addon.viewport.ViewportSession on room_indirect.blend (a
1280x720 viewport at QUARTER scale, the file's viewport settings) with its
render thread running, and makes an edit at a random point of a frame,
--edits times: a 1-degree camera turn, or a 5 cm move of the MovingBox
object. Prints, in seconds since the start, every frame (with its pass
timings), every abandoned frame, every fork and every abandon handed to the
twin process (core/workers/forked.py, Twin.abandon), then the latencies
from each edit to the first frame that includes it.
"""

import argparse
import dataclasses
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from bench_common import ROOT, load_addon

BLEND = ROOT / "example_blends" / "room_indirect.blend"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--edit", choices=("camera", "move"), default="camera")
    ap.add_argument("--edits", type=int, default=10)
    ap.add_argument("--no-twin", action="store_true", help="the viewport's passes on threads")
    ap.add_argument("--seed", type=int, default=3)
    args = ap.parse_args()

    load_addon()
    import bpy
    vp = sys.modules["restir_gi"].restir_addon.viewport.session
    from restir_gi.restir_addon.viewport.draw import session_settings
    from restir_gi.core.workers import forked
    from support.blender_util import Recorder      # imports restir_gi: after load_addon

    bpy.ops.wm.open_mainfile(filepath=str(BLEND))
    settings = session_settings(bpy.context.scene)
    log = []
    t0 = time.perf_counter()

    def now():
        return time.perf_counter() - t0

    step, abandon, start = vp.ViewportSession.render_step, forked.Twin.abandon, forked.Twin.start

    def logged_step(self, *a, **k):
        t = now()
        try:
            done = step(self, *a, **k)
        except Exception as e:
            log.append(("abandoned", t, now(), type(e).__name__))
            raise
        passes = {k: round(v * 1000) for k, v in self.restir.last_timings.items()}
        log.append(("frame", t, now(), f"generation {self.frame_generation} ms {passes}"))
        return done

    def logged_abandon(self, fingerprint, state):
        t = now()
        kept = abandon(self, fingerprint, state)
        log.append(("abandon", t, now(), "twin kept" if kept else "twin ended"))
        return kept

    def logged_start(*a, **k):
        t = now()
        twin = start(*a, **k)
        if twin is not None and twin.leader:
            log.append(("fork", t, now(), ""))
        return twin

    vp.ViewportSession.render_step = logged_step
    forked.Twin.abandon = logged_abandon
    forked.Twin.start = staticmethod(logged_start)
    if args.no_twin:
        vp.ViewportSession.twin_process = False

    recorder = Recorder()
    bpy.app.handlers.depsgraph_update_post.append(recorder)
    session = vp.ViewportSession(mode="RESTIR_BIASED", scale="QUARTER", max_bounces=settings["max_bounces"],
                                 restir=settings["restir"], samples=0, seed=settings["seed"],
                                 denoise_start=settings["denoise_start"])
    session.resize(1280, 720)
    session.sync(bpy.context.evaluated_depsgraph_get())
    for _ in range(4):
        session.render_step()
    steady = []
    for _ in range(5):
        t = time.perf_counter()
        session.render_step()
        steady.append(time.perf_counter() - t)
    rng = np.random.default_rng(args.seed)
    box = bpy.data.objects["MovingBox"]
    session.start()
    latencies = []
    for i in range(args.edits):
        session.wait_for_frame()
        time.sleep(rng.uniform(0, statistics.median(steady)))     # the edit lands mid-frame
        sign = 1 if i % 2 else -1
        t = now()
        log.append(("edit", t, t, args.edit))
        if args.edit == "move":
            box.location.x += 0.05 * sign
            bpy.context.view_layer.update()
            session.sync(bpy.context.evaluated_depsgraph_get(), recorder.take())
        else:
            cam = session.view
            a = math.radians(1.0) * sign
            rot = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
            m = cam.to_world.copy()
            m[:3, :3] = rot @ m[:3, :3]
            session.set_view(dataclasses.replace(cam, to_world=m))
        session.wait_for_frame(session.generation, timeout=60)
        latencies.append(now() - t)
    session.close()
    bpy.app.handlers.depsgraph_update_post.remove(recorder)
    print(f"steady frames (s): {', '.join(f'{s:.3f}' for s in steady)}")
    print(f"{'event':10s} {'start':>8s} {'end':>8s} {'took':>6s}")
    for kind, a, b, what in log:
        print(f"{kind:10s} {a:8.3f} {b:8.3f} {b - a:6.3f} {what}")
    print(f"edit to frame (s): {', '.join(f'{x:.3f}' for x in latencies)}; "
          f"median {statistics.median(latencies):.3f}")


if __name__ == "__main__":
    main()
