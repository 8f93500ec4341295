"""Cost of shader node evaluation and texture lookups, and their share of a frame.

    .venv/bin/python bench/bench_nodes.py [--blend example_blends/materials_showcase.blend] [--frames 8]

On the textured example (320x180, one worker): the camera rays' hits are
shaded again and again to time, per million hits, (a) the materials of
core/materials/shading.py (graphs run per hit, constant rows gathered) with the
view-dependent BSDF terms (ShadingFrame.at), and (b) the image texture
lookups alone (core/materials/texture.py, Linear filtering) on the same UVs. Then
ReSTIR frames (biased, the file's bounces) are timed with the time spent in
material evaluation inside them, for its share of the frame. Medians over
repeats; this machine is shared, so the numbers vary between runs.
"""

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import ROOT, export_blend, load_addon, median_ms


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blend", default=str(ROOT / "example_blends" / "materials_showcase.blend"))
    ap.add_argument("--frames", type=int, default=8)
    args = ap.parse_args()
    load_addon()
    import bpy
    from restir_gi.core.materials import shading as materials
    from restir_gi.core.camera.projection import generate_rays
    from restir_gi.core.integrators.base import RenderContext, ShadingFrame
    from restir_gi.core.geometry.interaction import surface_hits
    from restir_gi.core.restir import ReSTIRGI, ReSTIRSettings
    from restir_gi.core.materials.texture import lookup

    scene = export_blend(args.blend)
    bounces = bpy.context.scene.restir_gi.max_bounces
    ctx = RenderContext.build(scene, threads=1)
    w, h = scene.width, scene.height
    xy = np.stack(np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5), -1).reshape(-1, 2).astype(np.float32)
    o, d, tmax = generate_rays(scene.camera, w, h, xy)
    hits = ctx.accel.intersect_closest(o, d, tmax)
    surf, _ = surface_hits(scene, o, d, hits)
    n = len(surf)
    sh = materials.shading(scene)
    per_hit = sum(int((surf.material == m).sum()) for m in sh.varying)

    def shade():
        s = surf.subset(np.arange(n))
        ShadingFrame.at(scene, s)

    t_shade = median_ms(shade, 9)
    img = scene.images.get("tiles_color") or next(iter(scene.images.values()))
    uv = np.random.default_rng(0).random((n, 2)).astype(np.float32) * 4
    t_tex = median_ms(lambda: lookup(img, uv, "Linear", "REPEAT"), 9)
    print(f"{Path(args.blend).name} {w}x{h}: {n} camera hits, {per_hit} on per-hit graphs "
          f"({len(sh.varying)} of {len(scene.materials)} materials), one worker\n")
    print("| what | ms per batch | ms per million hits |")
    print("|---|---:|---:|")
    print(f"| materials + view terms (ShadingFrame.at) | {t_shade:.1f} | {t_shade / n * 1e6:.0f} |")
    print(f"| image texture lookups, Linear ({img.tiles[1001].width} px) | {t_tex:.1f} | "
          f"{t_tex / n * 1e6:.0f} |")

    spent = [0.0]
    real = materials.surface_params

    def timed(*a, **k):
        t0 = time.perf_counter()
        try:
            return real(*a, **k)
        finally:
            spent[0] += time.perf_counter() - t0

    materials.surface_params = timed
    restir = ReSTIRGI()
    settings = ReSTIRSettings(mode="RESTIR_BIASED", max_bounces=bounces, seed=1)
    for f in range(3):
        restir.render_frame(ctx, settings, f)
    frames, shares = [], []
    for f in range(3, 3 + args.frames):
        spent[0] = 0.0
        t0 = time.perf_counter()
        restir.render_frame(ctx, settings, f)
        dt = time.perf_counter() - t0
        frames.append(dt)
        shares.append(spent[0] / dt)
    materials.surface_params = real
    ctx.close()
    print(f"\nReSTIR biased frame ({bounces} bounces): median {statistics.median(frames) * 1000:.0f} ms, "
          f"material evaluation {statistics.median(shares) * 100:.0f} % of it")


if __name__ == "__main__":
    main()
