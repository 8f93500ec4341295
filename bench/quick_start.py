"""The quick-start animation (`make render`) against Cycles, frame by frame.

    .venv/bin/python bench/quick_start.py [--frames 1,12,24] [--ref-spp 256]

Renders example_blends/room_animated.blend as `make render` does (the file's
own settings: ReSTIR GI biased, its warm-up, its frame range) through
``bpy.ops.render.render(animation=True)``, and Cycles references of the
chosen frames (cached in bench/out/refs/, rebuilt when the file changes).
Per frame: mean luminance against the reference, the share of pixels lit in
the reference that come out near black (as bench/equal_time.py counts them),
and MSE (which includes the reference's own noise). Writes
bench/out/quick_start.md and bench/out/quick_start.png (ours over the
reference, one column per frame).
"""

import argparse
import hashlib
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import OUT, ROOT, load_addon, render_frames
from equal_time import brightness, cycles, mse

BLEND = ROOT / "example_blends" / "room_animated.blend"
REF_SEED = 1234


def reference(frame, spp):
    from restir_gi.core.camera.film import read_exr, write_exr
    sha = hashlib.sha1(BLEND.read_bytes()).hexdigest()[:12]
    path = OUT / "refs" / f"quick_start_f{frame}_{spp}spp_{sha}.exr"
    if path.exists():
        return read_exr(path)
    print(f"reference: Cycles {spp} spp of frame {frame} ...", flush=True)
    images, seconds, _ = render_frames(BLEND, [frame], cycles(spp, REF_SEED, False))
    path.parent.mkdir(parents=True, exist_ok=True)
    write_exr(path, images[frame])
    print(f"  took {seconds[frame]:.0f} s", flush=True)
    return images[frame]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", default="1,12,24")
    ap.add_argument("--ref-spp", type=int, default=256)
    args = ap.parse_args()
    frames = [int(f) for f in args.frames.split(",")]
    load_addon()
    import bpy

    def as_the_file_says(scene):
        scene.render.engine = "RESTIR_GI"

    bpy.ops.wm.open_mainfile(filepath=str(BLEND), load_ui=False)
    first, last = bpy.context.scene.frame_start, bpy.context.scene.frame_end
    ours, seconds, reports = render_frames(BLEND, list(range(first, last + 1)), as_the_file_says)
    for line in reports:
        print(f"  [ours] {line}")
    rows = ["| frame | ms | mean ratio | black % | MSE |", "|---:|---:|---:|---:|---:|"]
    tiles = []
    for f in frames:
        ref = reference(f, args.ref_spp)
        ratio, black = brightness(ours[f], ref)
        rows.append(f"| {f} | {seconds[f] * 1000:.0f} | {ratio:.3f} | {black:.2f} | {mse(ours[f], ref):.4g} |")
        tiles.append(np.concatenate([ref, ours[f]], axis=0))     # bottom row first: ours on top
    text = (f"{BLEND.name}, the file's settings, Cycles {args.ref_spp} spp references "
            f"(ms: render_pre to render_post)\n\n" + "\n".join(rows) + "\n")
    print(text)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "quick_start.md").write_text(text)
    from restir_gi.core.camera.film import write_png
    write_png(OUT / "quick_start.png", np.concatenate(tiles, axis=1))


if __name__ == "__main__":
    main()
