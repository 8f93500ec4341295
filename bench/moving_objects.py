"""Moving objects: what the motion adds to the error of a frame.

Our frame N of a corpus file's animation (still camera; the file's objects
move), against the same frame rendered the same way with every object held
at its frame-N pose, both against Cycles' reference of frame N. Reports MSE,
mean ratio and the ReSTIR Indirect pass of the moving frame over the held
one, on the whole image and on its brightest pixels (the reference's top
``--top`` share: the movers' sun patch, where the box's light falls).

    .venv/bin/python bench/moving_objects.py [--scene movers] [--frames 32]
        [--ref-spp 1024] [--mode biased] [--no-denoise] [--top 0.04]
        [--held-frame F] [--set accumulate_frames=1,temporal_m_cap=1]

--held-frame holds the objects at frame F's pose instead (the lag in
frames: the held frame whose light the moving one shows); --set sets the
engine's settings (``scene.restir_gi``) of both renders.

Everything renders as a user renders (bench_common.render_frames); the
reference is equal_time's (cached in bench/out/refs/).
"""

import argparse

import numpy as np

from bench_common import ROOT, load_addon, render_frames
from equal_time import MODES, ours, scene_size
from equal_time_refs import mse, reference

PASSES = ("ReSTIR Indirect",)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="movers")
    ap.add_argument("--frames", type=int, default=32)
    ap.add_argument("--ref-spp", type=int, default=1024)
    ap.add_argument("--mode", default="biased", choices=sorted(MODES))
    ap.add_argument("--no-denoise", action="store_true")
    ap.add_argument("--top", type=float, default=0.04)
    ap.add_argument("--held-frame", type=int, default=None)
    ap.add_argument("--set", default="", help="name=value,... of scene.restir_gi")
    args = ap.parse_args()
    plain = ours(MODES[args.mode], 1, not args.no_denoise)

    def setup(scene):
        plain(scene)
        for item in filter(None, args.set.split(",")):
            name, value = item.split("=")
            kind = type(getattr(scene.restir_gi, name))
            setattr(scene.restir_gi, name, kind(float(value)) if kind in (int, float) else kind(value))
    load_addon()
    blend = ROOT / "example_blends" / f"corpus_{args.scene}.blend"
    n = args.frames
    ref = reference(blend, args.scene, "still", n, args.ref_spp, scene_size(blend))[0][..., :3]
    lum = ref.mean(axis=-1)
    bright = lum >= np.quantile(lum, 1.0 - args.top)
    out = {}
    for label, hold in (("moving", None), ("held", args.held_frame or n)):
        images, _, _ = render_frames(blend, list(range(1, n + 1)), setup, pin=1, hold=hold, passes=PASSES)
        out[label] = images[n]
    print(f"{args.scene}, still camera, {args.mode}{'' if args.no_denoise else ' + denoiser'}, frame {n} "
          f"against Cycles at {args.ref_spp} spp (held: at frame {args.held_frame or n}'s pose) {args.set}:")
    print("| frame | MSE | mean ratio |")
    print("|---|---:|---:|")
    for label in ("moving", "held"):
        img = out[label]["Combined"][..., :3]
        print(f"| {label} | {mse(img, ref):.4g} | {img.mean() / ref.mean():.3f} |")
    ind_m, ind_h = (out[k]["ReSTIR Indirect"][..., :3].mean(axis=-1) for k in ("moving", "held"))
    print(f"indirect light, moving / held: whole image {ind_m.sum() / ind_h.sum():.3f}, "
          f"brightest {args.top:.0%} {ind_m[bright].sum() / ind_h[bright].sum():.3f}")


if __name__ == "__main__":
    main()
