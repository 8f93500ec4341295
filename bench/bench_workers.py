"""One worker against two, on the corpus scenes, rendered as users render.

    .venv/bin/python bench/bench_workers.py [--frames 9] [--repeats 2] [--scenes room,slit,...]

Each corpus file (example_blends/corpus_*.blend: 320x180, its own pixel
filter and Cycles' bounce limits, its moving camera), and the quick start's
room ("animated": example_blends/room_animated.blend, a box sliding into the
sun while the camera moves: objects move every frame), is rendered as an
animation through ``bpy.ops.render.render(animation=True)`` with Render >
Performance > Threads fixed at 1, then at 2 (on Linux the second worker is a
twin process, core/workers/forked.py), in the ReSTIR biased mode (one frame of
resampling per animation frame, --warmup frames for the first) and in path
tracing (--pt-samples per frame). Frame times run from render_pre to render_post
(export included). Per scene and mode: the first frame (a fresh start: the
still's warm-up frames in one loop, as F12 renders them), the median of the
frames after it (animation frames), and the speed-ups of two workers. The
setups alternate over --repeats; medians over all.
"""

import argparse
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import ROOT, load_addon, render_frames

SCENES = ("room", "slit", "glossy", "courtyard", "emitters", "animated")
FILES = {"animated": "room_animated.blend"}     # the others: corpus_<name>.blend
MODES = (("RESTIR_BIASED", "ReSTIR biased"), ("PATH", "path tracing"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=9)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--pt-samples", type=int, default=1, help="path tracing: samples per frame")
    ap.add_argument("--warmup", type=int, default=16, help="ReSTIR: warm-up frames of the first frame")
    args = ap.parse_args()
    load_addon()

    print(f"320x180, frames 1-{args.frames}, {args.repeats} repeats, ReSTIR warm-up {args.warmup}, "
          f"path tracing {args.pt_samples} spp; ms per frame (medians)\n")
    print("| scene | mode | first frame, 1 worker | 2 workers | speed-up | later frames, 1 worker | "
          "2 workers | speed-up |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    ups = {"first": [], "later": []}
    for name in args.scenes.split(","):
        blend = ROOT / "example_blends" / FILES.get(name, f"corpus_{name}.blend")
        for mode, label in MODES:
            first = {1: [], 2: []}
            later = {1: [], 2: []}
            for rep in range(args.repeats):
                for threads in ((1, 2) if rep % 2 == 0 else (2, 1)):
                    def setup(scene, threads=threads, mode=mode):
                        scene.render.engine = "RESTIR_GI"
                        scene.render.threads_mode = "FIXED"
                        scene.render.threads = threads
                        scene.restir_gi.mode = mode
                        scene.restir_gi.samples = args.pt_samples if mode == "PATH" else 1
                        scene.restir_gi.warmup_frames = args.warmup

                    _, seconds, reports = render_frames(blend, list(range(1, args.frames + 1)), setup)
                    if reports:
                        print(f"  ({name}, {label}, {threads} workers) reports: {reports[:3]}")
                    first[threads].append(seconds[1])
                    later[threads] += [seconds[f] for f in range(2, args.frames + 1)]
            f1, f2 = (statistics.median(first[t]) * 1000 for t in (1, 2))
            l1, l2 = (statistics.median(later[t]) * 1000 for t in (1, 2))
            ups["first"].append(f1 / f2)
            ups["later"].append(l1 / l2)
            print(f"| {name} | {label} | {f1:.0f} | {f2:.0f} | {f1 / f2:.2f}x | {l1:.0f} | {l2:.0f} | "
                  f"{l1 / l2:.2f}x |", flush=True)
    for key, text in (("first", "first frames"), ("later", "later frames")):
        v = ups[key]
        print(f"\n{text}: speed-up {min(v):.2f}x-{max(v):.2f}x, geometric mean "
              f"{statistics.geometric_mean(v):.2f}x")


if __name__ == "__main__":
    main()
