"""What giving each sun its own light sample (LightSet.nee_sets) does to a
scene lit by a sun and by lamps: frame time and error against Cycles.

    .venv/bin/python bench/suns_apart.py [--scene glossy] [--frames 32] [--ref-spp 1024]

Renders the corpus scene's still camera through the add-on (ReSTIR GI
biased, Denoise on, 1 warm-up frame, frames 1..N) twice in one run: as
the engine does, and with the sun chosen among the other emitters by power
(``nee_sets`` returning the set alone). Per run: the median frame time
(frames 2..N), and at frame N the MSE of the ReSTIR Direct pass against
Cycles' direct light (Diffuse / Glossy / Transmission Direct times their
Color passes, plus Emission and Environment) and of Combined against
Cycles' Combined, both from one Cycles render at --ref-spp (cached in
bench/out/refs/).
"""

import argparse
import hashlib
import pickle
import statistics
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import OUT, ROOT, load_addon, render_frames
from equal_time_refs import REF_SEED, cycles

CYCLES_PASSES = ("Diffuse Direct", "Diffuse Color", "Glossy Direct", "Glossy Color", "Transmission Direct",
                 "Transmission Color", "Emission", "Environment")
USE = ("diffuse_direct", "diffuse_color", "glossy_direct", "glossy_color", "transmission_direct",
       "transmission_color", "emit", "environment")


def reference(blend, spp):
    """Cycles' Combined and direct light of frame 1 (still camera), cached."""
    sha = hashlib.sha1(blend.read_bytes()).hexdigest()[:12]
    path = OUT / "refs" / f"direct_{blend.stem}_{spp}spp_{sha}.pkl"
    if path.exists():
        return pickle.loads(path.read_bytes())

    def setup(scene):
        cycles(spp, REF_SEED, False)(scene)
        for name in USE:
            setattr(scene.view_layers[0], "use_pass_" + name, True)
    print(f"reference: Cycles {spp} spp ...", flush=True)
    images, seconds, _ = render_frames(blend, [1], setup, pin=1, passes=CYCLES_PASSES)
    c = images[1]
    direct = (c["Diffuse Direct"] * c["Diffuse Color"] + c["Glossy Direct"] * c["Glossy Color"]
              + c["Transmission Direct"] * c["Transmission Color"] + c["Emission"] + c["Environment"])
    out = {"combined": c["Combined"], "direct": direct, "seconds": seconds[1]}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(pickle.dumps(out))
    return out


def ours(scene):
    scene.render.engine = "RESTIR_GI"
    s = scene.restir_gi
    s.mode, s.samples, s.use_denoising, s.warmup_frames = "RESTIR_BIASED", 1, True, 1


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="glossy")
    ap.add_argument("--frames", type=int, default=32)
    ap.add_argument("--ref-spp", type=int, default=1024)
    args = ap.parse_args()
    load_addon()
    from restir_gi.core.lights.light_set import LightSet
    blend = ROOT / "example_blends" / f"corpus_{args.scene}.blend"
    ref = reference(blend, args.ref_spp)
    n = args.frames
    apart = LightSet.nee_sets
    rows = []
    for label, sets in (("suns apart (as rendered)", apart), ("sun chosen by power", lambda self: [self])):
        LightSet.nee_sets = sets
        try:
            images, seconds, _ = render_frames(blend, list(range(1, n + 1)), ours, pin=1,
                                               passes=["ReSTIR Direct"])
        finally:
            LightSet.nee_sets = apart
        last = images[n]
        rows.append((label, statistics.median(seconds[f] for f in range(2, n + 1)),
                     float(((last["ReSTIR Direct"] - ref["direct"]) ** 2).mean()),
                     float(((last["Combined"] - ref["combined"]) ** 2).mean())))
        print(f"{label}: done", flush=True)
    print(f"\ncorpus {args.scene}, still camera, ReSTIR biased + denoiser, frame {n}, "
          f"against Cycles {args.ref_spp} spp\n")
    print("| NEE | s / frame | direct light MSE | Combined MSE |")
    print("|---|---:|---:|---:|")
    for label, t, e_direct, e_all in rows:
        print(f"| {label} | {t:.3f} | {e_direct:.3g} | {e_all:.3g} |")
    if not np.isfinite([r[2] for r in rows]).all():
        raise SystemExit("non-finite error")


if __name__ == "__main__":
    main()
