"""Unbiased still renders (F12) of the corpus in the core harness: their MSE
against the cached 1024-spp Cycles references of bench/equal_time.py, over
seeds, for each value of one ReSTIRSettings field (by default with each
pixel's Sobol points over the frames and with every frame's uniforms hashed
anew: ``sequences``), in one run; and each one's noise in the direct and the
indirect light.

    .venv/bin/python bench/stills.py [--scenes glossy,emitters,room,courtyard]
                                     [--frames 16] [--seeds 3] [--vary sky_samples=0,4]

The camera is pinned at its frame-1 pose and frame 32 is rendered, as
bench/equal_time.py's still rows do (run that first: it caches the
references in bench/out/refs/). One worker, the file's own settings.
Noise = half the mean squared difference of two seeds' stills.
"""

import argparse
import ast
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import OUT, ROOT, load_addon, pin_camera


def still(ctx, settings, frames, seed):
    from restir_gi.core.render import render_restir
    from restir_gi.core.restir import ReSTIRGI
    t = time.perf_counter()
    out = render_restir(ctx, ReSTIRGI(), dataclasses.replace(settings, seed=seed), 32, frames=frames, fresh=True)
    return out, time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="glossy,emitters,room,courtyard")
    ap.add_argument("--frames", type=int, default=16)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--vary", default="sequences=True,False",
                    help="a ReSTIRSettings field and the values to compare, e.g. sky_samples=0,4")
    args = ap.parse_args()
    field, _, listed = args.vary.partition("=")
    values = [(f"{field}={v}", ast.literal_eval(v)) for v in listed.split(",")]
    load_addon()
    import bpy
    from restir_gi.core import RenderContext
    from restir_gi.core.camera.film import read_exr
    from restir_gi.restir_addon.export import export_scene
    from restir_gi.restir_addon.final import restir_settings

    print(f"unbiased stills of {args.frames} frames, {args.seeds} seeds, one worker")
    print("| scene | setting | MSE | noise | noise of direct | noise of indirect | mean ratio | s per still |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for name in args.scenes.split(","):
        refs = sorted((OUT / "refs").glob(f"{name}_still_f32_*.exr"))
        if not refs:
            print(f"| {name} | no cached reference: run bench/equal_time.py --scenes {name} --cameras still |")
            continue
        ref = read_exr(refs[-1])[..., :3]
        bpy.ops.wm.open_mainfile(filepath=str(ROOT / "example_blends" / f"corpus_{name}.blend"), load_ui=False)
        scene = bpy.context.scene
        pin_camera(scene, 1)
        scene.frame_set(32)
        r = scene.render
        w = int(r.resolution_x * r.resolution_percentage / 100)
        h = int(r.resolution_y * r.resolution_percentage / 100)
        core_scene, _ = export_scene(bpy.context.evaluated_depsgraph_get(), w, h)
        ctx = RenderContext.build(core_scene, threads=1, processes=False)
        base = dataclasses.replace(restir_settings(scene), mode="RESTIR_UNBIASED")
        for label, value in values:
            settings = dataclasses.replace(base, **{field: value})
            images, parts, errs, means, times = [], [], [], [], []
            for seed in range(args.seeds):
                out, seconds = still(ctx, settings, args.frames, 7 + seed)
                img = out.color.reshape(h, w, 3)
                images.append(img)
                parts.append((out.direct.reshape(h, w, 3), out.indirect.reshape(h, w, 3)))
                errs.append(float(((img - ref) ** 2).mean()))
                means.append(float(img.mean() / ref.mean()))
                times.append(seconds)

            def noise(get):
                return np.mean([((get(i) - get(i + 1)) ** 2).mean() / 2 for i in range(args.seeds - 1)])

            print(f"| {name} | {label} | {np.mean(errs):.4g} | {noise(lambda i: images[i]):.4g} | "
                  f"{noise(lambda i: parts[i][0]):.4g} | {noise(lambda i: parts[i][1]):.4g} | "
                  f"{np.mean(means):.4f} | {np.median(times):.1f} |")
        ctx.close()


if __name__ == "__main__":
    main()
