"""The seed paper's Fig. 1 on the indirect-lit example room: 1 spp path tracing
against ReSTIR GI (biased and unbiased) after 32 frames of resampling, at
(measured) equal time.

    .venv/bin/python bench/fig1.py [--frames 32] [--ref-spp 512] [--repeats 3]

For each method: median ms per frame, MSE against a converged path-traced
reference, the MSE reduction over path tracing, and the equal-time gain
(MSE_PT x t_PT) / (MSE_ReSTIR x t_ReSTIR). Two-bounce light transport
(max_bounces 2) as in the paper's figure. Primary rays go through pixel
centres (filter width 0) for every method and the reference, so the error is
light transport noise, not anti-aliasing. Times and MSEs are medians over
--repeats runs with different seeds, all taken in this one run. Writes
bench/out/fig1.md and bench/out/fig1.png (PT | biased | unbiased | reference).
"""

import argparse
import hashlib
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import OUT, ROOT, export_blend, load_addon  # noqa: E402

BLEND = ROOT / "example_blends" / "room_indirect.blend"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blend", default=str(BLEND))
    ap.add_argument("--frames", type=int, default=32)
    ap.add_argument("--ref-spp", type=int, default=512)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--bounces", type=int, default=2)
    ap.add_argument("--scale", type=float, default=1.0, help="resolution scale of the file's size")
    args = ap.parse_args()

    load_addon()
    from restir_gi.core import RenderContext, RenderSettings, render_frame
    from restir_gi.core.film import read_exr, write_exr, write_png
    from restir_gi.core.restir import BIASED, UNBIASED, ReSTIRGI, ReSTIRSettings

    scene = export_blend(args.blend, args.scale)
    scene.filter_width = 0.0
    w, h = scene.width, scene.height
    ctx = RenderContext.build(scene)
    OUT.mkdir(parents=True, exist_ok=True)

    key = hashlib.sha1(Path(args.blend).read_bytes()).hexdigest()[:10]
    ref_path = OUT / f"reference_{Path(args.blend).stem}_{key}_{w}x{h}_b{args.bounces}_{args.ref_spp}spp.exr"
    if ref_path.exists():
        ref = read_exr(ref_path)
    else:
        print(f"rendering the reference ({args.ref_spp} spp), cached as {ref_path.name} ...", flush=True)
        t0 = time.perf_counter()
        ref = render_frame(ctx, RenderSettings(samples=args.ref_spp, max_bounces=args.bounces, seed=999)).mean()
        write_exr(ref_path, ref)
        print(f"  {time.perf_counter() - t0:.0f} s", flush=True)

    def mse(img):
        return float(((img.reshape(h, w, 3) - ref) ** 2).mean())

    rows, images = {}, {}
    pt_t, pt_e = [], []
    for r in range(args.repeats):
        for _ in range(3 if r == 0 else 1):   # 1 spp frames are short: time a few
            t0 = time.perf_counter()
            img = render_frame(ctx, RenderSettings(samples=1, max_bounces=args.bounces, seed=r)).mean()
            pt_t.append(time.perf_counter() - t0)
        pt_e.append(mse(img))
    rows["Path tracing, 1 spp"] = (statistics.median(pt_t), statistics.median(pt_e))
    images["pt"] = img

    for label, mode in (("ReSTIR GI biased", BIASED), ("ReSTIR GI unbiased", UNBIASED)):
        times, errs = [], []
        for r in range(args.repeats):
            restir = ReSTIRGI()
            settings = ReSTIRSettings(mode=mode, max_bounces=args.bounces, seed=100 + r)
            for f in range(args.frames):
                t0 = time.perf_counter()
                out = restir.render_frame(ctx, settings, f)
                if f > 0:
                    times.append(time.perf_counter() - t0)
            errs.append(mse(out.color))
        rows[label] = (statistics.median(times), statistics.median(errs))
        images[mode] = out.color.reshape(h, w, 3)

    t_pt, e_pt = rows["Path tracing, 1 spp"]
    lines = [f"Scene `{Path(args.blend).name}` at {w}x{h}, max_bounces {args.bounces}, "
             f"{args.frames} frames of resampling, reference {args.ref_spp} spp, "
             f"medians of {args.repeats} seeds.", "",
             "| method | ms / frame | MSE | MSE reduction | equal-time gain | time vs PT |",
             "|---|---:|---:|---:|---:|---:|"]
    for label, (t, e) in rows.items():
        lines.append(f"| {label} | {t * 1000:.0f} | {e:.4f} | {e_pt / e:.1f}x | "
                     f"{(e_pt * t_pt) / (e * t):.1f}x | {t / t_pt:.2f}x |")
    table = "\n".join(lines)
    print(table)
    (OUT / "fig1.md").write_text(table + "\n")
    strip = np.concatenate([images["pt"], images[BIASED], images[UNBIASED], ref], axis=1)
    write_png(OUT / "fig1.png", strip)
    print(f"wrote {OUT / 'fig1.md'} and {OUT / 'fig1.png'}")


if __name__ == "__main__":
    main()
