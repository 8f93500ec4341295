"""Shader node families, ours beside Cycles: the README's contact sheet.

    .venv/bin/python bench/contact_sheet.py [--size 128] [--samples 256] [--bounces 8] [--only NAME ...]

Each family of tests/support/node_families.py (image textures, procedural textures and
converters, shader mixing, bump and normal maps, attributes, emission, an HDRI
world), then each feature of tests/support/feature_scenes.py (panoramic cameras, ...),
is rendered by both engines, twice each with independent seeds. Prints
the mean luminance of each, their ratio and the block chi statistic (near 1
when the engines agree up to noise; tests/oracle/test_nodes_vs_cycles.py asserts the
same at 64x64). Writes bench/out/contact_sheet.png: one row per family, ours
on the left, Cycles in the middle, their difference (x4, grey = equal) on the
right.
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
    ap.add_argument("--only", nargs="*", help="families or features to render (default: all)")
    args = ap.parse_args()
    load_addon()
    from support.blender_util import compare_with_cycles, open_example, set_resolution
    from support.feature_scenes import FEATURES
    from support.node_families import FAMILIES
    from restir_gi.core.camera.film import write_png

    OUT.mkdir(parents=True, exist_ok=True)
    builders = {**FAMILIES, **FEATURES}
    names = args.only or list(builders)
    print(f"Cornell box {args.size}x{args.size}, {args.samples} spp, {args.bounces} bounces, "
          "two renders per engine")
    print("| family | ours | Cycles | ratio | block chi | seconds (4 renders) |")
    print("|---|---:|---:|---:|---:|---:|")
    rows = []
    for name in names:
        scene = open_example("cornell_box.blend")
        set_resolution(scene, args.size, args.size)
        builders[name](scene)
        t0 = time.perf_counter()
        r = compare_with_cycles(scene, args.samples, args.bounces, clamp=1.0)
        print(f"| {name} | {r['ours_mean']:.4f} | {r['cycles_mean']:.4f} | {r['ratio']:.4f} "
              f"| {r['chi']:.2f} | {time.perf_counter() - t0:.0f} |", flush=True)
        diff = np.clip(0.5 + 4.0 * (r["ours"] - r["cycles"]), 0, 1) ** 2.2   # grey after encoding
        rows.append(np.concatenate([r["ours"], r["cycles"], diff], axis=1))
    path = OUT / ("contact_sheet.png" if not args.only else f"contact_sheet_{'_'.join(names)}.png")
    write_png(path, np.concatenate(rows[::-1], axis=0))
    print(f"wrote {path} (rows top to bottom: {', '.join(names)}; ours | Cycles | difference x4)")


if __name__ == "__main__":
    main()
