"""Where a ReSTIR GI frame spends its time, next to a 1 spp path-traced frame.

    .venv/bin/python bench/bench_restir.py [--blend ...] [--bounces 2] [--frames 12] [--scale 1]
                                           [--denoise] [--workers 1,2,twin]

For one worker, two worker threads, and two workers of which the second is a
twin process (core/workers/forked.py, the default for render loops on Linux): median
ms per pass over --frames frames of a warmed-up static view
(ReSTIRGI.last_timings: wall time for the G-buffer and the whole frame,
summed worker time for the passes the workers run; with a child process only
the parent's share), and the 1 spp path-traced frame timed between them,
with the ratio of the medians and each setup's speed-up over one worker.
--denoise turns the engine's denoiser on (ReSTIRSettings.denoise): its
column is then its time, and the last column its share of the frame.
"""

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import ROOT, export_blend, load_addon

PASSES = ("gbuffer", "initial", "temporal", "spatial", "glossy", "shading", "denoise", "validation", "total")
SETUPS = {"1": ("1", 1, False), "2": ("2 threads", 2, False), "twin": ("2 (twin process)", 2, True)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blend", default=str(ROOT / "example_blends" / "room_indirect.blend"))
    ap.add_argument("--bounces", type=int, default=2)
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--mode", default="RESTIR_BIASED")
    ap.add_argument("--scale", type=float, default=1.0,
                    help="render at the file's resolution times this (two workers scale better on "
                         "larger images: numpy calls on short arrays hold the GIL for most of their time)")
    ap.add_argument("--denoise", action="store_true", help="with the engine's denoiser on")
    ap.add_argument("--workers", default="1,2,twin", help="setups to time: 1, 2 (threads), twin")
    args = ap.parse_args()

    load_addon()
    from restir_gi.core import RenderContext, RenderSettings, render_frame
    from restir_gi.core.restir import ReSTIRGI, ReSTIRSettings

    scene = export_blend(args.blend, args.scale)
    scene.filter_width = 0.0
    print(f"{Path(args.blend).name} {scene.width}x{scene.height}, {args.mode}, max_bounces "
          f"{args.bounces}, denoiser {'on' if args.denoise else 'off'}, medians of {args.frames} frames (ms)\n")
    print("| workers | " + " | ".join(PASSES) + " | PT 1 spp | ReSTIR / PT | denoise / total |")
    print("|---|" + "---:|" * (len(PASSES) + 3))
    totals = {}
    for label, threads, processes in (SETUPS[k] for k in args.workers.split(",")):
        ctx = RenderContext.build(scene, threads=threads, processes=processes)
        restir = ReSTIRGI()
        settings = ReSTIRSettings(mode=args.mode, max_bounces=args.bounces, seed=1, denoise=args.denoise)
        for f in range(4):
            restir.render_frame(ctx, settings, f)
        rows = {name: [] for name in PASSES}
        pt = []
        # One render loop over the timed frames: with processes, a twin
        # process computes its share of every pass (core/workers/forked.py); it
        # prints nothing and ends with the block.
        with ctx.workers.twin(scene.width * scene.height):
            for f in range(4, 4 + args.frames):
                restir.render_frame(ctx, settings, f)
                for name in PASSES:
                    rows[name].append(restir.last_timings.get(name, 0.0))
                t0 = time.perf_counter()
                render_frame(ctx, RenderSettings(samples=1, max_bounces=args.bounces, seed=f))
                pt.append(time.perf_counter() - t0)
        ctx.close()
        med = {name: statistics.median(v) * 1000 for name, v in rows.items()}
        t_pt = statistics.median(pt) * 1000
        totals[label] = (med["total"], t_pt)
        print(f"| {label} | " + " | ".join(f"{med[name]:.0f}" for name in PASSES)
              + f" | {t_pt:.0f} | {med['total'] / t_pt:.2f}x | "
              + f"{statistics.median(d / t for d, t in zip(rows['denoise'], rows['total'])) * 100:.0f} % |")
    one = totals.get("1")
    if one is not None and len(totals) > 1:
        print("\nspeed-up over one worker (ReSTIR frame, PT frame): "
              + ", ".join(f"{label} {one[0] / t[0]:.2f}x / {one[1] / t[1]:.2f}x"
                          for label, t in totals.items() if label != "1"))


if __name__ == "__main__":
    main()
