"""Real .blend files against Cycles: each file as a still, in both engines.

    .venv/bin/python bench/files_vs_cycles.py FILE_OR_DIR... [--size 96] [--samples 32]
        [--modes path,biased] [--warmup 16] [--no-camera]

Every .blend file given (or found under a folder) is opened with bpy, its
camera made to frame all visible geometry as ``bench/sweep.py --camera``
does (sweep_render.frame_camera), its resolution set to --size, Cycles'
denoiser and adaptive sampling turned off, and rendered by Cycles at
--samples and by this engine: Path Tracing at --samples, ReSTIR GI biased
with --warmup warm-up frames. Per file and mode: the whole image's mean
against Cycles', and the criterion of issue 40 on the pixels that see
geometry in Cycles' render (alpha > 0.5 with Film > Transparent): their
mean within 5 % and the median of 8x8-block relative differences within
10 % ("match"); a file whose frame shows no geometry in Cycles' render
matches where the whole images' means are within 5 % (or both are black).
Prints a markdown table; exit status 0.
"""

import argparse
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import OUT, captured_output, load_addon
from sweep_render import frame_camera

MODES = {"path": "PATH", "biased": "RESTIR_BIASED", "unbiased": "RESTIR_UNBIASED"}
BLOCK = 8


def blend_files(paths):
    out = []
    for p in map(Path, paths):
        out += sorted(p.rglob("*.blend")) if p.is_dir() else [p]
    return out


def setup(engine, args, mode=None):
    def run(scene):
        import bpy
        if args.camera:
            frame_camera(bpy, scene)
        r = scene.render
        r.resolution_x, r.resolution_y, r.resolution_percentage = args.size, args.size, 100
        r.film_transparent = True
        r.engine = engine
        if engine == "CYCLES":
            c = scene.cycles
            c.device, c.samples, c.seed = "CPU", args.samples, 1
            c.use_denoising, c.use_adaptive_sampling = False, False
        else:
            s = scene.restir_gi
            s.mode = MODES[mode]
            s.samples = args.samples if mode == "path" else 1
            s.warmup_frames = args.warmup
            s.use_denoising = False
    return run


def render_still(blend, setup):
    """(H, W, 4) float32 RGBA of the file's current frame after setup(scene),
    rendered with bpy.ops.render.render into an OpenEXR file."""
    import OpenEXR
    import bpy
    with tempfile.TemporaryDirectory(prefix="restir-files-") as tmp, captured_output(OUT / "blender.log"):
        try:
            bpy.ops.wm.open_mainfile(filepath=str(blend), load_ui=False)
        except RuntimeError:
            # Blender raises on errors it reports while loading (e.g. strips
            # past channel 128) and still opens the file.
            if os.path.realpath(bpy.data.filepath) != os.path.realpath(str(blend)):
                raise
        scene = bpy.context.scene
        setup(scene)
        s = scene.render.image_settings
        s.media_type, s.file_format, s.color_mode, s.color_depth = "IMAGE", "OPEN_EXR", "RGBA", "32"
        scene.render.filepath = os.path.join(tmp, "still.exr")
        scene.render.use_file_extension = False
        bpy.ops.render.render(write_still=True, scene=scene.name)
        with OpenEXR.File(scene.render.filepath, separate_channels=True) as f:
            ch = f.parts[0].channels
            img = np.stack([ch[c].pixels for c in "RGBA"], axis=2).astype(np.float32)
    return np.nan_to_num(img[::-1], nan=0.0, posinf=0.0, neginf=0.0)


def compare(ours, theirs):
    """(whole-image ratio, object-pixel ratio, block median, match) of RGBA images."""
    lum = lambda img: img[..., :3] @ np.array([0.2126, 0.7152, 0.0722])    # noqa: E731
    a, b = lum(ours), lum(theirs)
    whole = float(a.mean() / max(b.mean(), 1e-12))
    obj = theirs[..., 3] > 0.5
    if not obj.any():   # no geometry in Cycles' frame: the whole images compared
        both_black = max(a.mean(), b.mean()) < 1e-6
        return (1.0 if both_black else whole), float("nan"), float("nan"), both_black or abs(whole - 1) <= 0.05
    ratio = float(a[obj].mean() / max(b[obj].mean(), 1e-12))
    h, w = (s // BLOCK * BLOCK for s in a.shape)
    blocks = lambda x: x[:h, :w].reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK).mean(axis=(1, 3))  # noqa: E731
    ab, bb, ob = blocks(a * obj), blocks(b * obj), blocks(obj.astype(float))
    seen = (ob > 0.25) & (bb > 1e-4)
    median = float(np.median(np.abs(ab[seen] - bb[seen]) / bb[seen])) if seen.any() else 0.0
    return whole, ratio, median, abs(ratio - 1) <= 0.05 and median <= 0.10


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("paths", nargs="+")
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--samples", type=int, default=32)
    ap.add_argument("--warmup", type=int, default=16)
    ap.add_argument("--modes", default="path,biased")
    ap.add_argument("--no-camera", dest="camera", action="store_false")
    args = ap.parse_args()
    modes = [m for m in args.modes.split(",") if m]
    load_addon()
    rows = []
    for f in blend_files(args.paths):
        row = [f.name]
        try:
            theirs = render_still(f, setup("CYCLES", args))
            for mode in modes:
                ours = render_still(f, setup("RESTIR_GI", args, mode))
                whole, ratio, median, match = compare(ours, theirs)
                row.append(f"{whole:.3f} / {ratio:.3f} / {median:.3f} {'match' if match else 'off'}")
        except Exception as error:      # noqa: BLE001 -- one file must not end the table
            row += [f"failed: {type(error).__name__}"] * (len(modes) + 1 - len(row))
        rows.append(row)
        print(" | ".join(row), flush=True)
    print(f"\n{args.size}x{args.size}, {args.samples} spp (ReSTIR: {args.warmup} warm-up frames); "
          f"per mode: whole-image mean ratio / object pixels' mean ratio / median block difference\n")
    print("| file | " + " | ".join(modes) + " |")
    print("|---|" + "---|" * len(modes))
    for row in rows:
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
