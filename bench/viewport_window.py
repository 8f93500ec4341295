"""The rendered viewport in a real Blender 5.2 window, measured from
screenshots (issue 39): ReSTIR GI against Cycles' viewport on the example
room.

    .venv/bin/python bench/viewport_window.py [--engines RESTIR_GI CYCLES] [--shots 5 10 20]

For each engine, tools/real_blender.py opens example_blends/room_animated.blend
in a 1280x800 window and runs bench/viewport_window_driver.py: the largest
3D view looks through the camera, fitted to the view, overlays off, and
switches to Rendered; screenshots 5, 10 and 20 s later. Two references of
the camera, converged, are rendered once through the bpy module at the
camera frame's size in the window (--reference-divisor 2: half of it, upscaled;
full size takes 10-20 minutes on 2 quiet cores, hours on busy ones) and saved through the file's view transform: ours (ReSTIR GI unbiased, which
converges to the path-traced image; --warmup frames, no denoiser) and Cycles
(--samples, no adaptive sampling, no denoiser). They are cached under
bench/out/viewport_window/ while their settings hold. Each screenshot's
camera frame is resampled (bilinear) onto its full-size pixel grid (and a
smaller reference upscaled bilinearly to it); the error is the MSE of the 8-bit
display values (0-255) over the frame's pixels and channels. Also: time to
first image (the camera frame differs from the Solid view's, from crops
grabbed every 0.25 s for 6 s), and for ReSTIR GI the times of its first
frame, of the first draw of a frame (the add-on's redraw watcher) and of
its first full-resolution frame (the viewport session's counters).

Writes bench/out/viewport_window/results.md (and .json), the screenshots
under <engine>/, and pair_<s>.png: ours | Cycles at s seconds (the camera
frame only). Needs the real Blender root (tools/real_blender_setup.sh) and
root privileges; about a minute per engine, and the references once (minutes).
The ReSTIR GI package is built from the committed tree (HEAD).
"""

import argparse
import json
import os
import shutil
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
import real_blender  # noqa: E402
from real_blender_driver import read_log  # noqa: E402

OUT = os.path.join(ROOT, "bench", "out", "viewport_window")
DRIVER = os.path.join(ROOT, "bench", "viewport_window_driver.py")
BLEND = os.path.join(ROOT, "example_blends", "room_animated.blend")


def package():
    """The linux-x64 package of the committed tree (HEAD), built into a
    temporary folder: uncommitted edits in the working tree are not measured."""
    import subprocess
    import tempfile
    src = tempfile.mkdtemp(prefix="viewport-window-")
    archive = subprocess.run(["git", "-C", ROOT, "archive", "HEAD"], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", src], input=archive, check=True)
    os.symlink(os.path.join(ROOT, "wheels"), os.path.join(src, "wheels"))
    subprocess.run([sys.executable, os.path.join(src, "tools", "build_extension.py"), "--skip-download",
                    "--output-dir", os.path.join(src, "dist")], check=True, stdout=subprocess.DEVNULL)
    head = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], check=True,
                          capture_output=True, text=True).stdout.strip()
    return os.path.join(src, "dist", "restir_gi-0.1.0-linux_x64.zip"), head


def read_png(path):
    """(H, W, 3) float32 in [0, 1], row 0 at the bottom (read by Blender)."""
    import bpy
    img = bpy.data.images.load(path)
    img.colorspace_settings.name = "Non-Color"   # the file's values (a 16-bit PNG reads as linear)
    try:
        w, h = img.size
        px = np.empty(w * h * 4, np.float32)
        img.pixels.foreach_get(px)
        return px.reshape(h, w, 4)[..., :3].copy()
    finally:
        bpy.data.images.remove(img)


def write_png(path, rgb):
    """(H, W, 3) in [0, 1], row 0 at the bottom, as an 8-bit PNG."""
    import bpy
    h, w = rgb.shape[:2]
    img = bpy.data.images.new("out", w, h)
    try:
        rgba = np.concatenate([rgb, np.ones((h, w, 1), np.float32)], axis=2)
        img.pixels.foreach_set(rgba.astype(np.float32).ravel())
        img.filepath_raw = path
        img.file_format = "PNG"
        img.save()
    finally:
        bpy.data.images.remove(img)


def frame_of(screen, rect, width, height):
    """The camera frame rect (x0, y0, x1, y1 in screen pixels, origin bottom
    left) of a screenshot, sampled bilinearly at the centres of a width x
    height grid."""
    x0, y0, x1, y1 = rect
    sx = x0 + (np.arange(width) + 0.5) * (x1 - x0) / width - 0.5
    sy = y0 + (np.arange(height) + 0.5) * (y1 - y0) / height - 0.5
    H, W = screen.shape[:2]
    sx, sy = np.clip(sx, 0, W - 1), np.clip(sy, 0, H - 1)
    ix, iy = np.minimum(sx.astype(int), W - 2), np.minimum(sy.astype(int), H - 2)
    fx, fy = (sx - ix)[None, :, None], (sy - iy)[:, None, None]
    a = screen[iy][:, ix]
    b = screen[iy][:, ix + 1]
    c = screen[iy + 1][:, ix]
    d = screen[iy + 1][:, ix + 1]
    return (a * (1 - fx) + b * fx) * (1 - fy) + (c * (1 - fx) + d * fx) * fy


def first_image(folder, t_switch, rect):
    """Seconds from the switch to Rendered to the first crop of the camera
    frame that differs from the Solid view's (before.png) by over 0.03 on
    average and is not flat (luminance spread over half the last
    screenshot's); "n/a" if none."""
    before = read_png(os.path.join(folder, "before.png"))
    times = {}
    with open(os.path.join(folder, "poll.times")) as fh:
        for line in fh:
            i, t = line.split()
            times[int(i)] = float(t) - t_switch
    last = sorted(f for f in os.listdir(folder) if f.startswith("shot_") and f.endswith(".png"))
    x0, y0 = int(rect[0]), int(rect[1])
    final = read_png(os.path.join(folder, last[-1]))[y0:y0 + before.shape[0], x0:x0 + before.shape[1]]
    spread = float((final @ np.float32([0.2126, 0.7152, 0.0722])).std())
    for i in sorted(times):
        img = read_png(os.path.join(folder, f"poll_{i}.png"))
        lum = img @ np.float32([0.2126, 0.7152, 0.0722])
        if img.shape == before.shape and np.abs(img - before).mean() > 0.03 and lum.std() > 0.5 * spread:
            return f"{times[i]:.2f}"
    return "n/a"


def mse8(image, reference):
    """MSE of 8-bit display values (the reference rounded to 8 bits)."""
    ref8 = np.round(np.clip(reference, 0, 1) * 255.0)
    return float(np.mean((np.clip(image, 0, 1) * 255.0 - ref8) ** 2))


def run_engine(engine, shots, pkg):
    folder = os.path.join(OUT, engine.lower())
    shutil.rmtree(folder, ignore_errors=True)
    t = time.time()
    rc = real_blender.run(pkg, BLEND, DRIVER, folder, [], limit=120 + 2 * max(shots),
                          env={"REAL_MODE": "viewport", "REAL_ENGINE": engine,
                               "REAL_SHOTS": ",".join(f"{s:g}" for s in shots)})
    lines = read_log(folder)
    print(f"{engine}: blender exit {rc} after {time.time() - t:.0f} s", flush=True)
    if rc != 0 or "quitting" not in lines:
        sys.exit(f"{engine}: the driver did not finish; see {folder}/blender.log")
    return folder, lines


def render_reference(kind, width, height, samples, warmup):
    """A converged render of the file's camera at width x height, saved
    through the file's view transform (16-bit PNG), rendered here through
    the bpy module: "cycles" (samples, no adaptive sampling, no denoiser)
    or "ours" (ReSTIR GI unbiased, which converges to the path-traced image:
    warmup frames, no denoiser). Cached under OUT while its settings hold."""
    import bpy
    path = os.path.join(OUT, f"reference_{kind}.png")
    meta = path[:-4] + ".json"
    want = {"size": [width, height], "samples": samples, "warmup": warmup}
    if os.path.isfile(path) and os.path.isfile(meta) and json.load(open(meta)) == want:
        return path
    bpy.ops.wm.open_mainfile(filepath=BLEND)
    scene = bpy.context.scene
    if kind == "cycles":
        scene.render.engine = "CYCLES"
        c = scene.cycles
        c.device, c.samples, c.use_adaptive_sampling, c.use_denoising = "CPU", samples, False, False
    else:
        scene.render.engine = "RESTIR_GI"
        s = scene.restir_gi
        s.mode, s.warmup_frames, s.use_denoising = "RESTIR_UNBIASED", warmup, False
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
    r.image_settings.file_format, r.image_settings.color_depth = "PNG", "16"
    r.filepath = path
    t = time.time()
    bpy.ops.render.render(write_still=True)
    print(f"reference {kind}: {width}x{height} in {time.time() - t:.0f} s", flush=True)
    json.dump(want, open(meta, "w"))
    return path


def upscale(image, width, height):
    """Bilinear resize of (h, w, 3) to (height, width, 3), pixel centres aligned."""
    h, w = image.shape[:2]
    return frame_of(image, (0.0, 0.0, float(w), float(h)), width, height)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--engines", nargs="*", default=["RESTIR_GI", "CYCLES"],
                        help="engines to run in the window (the others' last screenshots are reused)")
    parser.add_argument("--report", nargs="+", default=["RESTIR_GI", "CYCLES"], help="engines in the table")
    parser.add_argument("--shots", nargs="+", type=float, default=[5.0, 10.0, 20.0])
    parser.add_argument("--samples", type=int, default=1024, help="the Cycles reference's samples")
    parser.add_argument("--reference-divisor", type=int, default=1,
                        help="the references' size: the camera frame's divided by this (1: full size)")
    parser.add_argument("--warmup", type=int, default=256, help="our reference's warm-up frames")
    args = parser.parse_args(argv)
    reason = real_blender.missing()
    if reason:
        sys.exit(reason)
    os.makedirs(OUT, exist_ok=True)
    pkg, head = package() if args.engines else (None, "the last run's")
    results = {}
    for engine in args.report:
        if engine in args.engines:
            folder, lines = run_engine(engine, args.shots, pkg)
        else:       # the screenshots of an earlier run
            folder = os.path.join(OUT, engine.lower())
            lines = read_log(folder)
        rect = tuple(float(v) for v in lines["rect"][0].split()[:4])
        results[engine] = {"folder": folder, "rect": rect, "lines": lines}
    # bpy only now: loading it sets OCIO in this process's environment, which
    # the real Blender would inherit (its colour management then failed to load).
    sys.path.insert(0, os.path.join(ROOT, "bench"))
    from bench_common import load_addon
    load_addon()            # bpy (image reading), Blender's user folder kept out of $HOME
    rect = results[args.report[0]]["rect"]
    width, height = int(round(rect[2] - rect[0])), int(round(rect[3] - rect[1]))
    d = max(1, args.reference_divisor)
    rw, rh = (width + d - 1) // d, (height + d - 1) // d
    refs = {kind: upscale(read_png(render_reference(kind, rw, rh, args.samples, args.warmup)), width, height)
            for kind in ("ours", "cycles")}
    rows = []
    frames = {}
    for engine, r in results.items():
        lines = r["lines"]
        errors = {kind: {} for kind in refs}
        for s in args.shots:
            img = frame_of(read_png(os.path.join(r["folder"], f"shot_{s:g}.png")), r["rect"], width, height)
            frames[(engine, s)] = img
            for kind, ref in refs.items():
                errors[kind][s] = mse8(img, ref)
        first = first_image(r["folder"], float(lines["switched"][0]), r["rect"])
        full = lines["full_res"][0].split()[0] if "full_res" in lines else "n/a"
        first_frame = lines["first_frame"][0].split()[0] if "first_frame" in lines else "n/a"
        first_drawn = lines["first_drawn"][0].split()[0] if "first_drawn" in lines else "n/a"
        rows.append({"engine": engine, "mse": errors, "first_image": first, "first_frame": first_frame,
                     "first_drawn": first_drawn,
                     "full_res": full, "shot_times": lines.get("shot", []),
                     "frames": lines.get("frames", [""])[0], "statuses": lines.get("status", [])})
    floor = mse8(refs["ours"], refs["cycles"])
    for s in args.shots:
        if all((e, s) in frames for e in ("RESTIR_GI", "CYCLES")):
            pair = np.concatenate([frames[("RESTIR_GI", s)], np.ones((height, 8, 3), np.float32),
                                   frames[("CYCLES", s)]], axis=1)
            write_png(os.path.join(OUT, f"pair_{s:g}.png"), pair)
    shots = " | ".join(f"{s:g} s" for s in args.shots)
    table = [f"| engine | reference | {shots} | first image (s) | first frame (s) | first drawn (s) | full resolution (s) |",
             "|---" * (6 + len(args.shots)) + "|"]
    for row in rows:
        for kind in refs:
            table.append(f"| {row['engine']} | {kind} | " +
                         " | ".join(f"{row['mse'][kind][s]:.0f}" for s in args.shots) +
                         f" | {row['first_image']} | {row['first_frame']} | {row['first_drawn']} | {row['full_res']} |")
    if len(rows) == 2:
        for kind in refs:
            ratio = [rows[1]["mse"][kind][s] / max(rows[0]["mse"][kind][s], 1e-9) for s in args.shots]
            table.append(f"| Cycles / ours | {kind} | " + " | ".join(f"{x:.1f}x" for x in ratio) + " | | | | |")
    text = "\n".join([
        f"Camera frame {width}x{height} px in a 1280x800 window, MSE of 8-bit display values against "
        f"references rendered at {rw}x{rh}{' and upscaled bilinearly' if d > 1 else ''}: ours (ReSTIR GI unbiased, "
        f"{args.warmup} warm-up frames) and Cycles ({args.samples} samples); the two references differ by "
        f"MSE {floor:.0f}. ReSTIR GI at commit {head}. "
        f"`.venv/bin/python bench/viewport_window.py` ({time.strftime('%Y-%m-%d %H:%M')} UTC, load average "
        f"{os.getloadavg()[0]:.1f} at the end)", "", *table, ""])
    print(text)
    with open(os.path.join(OUT, "results.md"), "w") as fh:
        fh.write(text)
    with open(os.path.join(OUT, "results.json"), "w") as fh:
        json.dump([{k: v for k, v in r.items()} for r in rows], fh, indent=1, default=str)


if __name__ == "__main__":
    main()
