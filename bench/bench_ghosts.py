"""What the running means' ghost and edge tests (core/restir/ghosts.py) cost
per frame of a moving view: median ms of surface_range, parallax and
kept_frames over the whole image, on random values.

    .venv/bin/python bench/bench_ghosts.py [--size 320x180] [--repeats 30]

The whole image's film motion that parallax reads (reprojection.film_shift,
two projections of every pixel's point) is not included.
"""

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import load_addon, median_ms


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", default="320x180")
    ap.add_argument("--repeats", type=int, default=30)
    args = ap.parse_args()
    load_addon()
    from restir_gi.core.restir.ghosts import kept_frames, parallax, surface_range
    w, h = (int(v) for v in args.size.split("x"))
    p = w * h
    rng = np.random.default_rng(0)
    albedo, normal = rng.random((p, 3), np.float32), rng.random((p, 3), np.float32)
    light, shift = rng.random(p, np.float32), rng.random((p, 2), np.float32)
    surface = surface_range(albedo, normal, light, w, h)
    surface.edges, surface.parallax = rng.random(p) < 0.1, parallax(shift, w)
    history = np.concatenate([albedo, normal], axis=1)
    frames = np.full(p, 16.0, np.float32)
    rows = [("surface_range", lambda: surface_range(albedo, normal, light, w, h)),
            ("parallax", lambda: parallax(shift, w)),
            ("kept_frames", lambda: kept_frames(frames, history, surface, light))]
    print(f"{args.size}, median of {args.repeats}:")
    total = 0.0
    for name, fn in rows:
        ms = median_ms(fn, args.repeats)
        total += ms
        print(f"  {name:14s} {ms:6.2f} ms")
    print(f"  {'total':14s} {total:6.2f} ms")


if __name__ == "__main__":
    main()
