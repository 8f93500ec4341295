"""Equal-time comparison of ReSTIR GI with our path tracing and with Cycles on
the scene corpus (example_blends/corpus_*.blend, make_corpus.py), raw and
finished by a denoiser.

    .venv/bin/python bench/equal_time.py [--scenes room,slit] [--frames 32]
        [--ref-spp 1024] [--modes biased,unbiased] [--cameras still,moving] [--quick]
        [--no-cycles] [--no-oidn] [--lag-modes biased] [--stills 16,64] [--scale 2]

Needs requirements-bench.txt (pyoidn, flip-evaluator) unless --no-oidn.
Everything renders as a user renders: the add-on loaded from this tree, the
file opened with bpy, ``bpy.ops.render.render(animation=True)`` into 32-bit
OpenEXR files. Frame times run from ``render_pre`` to ``render_post`` (scene
export or sync, and Cycles' denoiser, included); medians over frames 2..N
(frame 1 carries first-frame costs). Camera variants: "moving" keeps the
file's camera animation, "still" removes it (the camera stays at its frame-1
pose). Per scene and camera:

* reference: Cycles at --ref-spp, fixed seed, of frame N, cached in
  bench/out/refs/ (key: file sha1, scene, camera, frame, size, spp);
* ReSTIR GI biased / unbiased: frames 1..N with ``warmup_frames`` 1 (frame N is
  the result of N frames of resampling), MSE of frame N. Three rows each:
  raw (Denoise off); "+ OIDN", the raw frames' Combined, Denoising Albedo and
  Denoising Normal passes through Intel Open Image Denoise (bench/finished.py),
  its time added to the frame's; "+ denoiser", the engine's own (Render
  Properties > Sampling > Denoise, on);
* our path tracing, 1 spp, and Cycles at 1 and 16 spp (animated seed): frames
  ending at N with the camera (and moving objects: the movers' box) held at
  its frame-N pose, so that every frame is an independent render of the
  reference's view; MSE = median over the frames;
* Cycles + OIDN: Cycles with its own Denoise (OIDN, albedo and normal) at 1,
  2, 4, 8, 16 and 32 spp, frames as above.

MSE is over all RGB values; FLIP is mean HDR-FLIP (frame N; Cycles: its last
frame); flicker (still camera) is the mean squared difference between
consecutive frames (ours: N-3..N) over the reference's mean square. Gain vs
PT = (MSE_PT t_PT) / (MSE t). Gain vs Cycles = MSE_Cycles(t) / MSE, Cycles'
MSE at our frame time t read off its own raw curve: log-log interpolation
(extrapolation beyond 16 spp) between (t_1spp, MSE_1spp) and (t_16spp,
MSE_16spp), and MSE_1spp for t <= t_1spp. The "vs Cycles + OIDN" columns
read Cycles + OIDN's curve at t the same way (finished.Curve: its spp at t
from a linear fit of time over spp, never below 1 spp; MSE, FLIP and flicker
interpolated in log-log over spp) and give its MSE / ours, its FLIP / ours,
and our flicker / its. Mean ratio = mean luminance / the reference's. Black
% = share of lit reference pixels (luminance > 5 % of the reference's mean)
that are below 2 % of the reference's mean in ours. The reference row gives
its render time and its own noise (MSE), estimated from the spread of the
16-spp frames: var_16 x 16 / ref-spp; every MSE above includes it.

Lag (moving camera, --lag-modes, default the first mode): one run of 16 + 1
frames at the camera's frame-1 pose, then its move (file frames 2..N), then
4 frames held at its last pose (finished.lag_schedule), raw, + OIDN and +
denoiser: MSE of the first frame after the motion starts (against a Cycles
reference of file frame 2 at --ref-spp / 4, rendered as two halves whose
difference estimates its noise, which is subtracted; cached), MSE and FLIP
of the last moving frame and of the two frames right after it stops (against
the reference of frame N), and of the last still frame before the move
(against the still camera's reference).

On the still camera, --stills adds still renders (F12) in the unbiased mode
with 16 and 64 warm-up frames: their MSE, and the gains at the time the whole
still took. For those, Cycles renders a still at the samples its curve says
fit in that time (its row follows), and its MSE is taken to our time as
1 / time from there (the reference's noise kept as it is).

Writes bench/out/equal_time.md and bench/out/equal_time_<scene>_<camera>.png
(ours raw | + OIDN | + denoiser per mode | Cycles + OIDN at the biased +
denoiser frame time, its nearest rendered spp | reference) and
bench/out/finished_<scene>_<camera>.png (the finished frames: ours biased +
denoiser | Cycles + OIDN at its time | reference); --quick (8
frames, reference 64 spp) writes *_quick.* instead, and --scale S (the
files' resolution times S: 2 gives 640x360) *_xS.*. What Blender prints goes
to bench/out/blender.log. --no-cycles leaves out our path tracing and Cycles
but the reference (no gains then): ours against ours, quickly.
"""

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_common
from bench_common import OUT, ROOT, load_addon, luminance, render_frames
import finished
from finished import AUX, CYCLES_OIDN_SPP, Curve
from equal_time_refs import REF_SECONDS, cycles, cycles_denoised, mse, reference, report
from equal_time_table import lag_table, table

SCENES = ("room", "movers", "slit", "glossy", "courtyard", "emitters")
MODES = {"biased": "RESTIR_BIASED", "unbiased": "RESTIR_UNBIASED"}
CAMERAS = ("still", "moving")
PT_FRAMES = 5
CYCLES_FRAMES = 4
FLICKER_FRAMES = 4          # ours: flicker over frames N-3..N
LAG_STILL, LAG_HOLD = 16, 4


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--frames", type=int, default=None, help="N (default 32; 8 with --quick)")
    ap.add_argument("--ref-spp", type=int, default=None, help="default 1024; 64 with --quick")
    ap.add_argument("--modes", default="biased,unbiased")
    ap.add_argument("--cameras", default="still,moving")
    ap.add_argument("--quick", action="store_true", help="smoke run: 8 frames, 64-spp references")
    ap.add_argument("--scale", type=float, default=1.0,
                    help="render at this multiple of the files' resolution (2: 640x360)")
    ap.add_argument("--stills", default="16,64",
                    help="warm-up frames of the unbiased still renders (F12) on the still camera; '' for none")
    ap.add_argument("--no-cycles", action="store_true",
                    help="no path tracing or Cycles rows but the reference (and no gains or stills)")
    ap.add_argument("--no-oidn", action="store_true",
                    help="no OIDN and no FLIP (without requirements-bench.txt); no Cycles + OIDN curve")
    ap.add_argument("--lag-modes", default=None,
                    help="modes of the lag runs on the moving camera (default: the first of --modes; '' none)")
    args = ap.parse_args()
    args.frames = args.frames or (8 if args.quick else 32)
    args.ref_spp = args.ref_spp or (64 if args.quick else 1024)
    args.scenes = [s for s in args.scenes.split(",") if s]
    args.modes = [m for m in args.modes.split(",") if m]
    args.cameras = [c for c in args.cameras.split(",") if c]
    args.stills = [int(w) for w in args.stills.split(",") if w]
    lag = args.modes[:1] if args.lag_modes is None else [m for m in args.lag_modes.split(",") if m]
    args.lag_modes = lag
    for name, given, known in (("scene", args.scenes, SCENES), ("mode", args.modes, MODES),
                               ("camera", args.cameras, CAMERAS), ("lag mode", args.lag_modes, MODES)):
        bad = [g for g in given if g not in known]
        if bad:
            ap.error(f"unknown {name}(s) {bad}; known: {', '.join(known)}")
    if args.frames < FLICKER_FRAMES + 1:
        ap.error(f"--frames must be at least {FLICKER_FRAMES + 1}")
    return args


# ---------------------------------------------------------------- engine settings

def ours(mode, warmup=None, denoise=False, schedule=None):
    def setup(scene):
        if schedule is not None:
            finished.retime_camera(scene, schedule)
        scene.render.engine = "RESTIR_GI"
        s = scene.restir_gi
        s.mode = mode
        s.samples = 1
        s.use_denoising = denoise
        if warmup is not None:
            s.warmup_frames = warmup
    return setup


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


def row(method, t, img=None, ref=None, e=None, **extra):
    """A table row: method, ms, MSE, and what else is known (None: '-')."""
    r = {"method": method, "t": t, "mse": e}
    if img is not None and ref is not None:
        r["mse"] = mse(img, ref) if e is None else e
        r["ratio"], r["black"] = brightness(img, ref)
    r.update(extra)
    return r


# ---------------------------------------------------------------- one scene x camera

def frame_stats(seconds, skip_first=True):
    frames = sorted(seconds)
    return statistics.median(seconds[f] for f in (frames[1:] if skip_first else frames))


def render_ours(blend, camera, label, n, args, denoise, schedule=None, frames=None):
    """Our frames 1..n of one mode: {frame: passes or Combined}, ms/frame."""
    pin = 1 if camera == "still" else None
    passes = AUX if not (denoise or args.no_oidn) else None
    images, seconds, reps = render_frames(blend, list(range(1, n + 1)),
                                          ours(MODES[label], 1, denoise, schedule), pin=pin, passes=passes)
    report(label + (" + denoiser" if denoise else ""), reps)
    keep = frames or range(n - FLICKER_FRAMES + 1, n + 1)
    if passes:
        return {f: images[f] for f in keep}, frame_stats(seconds)
    return {f: {"Combined": images[f]} for f in keep}, frame_stats(seconds)


def ours_rows(blend, camera, label, ref, args):
    """Rows (raw, + OIDN, + denoiser) of one mode; images for the pictures."""
    n = args.frames
    out = []
    raw, t_raw = render_ours(blend, camera, label, n, args, False)
    last = sorted(raw)
    variants = [(f"ReSTIR {label}", [raw[f]["Combined"] for f in last], t_raw)]
    if not args.no_oidn:
        done = [finished.oidn(raw[f]) for f in last]
        variants.append((f"ReSTIR {label} + OIDN", [d[0] for d in done],
                         t_raw + statistics.median(d[1] for d in done)))
    den, t_den = render_ours(blend, camera, label, n, args, True)
    variants.append((f"ReSTIR {label} + denoiser", [den[f]["Combined"] for f in sorted(den)], t_den))
    pictures = {}
    for method, imgs, t in variants:
        img = imgs[-1]
        out.append(row(method, t, img, ref,
                       flip=None if args.no_oidn else finished.flip(img, ref),
                       flicker=finished.flicker(imgs, ref) if camera == "still" else None))
        pictures[method] = img
        print(f"  {method}: {t * 1000:.0f} ms/frame, MSE {out[-1]['mse']:.4g}", flush=True)
    return out, pictures


def cycles_oidn_curve(blend, ref, pin, n, camera, args):
    """Cycles + its OIDN at CYCLES_OIDN_SPP: a Curve, its rows and last frames."""
    points, rows, last = {}, [], {}
    for spp in CYCLES_OIDN_SPP:
        images, seconds, reps = render_frames(blend, list(range(n - CYCLES_FRAMES + 1, n + 1)),
                                              cycles_denoised(spp, 1, True), pin=pin, hold=n)
        report(f"Cycles + OIDN {spp} spp", reps)
        imgs = [images[f] for f in sorted(images)]
        p = {"t": frame_stats(seconds), "mse": statistics.median(mse(i, ref) for i in imgs),
             "flip": finished.flip(imgs[-1], ref),
             "flicker": finished.flicker(imgs, ref) if camera == "still" else None}
        points[spp], last[spp] = p, imgs[-1]
        ratio, black = brightness(imgs[-1], ref)
        rows.append(row(f"Cycles + OIDN {spp} spp", p["t"], e=p["mse"], flip=p["flip"],
                        flicker=p["flicker"], ratio=ratio, black=black))
    return Curve(points), rows, last


def against_curves(r, pt, c_raw, curve):
    """Fill a row's gains against PT, raw Cycles and Cycles + OIDN at its time."""
    t, e = r["t"], r["mse"]
    if pt is not None:
        r["g_pt"] = (pt[1] * pt[0]) / (e * t)
    if c_raw is not None:
        r["g_c"] = cycles_mse_at(t, *c_raw) / e
    if curve is not None:
        r["g_co"] = curve.at(t, "mse") / e
        if r.get("flip"):
            r["f_co"] = curve.at(t, "flip") / r["flip"]
        k = curve.at(t, "flicker")
        if r.get("flicker") is not None and k:
            r["k_co"] = r["flicker"] / k


def run_case(name, camera, args):
    blend = ROOT / "example_blends" / f"corpus_{name}.blend"
    n = args.frames
    pin = 1 if camera == "still" else n       # PT / Cycles frames: the view of frame N
    rows, pictures = [], {}
    # The reference first (its size: the file's), then ours.
    size = scene_size(blend)
    ref, ref_s, cached, _ = reference(blend, name, camera, n, args.ref_spp, size)
    if cached:
        print(f"  reference: cached ({ref_s:.0f} s when rendered)", flush=True)
    if not args.no_oidn:
        finished.warm_oidn(ref.shape)
    for label in args.modes:
        r, pics = ours_rows(blend, camera, label, ref, args)
        rows += r
        pictures.update(pics)
    if args.no_cycles:
        rows.append(row(f"reference {args.ref_spp} spp", ref_s, e=float("nan"), ratio=1.0))
        pictures["reference"] = ref
        return rows, pictures, None

    # Our path tracing, 1 spp, and Cycles at 1 and 16 spp: frames ending at N.
    def series(setup, count, label):
        images, seconds, reps = render_frames(blend, list(range(n - count + 1, n + 1)), setup, pin=pin,
                                              hold=n)
        report(label, reps)
        imgs = [images[f] for f in sorted(images)]
        return imgs, frame_stats(seconds), statistics.median(mse(i, ref) for i in imgs)

    pt_imgs, t_pt, e_pt = series(ours("PATH"), PT_FRAMES, "PT")
    c1_imgs, t_c1, e_c1 = series(cycles(1, 1, True), CYCLES_FRAMES, "Cycles 1 spp")
    c16_imgs, t_c16, e_c16 = series(cycles(16, 1, True), CYCLES_FRAMES, "Cycles 16 spp")
    pairs = [(a, b) for i, a in enumerate(c16_imgs) for b in c16_imgs[i + 1:]]
    ref_noise = statistics.mean(mse(a, b) / 2 for a, b in pairs) * 16 / args.ref_spp
    curve, c_rows, c_last = (None, [], {}) if args.no_oidn else \
        cycles_oidn_curve(blend, ref, pin, n, camera, args)
    c_raw = ((t_c1, e_c1), (t_c16, e_c16))
    for r in rows:
        against_curves(r, (t_pt, e_pt), c_raw, curve)

    def mean_ratio(imgs):
        return statistics.mean(float(luminance(i).mean()) for i in imgs) / float(luminance(ref).mean())

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
        spp = cycles_spp_at(t, t_c1, t_c16)
        c_images, c_seconds, reps = render_frames(blend, [n], cycles(spp, 7, False), pin=1)
        report(f"Cycles for still {warmup}", reps)
        t_cy, e_cy = c_seconds[n], mse(c_images[n], ref)
        e_cy_at_t = ref_noise + max(e_cy - ref_noise, 0.0) * t_cy / t
        r = row(f"F12 still unbiased, {warmup} warm-up (whole render)", t, img, ref)
        r["g_pt"], r["g_c"] = (e_pt * t_pt) / (r["mse"] * t), e_cy_at_t / r["mse"]
        rows.append(r)
        rows.append(row(f"Cycles {spp} spp still (for the {warmup} warm-up row)", t_cy, c_images[n], ref))
    rows.append(row("PT 1 spp (ours)", t_pt, e=e_pt, g_pt=1.0, ratio=mean_ratio(pt_imgs)))
    rows.append(row("Cycles 1 spp", t_c1, e=e_c1, g_c=1.0, ratio=mean_ratio(c1_imgs)))
    rows.append(row("Cycles 16 spp", t_c16, e=e_c16, ratio=mean_ratio(c16_imgs)))
    rows += c_rows
    rows.append(row(f"reference {args.ref_spp} spp", ref_s, e=ref_noise, ratio=1.0))
    if curve is not None:
        key = next((k for k in (f"ReSTIR {m} + denoiser" for m in args.modes)), None)
        t_eq = next(r["t"] for r in rows if r["method"] == key)
        s = curve.spp_at(t_eq)
        near = min(c_last, key=lambda k: abs(math.log(k) - math.log(s)))
        pictures[f"Cycles + OIDN {near} spp"] = c_last[near]
    pictures["reference"] = ref
    return rows, pictures, curve


def scene_size(blend):
    """(width, height) the file renders at."""
    import bpy
    bpy.ops.wm.open_mainfile(filepath=str(blend), load_ui=False)
    r = bpy.context.scene.render
    percent = max(1, round(r.resolution_percentage * bench_common.SCALE))
    return int(r.resolution_x * percent / 100), int(r.resolution_y * percent / 100)


# ---------------------------------------------------------------- lag

def lag_rows(name, args, curve):
    """Rows of the lag runs (moving camera): per mode and variant, MSE and
    FLIP of the frames around the start and the stop of the camera's move."""
    blend = ROOT / "example_blends" / f"corpus_{name}.blend"
    n = args.frames
    size = scene_size(blend)
    sched, start, stop = finished.lag_schedule(LAG_STILL, n, LAG_HOLD)
    total = max(sched)
    still_ref = reference(blend, name, "still", n, args.ref_spp, size)[0]
    end_ref = reference(blend, name, "moving", n, args.ref_spp, size)[0]
    start_ref, _, _, start_noise = reference(blend, name, "moving", 2, args.ref_spp // 4, size, halves=True)
    refs = {start - 1: still_ref, start: start_ref, stop - 1: end_ref, stop: end_ref, stop + 1: end_ref}
    out = []
    for label in args.lag_modes:
        raw, t_raw = render_ours(blend, "moving", label, total, args, False, sched, frames=sorted(refs))
        variants = [(f"ReSTIR {label}", {f: p["Combined"] for f, p in raw.items()}, t_raw)]
        if not args.no_oidn:
            done = {f: finished.oidn(p) for f, p in raw.items()}
            variants.append((f"ReSTIR {label} + OIDN", {f: d[0] for f, d in done.items()},
                             t_raw + statistics.median(d[1] for d in done.values())))
        den, t_den = render_ours(blend, "moving", label, total, args, True, sched, frames=sorted(refs))
        variants.append((f"ReSTIR {label} + denoiser", {f: p["Combined"] for f, p in den.items()}, t_den))
        for method, imgs, t in variants:
            r = {"scene": name, "method": method, "t": t}
            for key, frames in (("before", [start - 1]), ("start", [start]),
                                ("moving", [stop - 1]), ("stop", [stop, stop + 1])):
                r[key] = statistics.mean(mse(imgs[f], refs[f]) for f in frames)
                if not args.no_oidn and key != "start":
                    r[key + "_flip"] = statistics.mean(finished.flip(imgs[f], refs[f]) for f in frames)
            r["start"] -= start_noise       # the start reference's own noise, estimated
            if curve is not None:
                r["c_mse"], r["c_flip"] = curve.at(t, "mse"), curve.at(t, "flip")
            out.append(r)
            print(f"  lag {method}: MSE before {r['before']:.4g} start {r['start']:.4g} "
                  f"moving {r['moving']:.4g} stop {r['stop']:.4g}", flush=True)
    return out


# ---------------------------------------------------------------- main

def main():
    args = parse_args()
    t_start = time.perf_counter()
    load_addon()
    from restir_gi.core.camera.film import write_png
    OUT.mkdir(parents=True, exist_ok=True)
    bench_common.SCALE = args.scale
    suffix = ("_quick" if args.quick else "") + (f"_x{args.scale:g}" if args.scale != 1.0 else "")
    results, lags = {}, []
    for name in args.scenes:
        for camera in args.cameras:
            print(f"{name} / {camera}", flush=True)
            rows, pictures, curve = run_case(name, camera, args)
            results[(name, camera)] = rows
            png = OUT / f"equal_time_{name}_{camera}{suffix}.png"
            write_png(png, np.concatenate(list(pictures.values()), axis=1))
            print(f"  picture: {' | '.join(pictures)}", flush=True)
            done = [k for k in pictures if k.endswith(" + denoiser")][:1] \
                + [k for k in pictures if k.startswith("Cycles + OIDN")] + ["reference"]
            if len(done) == 3:      # the finished frames: ours | Cycles + OIDN at our time | reference
                write_png(OUT / f"finished_{name}_{camera}{suffix}.png",
                          np.concatenate([pictures[k] for k in done], axis=1))
                print(f"  finished picture: {' | '.join(done)}", flush=True)
            if camera == "moving" and args.lag_modes:
                lags += lag_rows(name, args, curve)
    text = table(results, args, PT_FRAMES, CYCLES_FRAMES)
    if lags:
        text += "\n\n" + lag_table(lags, args, LAG_STILL)
    print(text)
    md = OUT / f"equal_time{suffix}.md"
    md.write_text(text + "\n")
    print(f"wrote {md.relative_to(ROOT)} and the pictures; total {time.perf_counter() - t_start:.0f} s "
          f"({len(REF_SECONDS)} references rendered in this run: {sum(REF_SECONDS):.0f} s)")


if __name__ == "__main__":
    main()
