"""Converged comparison with Cycles on the Cornell box: emissive quad, point
light and area light, both engines at the same samples and bounces.

    .venv/bin/python bench/vs_cycles.py [--size 128] [--samples 256] [--bounces 8]

Prints, per light: mean luminance of each engine, their ratio, and the block
chi statistic (squared 8x8-block differences over their variance estimated
from two independent renders per engine: near 1 when the engines agree up to
noise). Writes bench/out/vs_cycles.png (one row per light, ours | Cycles).
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE.parent))
from bench_common import OUT, load_addon  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--bounces", type=int, default=8)
    args = ap.parse_args()
    load_addon()
    import test_vs_cycles as cornell
    from support.blender_util import compare_with_cycles, set_resolution
    from restir_gi.core.camera.film import write_png

    OUT.mkdir(parents=True, exist_ok=True)
    print(f"Cornell box {args.size}x{args.size}, {args.samples} spp, {args.bounces} bounces, "
          "two renders per engine")
    print("| light | ours | Cycles | ratio | block chi | seconds (4 renders) |")
    print("|---|---:|---:|---:|---:|---:|")
    rows = []
    for light in ("emitter", "point", "area"):
        scene = cornell._cornell(light)
        set_resolution(scene, args.size, args.size)
        t0 = time.perf_counter()
        r = compare_with_cycles(scene, args.samples, args.bounces)
        print(f"| {light} | {r['ours_mean']:.4f} | {r['cycles_mean']:.4f} | {r['ratio']:.4f} "
              f"| {r['chi']:.2f} | {time.perf_counter() - t0:.0f} |", flush=True)
        rows.append(np.concatenate([r["ours"], r["cycles"]], axis=1))
    write_png(OUT / "vs_cycles.png", np.concatenate(rows[::-1], axis=0))   # emitter on top
    print(f"wrote {OUT / 'vs_cycles.png'} (rows: emitter, point, area; left ours, right Cycles)")


if __name__ == "__main__":
    main()
