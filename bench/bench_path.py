"""Path tracer throughput: the engine's rays per second against raw Embree on
the very same rays, and one frame's time split into export, tracing, shading
and writing, on an example scene rendered through the add-on.

    .venv/bin/python bench/bench_path.py [--blend example_blends/room_indirect.blend]
                                         [--samples 4] [--repeats 3]

All figures are medians over the repeats, taken in one run.
"""

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import ROOT, load_addon


class Recorder:
    """Wraps an Accel to keep a copy of every ray batch it traces."""

    def __init__(self, accel):
        self.accel = accel
        self.batches = []
        self._closest, self._occluded = accel.intersect_closest, accel.occluded
        accel.intersect_closest = self.intersect_closest
        accel.occluded = self.occluded

    def intersect_closest(self, o, d, tmax=None, camera=False):
        self.batches.append(("closest", np.array(o, np.float32), np.array(d, np.float32),
                             None if tmax is None else np.array(tmax, np.float32)))
        return self._closest(o, d, tmax, camera=camera)

    def occluded(self, o, d, tmax):
        self.batches.append(("occluded", np.array(o, np.float32), np.array(d, np.float32),
                             np.array(tmax, np.float32)))
        return self._occluded(o, d, tmax)


def raw_embree_seconds(scene, batches, threads):
    """Replay recorded batches straight through embreex, split over threads."""
    from concurrent.futures import ThreadPoolExecutor
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh
    es = rtcore_scene.EmbreeScene(robust=True)
    TriangleMesh(es, scene.vertices, scene.triangles)
    es.run(np.zeros((1, 3), np.float32), np.float32([[0, 0, 1]]))
    pool = ThreadPoolExecutor(threads)
    start = time.perf_counter()
    for kind, o, d, tmax in batches:
        n = len(o)
        dist = np.full(n, 1e30, np.float32) if tmax is None else tmax.copy()
        bounds = np.linspace(0, n, threads + 1).astype(int)
        if kind == "closest":
            job = lambda a, b: es.run(o[a:b], d[a:b], dist[a:b], output=True)  # noqa: E731
        else:
            job = lambda a, b: es.run(o[a:b], d[a:b], dist[a:b], query="OCCLUDED")  # noqa: E731
        list(pool.map(lambda ab: job(*ab), zip(bounds[:-1], bounds[1:])))
    seconds = time.perf_counter() - start
    pool.shutdown()
    return seconds


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blend", default=str(ROOT / "example_blends" / "room_indirect.blend"))
    ap.add_argument("--samples", type=int, default=4)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--bounces", type=int, default=4)
    args = ap.parse_args()

    addon = load_addon()
    import bpy
    from restir_gi.core import RenderContext, RenderSettings, render_frame
    from restir_gi.restir_addon import final
    from restir_gi.restir_addon.export import export_scene

    bpy.ops.wm.open_mainfile(filepath=args.blend)
    scene = bpy.context.scene
    scene.render.engine = "RESTIR_GI"
    scene.restir_gi.samples = args.samples
    scene.restir_gi.max_bounces = args.bounces
    w = int(scene.render.resolution_x * scene.render.resolution_percentage / 100)
    h = int(scene.render.resolution_y * scene.render.resolution_percentage / 100)

    # 1. Engine rays/s vs raw Embree on the same rays.
    dg = bpy.context.evaluated_depsgraph_get()
    core_scene, _ = export_scene(dg, w, h)
    settings = RenderSettings(samples=args.samples, max_bounces=args.bounces)
    # The rays are recorded on threads (a forked twin's rays would stay in the
    # child) and timed through embreex alone; frames are timed as rendered:
    # one worker, and two (a twin process on Linux, core/workers/forked.py).
    setups = (("1 worker", 1, True), ("2 workers", 2, True))
    engine_rate = {label: [] for label, _, _ in setups}
    raw_rate = {label: [] for label, _, _ in setups}
    ratios = {label: [] for label, _, _ in setups}
    for _ in range(args.repeats):
        ctx = RenderContext.build(core_scene, threads=1, processes=False)
        rec = Recorder(ctx.accel)
        render_frame(ctx, settings)
        ctx.close()
        rays = sum(len(b[1]) for b in rec.batches)
        for label, threads, processes in setups:
            raw_s = raw_embree_seconds(core_scene, rec.batches, threads)
            ctx = RenderContext.build(core_scene, threads=threads, processes=processes)
            t0 = time.perf_counter()
            render_frame(ctx, settings)
            frame_s = time.perf_counter() - t0
            ctx.close()
            engine_rate[label].append(rays / frame_s)
            raw_rate[label].append(rays / raw_s)
            ratios[label].append(frame_s / raw_s)

    # 2. Frame time split, through the add-on's render callback.
    splits = []
    out = tempfile.mkdtemp(prefix="restir-bench-out-")
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = os.path.join(out, "frame")
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        total = time.perf_counter() - t0
        splits.append(dict(final.state.stream_for(scene.name, scene.view_layers[0].name).timings, total=total))

    med = lambda xs: statistics.median(xs)  # noqa: E731
    print(f"scene {Path(args.blend).name} {w}x{h}, {core_scene.triangle_count} triangles, "
          f"{args.samples} spp, {args.bounces} bounces, {args.repeats} repeats (medians)")
    print(f"rays per frame           {rays:,}")
    for label, _, _ in setups:
        print(f"{label:9s}: engine rays/s {med(engine_rate[label]) / 1e6:.2f} M (whole frame time), "
              f"raw embreex {med(raw_rate[label]) / 1e6:.2f} M (same rays, same threads): "
              f"frame = {med(ratios[label]):.1f}x pure Embree time")
    keys = ("export", "trace", "shade", "write")
    total = med([s["total"] for s in splits])
    print("frame time split (s)     " + ", ".join(f"{k} {med([s[k] for s in splits]):.3f}" for k in keys)
          + f", total render call {total:.3f} (trace: the rays of this process; with a twin "
          "process rendering half of each pass, core/workers/forked.py, its rays are not counted)")
    del addon


if __name__ == "__main__":
    main()
