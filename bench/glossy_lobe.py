"""Where a glossy scene's ReSTIR frame is noisy, and what reusing the glossy
lobe over neighbours could give (docs/plan.md, issue 9).

    .venv/bin/python bench/glossy_lobe.py [--scene glossy] [--seeds 4] [--lobe diffuse]

split: one frame's variance (unbiased, Cycles' 12/4/4 bounces, temporal cap
4, accumulation off, frame 12, over seeds) of the direct light and of the
indirect light, as rendered (the glossy lobe's light by path reuse over
neighbours, core/restir/glossy_reuse.py), without path reuse (each pixel's
own one-path estimate), and without the glossy lobe's light at all
(initial.py's term zeroed, no reuse); with each one's median frame time and
its glossy pass's (one worker).

reuse: for the pixels with a glossy lobe, the glossy lobe's light from one
frame's initial samples (sample points on surfaces; sky samples are left
out), estimated from the pixel's own sample alone, and from its own and K
neighbours' samples as path reuse with the balance heuristic,
sum_j f_g(x1, x2_j) G_j Lo_j V_j / sum_l p_l(x2_j), each p_l the area
density of pixel l's direction sampler (its own source density through the
reconnection Jacobian) times the visibility of x2_j from pixel l's point:
K + K (K - 1) shadow rays per pixel, unbiased. Variance over seeds, and the
means. Not what the renderer does: what a change to it could reach.
--lobe diffuse: the same for the diffuse lobe of every pixel, sky samples
included (what the reservoirs carry).
"""

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import ROOT, export_blend, load_addon

LUM = np.array([0.2126, 0.7152, 0.0722])
NEIGHBOURS = {"4 at 3 px": [(-3, 0), (3, 0), (0, -3), (0, 3)],
              "8 at 3-4 px": [(-4, 0), (4, 0), (0, -4), (0, 4), (-3, -3), (3, 3), (-3, 3), (3, -3)],
              "4 at 8 px": [(-8, 0), (8, 0), (0, -8), (0, 8)]}


def split(ctx, seeds):
    import time

    import restir_gi.core.restir as restir_mod
    from restir_gi.core.integrators.bounces import Bounces
    from restir_gi.core.restir import ReSTIRGI, ReSTIRSettings
    own = restir_mod.initial_samples
    out = {}
    for label, reuse_on, zero in (("as rendered (path reuse of the glossy lobe)", True, False),
                                  ("without path reuse (own one-path estimate)", False, False),
                                  ("without the glossy lobe's light", False, True)):
        if zero:
            def without_glossy(*a, **k):
                res, direct, glossy = own(*a, **k)
                return res, direct, glossy * 0
            restir_mod.initial_samples = without_glossy
        frames, times, glossy_times = [], [], []
        try:
            for seed in seeds:
                restir = ReSTIRGI()
                st = ReSTIRSettings(mode="RESTIR_UNBIASED", max_bounces=Bounces(12, 4, 4, 12), seed=seed,
                                    accumulate=1, temporal_M_cap=4.0, glossy_reuse=reuse_on)
                for f in range(12):
                    t = time.perf_counter()
                    r = restir.render_frame(ctx, st, 100 + f)
                    times.append(time.perf_counter() - t)
                    glossy_times.append(restir.last_timings["glossy"])
                frames.append((r.direct @ LUM, r.indirect @ LUM))
        finally:
            restir_mod.initial_samples = own
        direct, indirect = (np.array([f[k] for f in frames]) for k in (0, 1))
        out[label] = (float(direct.var(axis=0, ddof=1).mean()), float(indirect.var(axis=0, ddof=1).mean()),
                      float(indirect.mean()), 1000 * float(np.median(times)), 1000 * float(np.median(glossy_times)))
    return out


def reuse(ctx, pixel_filter, seeds, offsets, diffuse=False):
    """(variance own, variance reused, mean own, mean reused, pixels) over
    the pixels with a glossy lobe (diffuse: every pixel, the diffuse lobe)."""
    from restir_gi.core.bsdfs import bsdf
    from restir_gi.core.integrators.base import shadow_rays
    from restir_gi.core.integrators.bounces import Bounces
    from restir_gi.core.restir.gbuffer import trace_rows
    from restir_gi.core.restir.initial import COSINE, InitialSampling, _source_pdf, initial_samples
    from restir_gi.core.sampling.warps import INV_PI
    from restir_gi.core.util.vectors import dot, to_local
    w, h = ctx.scene.width, ctx.scene.height
    runs = []
    for seed in seeds:
        gb = trace_rows(ctx, seed, 5, pixel_filter, True, 0, w * h, None)
        res, _, _ = initial_samples(ctx, gb, seed, 5, 0, InitialSampling(Bounces(12, 4, 4, 12)))
        surf, fr, n = gb.surf, gb.frame, len(gb.index)
        row_of = np.full(w * h, -1)
        row_of[gb.index] = np.arange(n)
        x2, n2, lo = res.x2[gb.index], res.n2[gb.index], res.lo[gb.index]
        usable_sample = ((res.prim2[gb.index] >= 0) | diffuse) & (res.M[gb.index] > 0)
        glossy = np.ones(n, bool) if diffuse else fr.params.p_spec > 0

        def area_density(l, x, nx):  # noqa: E741 (pixel l, as in the formula above)
            """Density of pixel rows l's direction sampler at points x (normals nx), per area."""
            to = x - surf.p[l]
            d2 = np.maximum(dot(to, to), 1e-12)
            wi = to / np.sqrt(d2)[:, None]
            wl = to_local(wi, fr.t[l], fr.b[l], surf.ns[l]).astype(np.float32)
            ok = (dot(wi, surf.ng[l]) > 0) == (wl[:, 2] > 0)
            p = _source_pdf(fr.params.subset(l), fr.wo_local[l], wl, COSINE)
            return np.where(ok, p, 0.0) * np.abs(dot(wi, nx)) / d2

        px, py = gb.index % w, gb.index // w
        cand = [np.arange(n)]
        for dx, dy in offsets:
            qx, qy = px + dx, py + dy
            inside = (qx >= 0) & (qx < w) & (qy >= 0) & (qy < h)
            cand.append(np.where(inside, row_of[np.clip(qy, 0, h - 1) * w + np.clip(qx, 0, w - 1)], -1))
        cand = np.stack(cand, 1)
        usable = (cand >= 0) & usable_sample[np.maximum(cand, 0)]
        own, shared = np.zeros(n), np.zeros(n)
        rows = np.nonzero(glossy)[0]
        for c in range(cand.shape[1]):
            i = rows[usable[rows, c]]
            j = cand[i, c]
            x, nx = x2[j], n2[j]
            to = x - surf.p[i]
            d2 = np.maximum(dot(to, to), 1e-12)
            wi = (to / np.sqrt(d2)[:, None]).astype(np.float32)
            wl = to_local(wi, fr.t[i], fr.b[i], surf.ns[i]).astype(np.float32)
            f = bsdf.evaluate(fr.params.subset(i), fr.wo_local[i], wl)
            fd = fr.params.diffuse[i] * ((wl[:, 2] > 0) * INV_PI)[:, None]
            f = fd if diffuse else np.maximum(f - fd, 0.0)
            value = (f * lo[j]) @ LUM * np.abs(wl[:, 2]) * np.abs(dot(wi, nx)) / d2
            if c > 0:       # a neighbour's sample point may be hidden from this pixel
                o, d, tmax = shadow_rays(ctx, surf.p[i], surf.ng[i], wi, np.sqrt(d2).astype(np.float32))
                value = value * ~ctx.accel.occluded(o, d, tmax)
            total = np.zeros(len(i))
            for lc in range(cand.shape[1]):
                l = cand[i, lc]  # noqa: E741
                has = np.nonzero(l >= 0)[0]
                dens = area_density(l[has], x[has], nx[has])
                if lc not in (0, c) and len(has):
                    # Pixel l's sampler reaches x only if x is visible from it:
                    # without this the means came out 0.4-1 % low here (and
                    # 2-5 % on the courtyard's diffuse lobe).
                    lp = surf.p[l[has]]
                    to_l = x[has] - lp
                    dl = np.sqrt(np.maximum(dot(to_l, to_l), 1e-12))
                    o, d, tmax = shadow_rays(ctx, lp, surf.ng[l[has]], (to_l / dl[:, None]).astype(np.float32),
                                             dl.astype(np.float32))
                    dens = dens * ~ctx.accel.occluded(o, d, tmax)
                total[has] += dens
            np.add.at(shared, i, np.where(total > 0, value / np.maximum(total, 1e-30), 0.0))
            if c == 0:
                p0 = area_density(i, x, nx)
                own[i] += np.where(p0 > 0, value / np.maximum(p0, 1e-30), 0.0)
        image = [np.zeros(w * h), np.zeros(w * h), np.zeros(w * h, bool)]    # pixels seen differ by seed
        for a, v in zip(image, (own, shared, glossy)):
            a[gb.index] = v
        runs.append(image)
    own = np.array([r[0] for r in runs])
    shared = np.array([r[1] for r in runs])
    sel = np.logical_and.reduce([r[2] for r in runs])
    return (float(own[:, sel].var(axis=0, ddof=1).mean()), float(shared[:, sel].var(axis=0, ddof=1).mean()),
            float(own[:, sel].mean()), float(shared[:, sel].mean()), int(sel.sum()))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="glossy", help="corpus scene (example_blends/corpus_NAME.blend)")
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--lobe", choices=("glossy", "diffuse"), default="glossy")
    args = ap.parse_args()
    load_addon()
    from restir_gi.core import RenderContext
    from restir_gi.core.camera.projection import PixelFilter
    scene = export_blend(ROOT / "example_blends" / f"corpus_{args.scene}.blend")
    ctx = RenderContext.build(scene, threads=1, processes=False)
    seeds = list(range(1, args.seeds + 1))
    try:
        print(f"corpus_{args.scene}.blend {scene.width}x{scene.height}, seeds {seeds}\n")
        print("| one frame (frame 12) | variance of the direct light | of the indirect light | its mean "
              "| frame ms | glossy pass ms |")
        print("|---|---:|---:|---:|---:|---:|")
        for label, (vd, vi, mi, t, tg) in split(ctx, seeds).items():
            print(f"| {label} | {vd:.4g} | {vi:.4g} | {mi:.5g} | {t:.0f} | {tg:.0f} |")
        what = "diffuse lobe, initial samples" if args.lobe == "diffuse" else "glossy lobe, initial samples on surfaces"
        print(f"\n| {what} | pixels | variance | mean |")
        print("|---|---:|---:|---:|")
        first = True
        for label, offsets in NEIGHBOURS.items():
            v_own, v_shared, m_own, m_shared, count = reuse(ctx, PixelFilter(scene.filter_width), seeds, offsets,
                                                            diffuse=args.lobe == "diffuse")
            if first:
                print(f"| own sample | {count} | {v_own:.4g} | {m_own:.4g} |")
                first = False
            print(f"| own + {label} (balance heuristic) | {count} | {v_shared:.4g} ({v_own / v_shared:.1f}x lower) "
                  f"| {m_shared:.4g} |")
    finally:
        ctx.close()


if __name__ == "__main__":
    main()
