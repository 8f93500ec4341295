"""Cost of a volume object (an OpenVDB grid) in Path Tracing, against Cycles
and against the same scene without it.

    .venv/bin/python bench/bench_volumes.py [--size 96] [--samples 16] [--repeats 3]

The scene of tests/oracle/test_volume_objects.py (a lumpy ball of smoke, 40
voxels a side, over a lit floor) is rendered by both engines through
Blender's render operator, with and without the volume object, each
repeated; prints the median seconds of each and the ratios taken in this
one run. This machine is shared, so the numbers vary between runs.
"""

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))
from bench_common import load_addon  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    load_addon()
    import bpy
    from support.blender_util import render_image, setup_cycles, setup_restir
    from support.volume_scenes import lumpy_ball, smoke_material, stage, volume_object, write_vdb

    tmp = tempfile.mkdtemp(prefix="restir-bench-volumes-")
    scene = stage(args.size, args.size)
    smoke = volume_object(write_vdb(Path(tmp) / "ball.vdb", {"density": lumpy_ball()}),
                           material=smoke_material("principled")[0])
    times = {}
    for volume in (True, False):
        smoke.hide_render = not volume
        for engine, setup in (("ours", setup_restir), ("Cycles", setup_cycles)):
            runs = []
            for seed in range(args.repeats + 1):        # the first run warms up
                setup(scene, args.samples, seed + 1, 3)
                t0 = time.perf_counter()
                render_image(scene)
                runs.append(time.perf_counter() - t0)
            times[engine, volume] = statistics.median(runs[1:])
    bpy.data.objects.remove(smoke)
    print(f"{args.size}x{args.size}, {args.samples} spp, Path Tracing; median of {args.repeats} renders (s)")
    print("| scene | ours | Cycles | ours / Cycles |")
    print("|---|---:|---:|---:|")
    for volume, label in ((True, "with the volume object"), (False, "without it")):
        o, c = times["ours", volume], times["Cycles", volume]
        print(f"| {label} | {o:.2f} | {c:.2f} | {o / c:.2f} |")
    print(f"the volume object's cost: ours x{times['ours', True] / times['ours', False]:.2f}, "
          f"Cycles x{times['Cycles', True] / times['Cycles', False]:.2f}")


if __name__ == "__main__":
    main()
