"""The seed paper's Fig. 1 on the indirect-lit example room: 1 spp path tracing
against ReSTIR GI (biased and unbiased) after 32 frames of resampling, at
(measured) equal time.

    .venv/bin/python bench/fig1.py [--frames 32] [--ref-spp 512] [--repeats 3]

For each method: median ms per frame, MSE against a converged path-traced
reference (and the part of it due to the direct light, from the spread of the
unbiased direct-light pass over seeds), the MSE reduction over path tracing,
and the equal-time gain (MSE_PT x t_PT) / (MSE_ReSTIR x t_ReSTIR), with the
time ratio taken from path-traced frames timed between the ReSTIR frames. Two-bounce light transport
(max_bounces 2) as in the paper's figure. Primary rays go through pixel
centres (filter width 0) for every method and the reference, so the error is
light transport noise, not anti-aliasing. Each ReSTIR frame is its own image
(no accumulation of frames), as in the paper. Times and MSEs are medians over
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
from bench_common import OUT, ROOT, export_blend, load_addon

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
    from restir_gi.core.camera.film import read_exr, write_exr, write_png
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

    def pt_frame(seed):
        t0 = time.perf_counter()
        img = render_frame(ctx, RenderSettings(samples=1, max_bounces=args.bounces, seed=seed)).mean()
        return img, time.perf_counter() - t0

    # Path tracing's error over independent seeds; its time is taken between
    # the ReSTIR frames below, so both see the same load on a shared machine.
    pt_e = []
    for r in range(args.repeats):
        img, _ = pt_frame(r)
        pt_e.append(mse(img))
    images = {"pt": img}

    rows = {}
    pt_t_all = []
    for label, mode in (("ReSTIR GI biased", BIASED), ("ReSTIR GI unbiased", UNBIASED)):
        times, pt_t, errs, directs = [], [], [], []
        for r in range(args.repeats):
            restir = ReSTIRGI()
            # accumulate=1: the paper's estimator, each frame on its own (the
            # engine's running mean over frames is measured by equal_time.py).
            settings = ReSTIRSettings(mode=mode, max_bounces=args.bounces, seed=100 + r, accumulate=1,
                                      light_samples=16)
            for f in range(args.frames):
                t0 = time.perf_counter()
                out = restir.render_frame(ctx, settings, f)
                if f > 0:
                    times.append(time.perf_counter() - t0)
                    pt_t.append(pt_frame(1000 + f)[1])
            errs.append(mse(out.color))
            directs.append(out.direct.reshape(h, w, 3))
        # Direct light is unbiased, so two independent runs differ by twice
        # its variance: that estimates its share of the error.
        pairs = [(a, b) for i, a in enumerate(directs) for b in directs[i + 1:]]
        e_direct = float(np.mean([((a - b) ** 2).mean() / 2 for a, b in pairs])) if pairs else float("nan")
        rows[label] = (statistics.median(times), statistics.median(errs), e_direct,
                       statistics.median(times) / statistics.median(pt_t))
        pt_t_all += pt_t
        images[mode] = out.color.reshape(h, w, 3)

    t_pt, e_pt = statistics.median(pt_t_all), statistics.median(pt_e)
    lines = [f"Scene `{Path(args.blend).name}` at {w}x{h}, max_bounces {args.bounces}, "
             f"{args.frames} frames of resampling, reference {args.ref_spp} spp, "
             f"medians of {args.repeats} seeds. Path-traced frames are timed between the "
             f"ReSTIR frames; 'time vs PT' is the ratio of the medians of each run.", "",
             "| method | ms / frame | MSE | of which direct light | MSE reduction | equal-time gain | time vs PT |",
             "|---|---:|---:|---:|---:|---:|---:|",
             f"| Path tracing, 1 spp | {t_pt * 1000:.0f} | {e_pt:.4f} | - | 1.0x | 1.0x | 1.00x |"]
    for label, (t, e, e_d, ratio) in rows.items():
        lines.append(f"| {label} | {t * 1000:.0f} | {e:.4f} | {e_d:.4f} | {e_pt / e:.1f}x | "
                     f"{e_pt / (e * ratio):.1f}x | {ratio:.2f}x |")
    table = "\n".join(lines)
    print(table)
    (OUT / "fig1.md").write_text(table + "\n")
    strip = np.concatenate([images["pt"], images[BIASED], images[UNBIASED], ref], axis=1)
    write_png(OUT / "fig1.png", strip)
    print(f"wrote {OUT / 'fig1.md'} and {OUT / 'fig1.png'}")


if __name__ == "__main__":
    main()
