"""Fingerprints of rendered images, to show that a change which only moves
code renders bit for bit as before it.

Renders, through the add-on as a user does (bench_common.render_frames), the
quick start's example animation (frames 1-3) and frame 1 of every corpus
scene, in Path Tracing, ReSTIR Biased and ReSTIR Unbiased, at a small size,
and records a SHA-256 of every pass of every frame:

    .venv/bin/python bench/bit_for_bit.py --write before.json   # on the old code
    .venv/bin/python bench/bit_for_bit.py --check before.json   # on the new code

``--check`` prints each difference and exits 1 if there is one. Fingerprints
hold on one machine and one environment (numpy, Embree and the CPU decide the
last bits); compare runs of the same ``make`` line on the same machine.
"""

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import OUT, ROOT, captured_output, load_addon
SCENES = [("room_animated", (1, 2, 3))] + [(f"corpus_{name}", (1,)) for name in
                                           ("room", "slit", "glossy", "courtyard", "emitters")]
MODES = ("PATH", "RESTIR_BIASED", "RESTIR_UNBIASED")


def channels(path):
    """{channel name: pixels} of every part of a multilayer EXR."""
    import OpenEXR
    out = {}
    with OpenEXR.File(str(path), separate_channels=True) as f:
        for part in f.parts:
            for name, channel in part.channels.items():
                out[name] = channel.pixels.copy()
    return out


def render(blend, frames, setup):
    """{frame: channels} of an animation render of ``frames`` into multilayer EXRs."""
    import os
    import tempfile

    import bpy
    with tempfile.TemporaryDirectory(prefix="restir-b4b-") as tmp, captured_output(OUT / "bit_for_bit.log"):
        bpy.ops.wm.open_mainfile(filepath=str(blend), load_ui=False)
        scene = bpy.context.scene
        setup(scene)
        scene.frame_start, scene.frame_end, scene.frame_step = frames[0], frames[-1], 1
        r = scene.render
        r.use_file_extension, r.use_overwrite, r.use_placeholder = True, True, False
        s = r.image_settings
        s.media_type, s.file_format = 'MULTI_LAYER_IMAGE', 'OPEN_EXR_MULTILAYER'
        s.color_mode, s.color_depth = 'RGBA', '32'
        r.filepath = os.path.join(tmp, "frame_####")
        if bpy.ops.render.render(animation=True, scene=scene.name) != {'FINISHED'}:
            raise RuntimeError(f"the render of {blend} did not finish")
        return {f: channels(os.path.join(tmp, f"frame_{f:04d}.exr")) for f in frames}


def fingerprints(width, height, warmup):
    load_addon()
    out = {}
    for name, frames in SCENES:
        for mode in MODES:
            def setup(scene, mode=mode):
                r = scene.render
                r.engine = "RESTIR_GI"         # as blender -E RESTIR_GI
                r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
                s = scene.restir_gi
                s.mode, s.seed = mode, 0
                s.warmup_frames = warmup
                if mode == "PATH":
                    s.samples = 4

            files = render(ROOT / "example_blends" / f"{name}.blend", frames, setup)
            for f, chans in sorted(files.items()):
                for channel, pixels in sorted(chans.items()):
                    key = f"{name} {mode} frame {f} {channel}"
                    out[key] = hashlib.sha256(np.ascontiguousarray(pixels).tobytes()).hexdigest()
                print(f"{name} {mode} frame {f}: {len(chans)} channels", flush=True)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    group = ap.add_mutually_exclusive_group(required=True)
    group.add_argument("--write", metavar="JSON", help="write the fingerprints to JSON")
    group.add_argument("--check", metavar="JSON", help="compare with the fingerprints in JSON")
    ap.add_argument("--size", default="64x36", help="render size WxH (default 64x36)")
    ap.add_argument("--warmup", type=int, default=4, help="ReSTIR warm-up frames (default 4)")
    args = ap.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    now = fingerprints(width, height, args.warmup)
    if args.write:
        Path(args.write).write_text(json.dumps(now, indent=1, sort_keys=True) + "\n")
        print(f"{len(now)} fingerprints written to {args.write}")
        return 0
    before = json.loads(Path(args.check).read_text())
    differ = sorted(k for k in set(before) | set(now) if before.get(k) != now.get(k))
    for k in differ:
        print(f"DIFFERS: {k}")
    print(f"{len(now) - len([k for k in differ if k in now])} of {len(now)} images bit for bit as before"
          + (f"; {len(differ)} differ" if differ else ""))
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
