"""Converged comparison with Cycles on the Cornell box: emissive quad, point
light and area light, both engines at the same samples and bounces.

    .venv/bin/python bench/vs_cycles.py [--size 128] [--samples 256] [--bounces 8]

Prints, per light: mean luminance of each engine, their ratio, and the block
chi statistic (squared 8x8-block differences over their variance estimated
from two independent renders per engine: near 1 when the engines agree up to
noise). Writes bench/out/vs_cycles_<light>.png (ours | Cycles).
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
    from blender_util import block_means, render_image, set_resolution, setup_cycles, setup_restir
    from restir_gi.core.film import write_png

    OUT.mkdir(parents=True, exist_ok=True)
    print(f"Cornell box {args.size}x{args.size}, {args.samples} spp, {args.bounces} bounces, "
          "two renders per engine")
    print("| light | ours | Cycles | ratio | block chi | ours s | Cycles s |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for light in ("emitter", "point", "area"):
        scene = cornell._cornell(light)
        set_resolution(scene, args.size, args.size)
        imgs, secs = {}, {}
        for name, setup in (("ours", setup_restir), ("cycles", setup_cycles)):
            imgs[name], secs[name] = [], 0.0
            for seed in (1, 2):
                setup(scene, args.samples, seed, args.bounces)
                t0 = time.perf_counter()
                imgs[name].append(render_image(scene))
                secs[name] += time.perf_counter() - t0
        o = [block_means(i, 8) for i in imgs["ours"]]
        c = [block_means(i, 8) for i in imgs["cycles"]]
        om, cm = (o[0] + o[1]) / 2, (c[0] + c[1]) / 2
        var = ((o[0] - o[1]) / 2) ** 2 + ((c[0] - c[1]) / 2) ** 2
        chi = float(((om - cm) ** 2).sum() / var.sum())
        print(f"| {light} | {om.mean():.4f} | {cm.mean():.4f} | {om.mean() / cm.mean():.4f} | {chi:.2f} "
              f"| {secs['ours'] / 2:.1f} | {secs['cycles'] / 2:.1f} |", flush=True)
        ours = (imgs["ours"][0] + imgs["ours"][1]) / 2
        cyc = (imgs["cycles"][0] + imgs["cycles"][1]) / 2
        write_png(OUT / f"vs_cycles_{light}.png", np.concatenate([ours, cyc], axis=1))


if __name__ == "__main__":
    main()
