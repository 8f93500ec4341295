"""Equal-time comparison of ReSTIR GI with our path tracing and with Cycles on
the scene corpus (example_blends/corpus_*.blend, make_corpus.py).

    .venv/bin/python bench/equal_time.py [--scenes room,slit] [--frames 32]
        [--ref-spp 1024] [--modes biased,unbiased] [--cameras still,moving] [--quick]
        [--denoise] [--no-cycles]

Everything renders as a user renders: the add-on loaded from this tree, the
file opened with bpy, ``bpy.ops.render.render(animation=True)`` into 32-bit
OpenEXR files. Frame times run from ``render_pre`` to ``render_post`` (scene
export or sync included); medians over frames 2..N (frame 1 carries first-frame
costs). Camera variants: "moving" keeps the file's camera animation, "still"
removes it (the camera stays at its frame-1 pose). Per scene and camera:

* reference: Cycles at --ref-spp, fixed seed, of frame N, cached in
  bench/out/refs/ (key: file sha1, scene, camera, frame, size, spp);
* ReSTIR GI biased / unbiased: frames 1..N with ``warmup_frames`` 1 (frame N is
  the result of N frames of resampling), MSE of frame N; with --denoise also
  with the engine's denoiser (Render Properties > Sampling > Denoise), rows
  "+ denoiser";
* our path tracing, 1 spp, and Cycles at 1 and 16 spp (animated seed): frames
  ending at N with the camera held at its frame-N pose, so that every frame is an
  independent render of the reference's view; MSE = median over the frames.

MSE is over all RGB values. Gain vs PT = (MSE_PT t_PT) / (MSE t). Gain vs
Cycles = MSE_Cycles(t) / MSE, with Cycles' MSE at our frame time t read off its
own curve: log-log interpolation (extrapolation beyond 16 spp) between
(t_1spp, MSE_1spp) and (t_16spp, MSE_16spp), and MSE_1spp for t <= t_1spp.
Mean ratio = mean luminance / the reference's. Black % = share of lit
reference pixels (luminance > 5 % of the reference's mean) that are below 2 %
of the reference's mean in ours. The reference row gives its render time and
its own noise (MSE), estimated from the spread of the 16-spp frames:
var_16 x 16 / ref-spp; every MSE above includes it.

On the still camera, --stills adds still renders (F12) in the unbiased mode
with 16 and 64 warm-up frames: their MSE, and the gains at the time the whole
still took. For those, Cycles renders a still at the samples its curve says
fit in that time (its row follows), and its MSE is taken to our time as
1 / time from there (the reference's noise kept as it is).

Writes bench/out/equal_time.md and bench/out/equal_time_<scene>_<camera>.png
(ReSTIR biased | ReSTIR unbiased | Cycles at our biased frame time | reference;
with --denoise, each ReSTIR picture followed by its denoised one);
--quick (8 frames, reference 64 spp) writes *_quick.* instead. What Blender
prints goes to bench/out/blender.log. --no-cycles leaves out our path tracing
and Cycles but the reference (no gains then): the denoiser's rows against
the raw ones, quickly.
"""

import argparse
import hashlib
import json
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import OUT, ROOT, load_addon, luminance, render_frames  # noqa: E402

SCENES = ("room", "slit", "glossy", "courtyard", "emitters")
MODES = {"biased": "RESTIR_BIASED", "unbiased": "RESTIR_UNBIASED"}
CAMERAS = ("still", "moving")
REF_SEED = 1234
PT_FRAMES = 5
CYCLES_FRAMES = 4
REF_SECONDS = []            # render times of the references rendered in this run


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--frames", type=int, default=None, help="N (default 32; 8 with --quick)")
    ap.add_argument("--ref-spp", type=int, default=None, help="default 1024; 64 with --quick")
    ap.add_argument("--modes", default="biased,unbiased")
    ap.add_argument("--cameras", default="still,moving")
    ap.add_argument("--quick", action="store_true", help="smoke run: 8 frames, 64-spp references")
    ap.add_argument("--stills", default="16,64",
                    help="warm-up frames of the unbiased still renders (F12) on the still camera; '' for none")
    ap.add_argument("--denoise", action="store_true",
                    help="also render each ReSTIR mode with the engine's denoiser on")
    ap.add_argument("--no-cycles", action="store_true",
                    help="no path tracing or Cycles rows but the reference (and no gains or stills)")
    args = ap.parse_args()
    args.frames = args.frames or (8 if args.quick else 32)
    args.ref_spp = args.ref_spp or (64 if args.quick else 1024)
    args.scenes = [s for s in args.scenes.split(",") if s]
    args.modes = [m for m in args.modes.split(",") if m]
    args.cameras = [c for c in args.cameras.split(",") if c]
    args.stills = [int(w) for w in args.stills.split(",") if w]
    for name, given, known in (("scene", args.scenes, SCENES), ("mode", args.modes, MODES),
                               ("camera", args.cameras, CAMERAS)):
        bad = [g for g in given if g not in known]
        if bad:
            ap.error(f"unknown {name}(s) {bad}; known: {', '.join(known)}")
    if args.frames < 3:
        ap.error("--frames must be at least 3")
    return args


# ---------------------------------------------------------------- engine settings

def cycles(spp, seed, animated):
    def setup(scene):
        scene.render.engine = "CYCLES"
        c = scene.cycles
        c.device = "CPU"
        c.samples = spp
        c.seed = seed
        c.use_animated_seed = animated
        c.use_denoising = False
        c.use_adaptive_sampling = False
    return setup


def ours(mode, warmup=None, denoise=False):
    def setup(scene):
        scene.render.engine = "RESTIR_GI"
        s = scene.restir_gi
        s.mode = mode
        s.samples = 1
        s.use_denoising = denoise
        if warmup is not None:
            s.warmup_frames = warmup
    return setup


def mse(img, ref):
    return float(((img - ref) ** 2).mean())


def cycles_mse_at(t, c1, c16):
    """Cycles' MSE at frame time t along its own log-log curve through its
    1-spp and 16-spp points; never below its 1-spp frame time."""
    (t1, e1), (t16, e16) = c1, c16
    if t <= t1 or t16 <= t1:
        return e1
    slope = (math.log(e16) - math.log(e1)) / (math.log(t16) - math.log(t1))
    return math.exp(math.log(e1) + slope * (math.log(t) - math.log(t1)))


def cycles_spp_at(t, t1, t16):
    if t <= t1 or t16 <= t1:
        return 1
    return max(1, round(math.exp((math.log(t) - math.log(t1)) / (math.log(t16) - math.log(t1))
                                 * math.log(16))))


def brightness(img, ref):
    """(mean ratio, black %) of img against the reference."""
    lum, ref_lum = luminance(img), luminance(ref)
    m = float(ref_lum.mean())
    lit = ref_lum > 0.05 * m
    black = float((lum[lit] < 0.02 * m).mean() * 100) if lit.any() else 0.0
    return float(lum.mean()) / m, black


def report(label, reports):
    for line in reports:
        print(f"    [{label}] {line}", flush=True)


# ---------------------------------------------------------------- one scene x camera

def reference(blend, name, camera, args, size):
    """Cached Cycles reference of frame N; (image, seconds to render it)."""
    from restir_gi.core.film import read_exr, write_exr
    sha = hashlib.sha1(blend.read_bytes()).hexdigest()[:12]
    w, h = size
    refs = OUT / "refs"
    stem = f"{name}_{camera}_f{args.frames}_{w}x{h}_{args.ref_spp}spp_{sha}"
    path, meta = refs / f"{stem}.exr", refs / f"{stem}.json"
    if path.exists() and meta.exists():
        return read_exr(path), json.loads(meta.read_text())["seconds"], True
    print(f"  reference: Cycles {args.ref_spp} spp of frame {args.frames} ({camera}) ...", flush=True)
    pin = 1 if camera == "still" else None
    images, seconds, reps = render_frames(blend, [args.frames], cycles(args.ref_spp, REF_SEED, False),
                                          pin=pin)
    report("reference", reps)
    refs.mkdir(parents=True, exist_ok=True)
    write_exr(path, images[args.frames])
    t = seconds[args.frames]
    meta.write_text(json.dumps({"seconds": t, "blend": blend.name, "camera": camera,
                                "frame": args.frames, "spp": args.ref_spp, "seed": REF_SEED}))
    print(f"  reference took {t:.0f} s, cached as {path.relative_to(ROOT)}", flush=True)
    REF_SECONDS.append(t)
    return images[args.frames], t, False


def frame_stats(seconds, skip_first=True):
    frames = sorted(seconds)
    return statistics.median(seconds[f] for f in (frames[1:] if skip_first else frames))


def run_case(name, camera, args):
    blend = ROOT / "example_blends" / f"corpus_{name}.blend"
    n = args.frames
    pin = 1 if camera == "still" else n       # PT / Cycles frames: the view of frame N
    rows, pictures = [], {}

    # Ours, ReSTIR GI: frames 1..N with the variant's camera.
    restir = {}
    for label in args.modes:
        for denoise in (False, True) if args.denoise else (False,):
            key = f"{label} + denoiser" if denoise else label
            images, seconds, reps = render_frames(blend, list(range(1, n + 1)), ours(MODES[label], 1, denoise),
                                                  pin=1 if camera == "still" else None)
            report(key, reps)
            restir[key] = (images[n], frame_stats(seconds))
            print(f"  ReSTIR {key}: {restir[key][1] * 1000:.0f} ms/frame", flush=True)
    h, w = next(iter(restir.values()))[0].shape[:2] if restir else (180, 320)
    ref, ref_s, cached = reference(blend, name, camera, args, (w, h))
    if cached:
        print(f"  reference: cached ({ref_s:.0f} s when rendered)", flush=True)
    if args.no_cycles:
        for label, (img, t) in restir.items():
            e = mse(img, ref)
            ratio, black = brightness(img, ref)
            rows.append([f"ReSTIR {label}", t, e, None, None, ratio, black])
            pictures[label] = img
        rows.append([f"reference {args.ref_spp} spp", ref_s, float("nan"), None, None, 1.0, None])
        pictures["reference"] = ref
        return rows, pictures

    # Our path tracing, 1 spp, and Cycles at 1 and 16 spp: frames ending at N.
    def series(setup, count, label):
        images, seconds, reps = render_frames(blend, list(range(n - count + 1, n + 1)), setup, pin=pin)
        report(label, reps)
        imgs = [images[f] for f in sorted(images)]
        return imgs, frame_stats(seconds), statistics.median(mse(i, ref) for i in imgs)

    pt_imgs, t_pt, e_pt = series(ours("PATH"), PT_FRAMES, "PT")
    c1_imgs, t_c1, e_c1 = series(cycles(1, 1, True), CYCLES_FRAMES, "Cycles 1 spp")
    c16_imgs, t_c16, e_c16 = series(cycles(16, 1, True), CYCLES_FRAMES, "Cycles 16 spp")
    pairs = [(a, b) for i, a in enumerate(c16_imgs) for b in c16_imgs[i + 1:]]
    ref_noise = statistics.mean(mse(a, b) / 2 for a, b in pairs) * 16 / args.ref_spp

    def mean_ratio(imgs):
        return statistics.mean(float(luminance(i).mean()) for i in imgs) / float(luminance(ref).mean())

    for label, (img, t) in restir.items():
        e = mse(img, ref)
        ratio, black = brightness(img, ref)
        rows.append([f"ReSTIR {label}", t, e, (e_pt * t_pt) / (e * t),
                     cycles_mse_at(t, (t_c1, e_c1), (t_c16, e_c16)) / e, ratio, black])
        pictures[label] = img
    # Still renders (F12): one frame after `warmup` frames of resampling, whose
    # mean is the image; the time is the whole render's.
    # Cycles is rendered at the samples that its own curve says fit in that
    # time, and its MSE taken to our time from there as 1 / time (beyond its
    # noise-free part, the reference's own noise): extrapolating its 1-16
    # spp curve to hundreds of samples put it below the reference's noise.
    for warmup in (args.stills if camera == "still" else []):
        images, seconds, reps = render_frames(blend, [n], ours(MODES["unbiased"], warmup), pin=1)
        report(f"still {warmup}", reps)
        img, t = images[n], seconds[n]
        e = mse(img, ref)
        ratio, black = brightness(img, ref)
        spp = cycles_spp_at(t, t_c1, t_c16)
        c_images, c_seconds, reps = render_frames(blend, [n], cycles(spp, 7, False), pin=1)
        report(f"Cycles for still {warmup}", reps)
        t_cy, e_cy = c_seconds[n], mse(c_images[n], ref)
        e_cy_at_t = ref_noise + max(e_cy - ref_noise, 0.0) * t_cy / t
        rows.append([f"F12 still unbiased, {warmup} warm-up (whole render)", t, e, (e_pt * t_pt) / (e * t),
                     e_cy_at_t / e, ratio, black])
        c_ratio, c_black = brightness(c_images[n], ref)
        rows.append([f"Cycles {spp} spp still (for the {warmup} warm-up row)", t_cy, e_cy, None, None,
                     c_ratio, c_black])
    rows.append(["PT 1 spp (ours)", t_pt, e_pt, 1.0, None, mean_ratio(pt_imgs), None])
    rows.append(["Cycles 1 spp", t_c1, e_c1, None, 1.0, mean_ratio(c1_imgs), None])
    rows.append(["Cycles 16 spp", t_c16, e_c16, None, None, mean_ratio(c16_imgs), None])

    # Cycles at the spp that fits in our biased frame time, for the picture.
    t_eq = restir.get("biased", next(iter(restir.values()), (None, t_c1)))[1]
    spp = cycles_spp_at(t_eq, t_c1, t_c16)
    images, seconds, reps = render_frames(blend, [n], cycles(spp, 7, False), pin=pin)
    report("Cycles equal time", reps)
    pictures["cycles"] = images[n]
    ratio, black = brightness(images[n], ref)
    rows.append([f"Cycles {spp} spp (picture)", seconds[n], mse(images[n], ref), None, None, ratio, black])
    rows.append([f"reference {args.ref_spp} spp", ref_s, ref_noise, None, None, 1.0, None])
    pictures["reference"] = ref
    return rows, pictures


# ---------------------------------------------------------------- output

def fmt(v, spec, suffix=""):
    return "-" if v is None else format(v, spec) + suffix


def table(results, args):
    lines = [f"Corpus at 320x180 (files' settings: 12/4/4/12 bounces in both engines, no clamping "
             f"in Cycles), frame N = {args.frames}, reference Cycles {args.ref_spp} spp. "
             f"ms per frame: median of frames 2..N (PT: {PT_FRAMES} frames, Cycles: "
             f"{CYCLES_FRAMES} frames, camera held at frame N; reference: its single frame). "
             f"Reference row's MSE: its own estimated noise.", "",
             "| scene | camera | method | ms / frame | MSE | gain vs PT | gain vs Cycles | "
             "mean ratio | black % |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|"]
    for (name, camera), rows in results.items():
        for method, t, e, g_pt, g_c, ratio, black in rows:
            lines.append(f"| {name} | {camera} | {method} | {t * 1000:.0f} | {e:.4g} | "
                         f"{fmt(g_pt, '.1f', 'x')} | {fmt(g_c, '.1f', 'x')} | {ratio:.3f} | "
                         f"{fmt(black, '.2f')} |")
    # Geometric means of the gains over the scenes, per mode and camera.
    summary = {}
    for (_name, camera), rows in results.items():
        for method, _t, _e, g_pt, g_c, _r, _b in rows:
            if method.startswith("ReSTIR") and g_pt is not None:
                summary.setdefault((method, camera), []).append((g_pt, g_c))
    if summary:
        lines += ["", "| method | camera | scenes | geo. mean gain vs PT | geo. mean gain vs Cycles |",
                  "|---|---|---:|---:|---:|"]
        for (method, camera), gains in summary.items():
            gm = [math.exp(statistics.mean(math.log(g[i]) for g in gains)) for i in (0, 1)]
            lines.append(f"| {method} | {camera} | {len(gains)} | {gm[0]:.1f}x | {gm[1]:.1f}x |")
    return "\n".join(lines)


def main():
    args = parse_args()
    t_start = time.perf_counter()
    load_addon()
    from restir_gi.core.film import write_png
    OUT.mkdir(parents=True, exist_ok=True)
    suffix = "_quick" if args.quick else ""
    results = {}
    for name in args.scenes:
        for camera in args.cameras:
            print(f"{name} / {camera}", flush=True)
            rows, pictures = run_case(name, camera, args)
            results[(name, camera)] = rows
            order = [k for m in ("biased", "unbiased") for k in (m, f"{m} + denoiser")] + ["cycles", "reference"]
            strip = [pictures[k] for k in order if k in pictures]
            png = OUT / f"equal_time_{name}_{camera}{suffix}.png"
            write_png(png, np.concatenate(strip, axis=1))
    text = table(results, args)
    print(text)
    md = OUT / f"equal_time{suffix}.md"
    md.write_text(text + "\n")
    print(f"wrote {md.relative_to(ROOT)} and the pictures; total {time.perf_counter() - t_start:.0f} s "
          f"({len(REF_SECONDS)} references rendered in this run: {sum(REF_SECONDS):.0f} s)")


if __name__ == "__main__":
    main()
