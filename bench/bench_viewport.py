"""Viewport benchmark: the acceleration structure for edits, and the time from
an edit to the next finished viewport frame on the example room.

    .venv/bin/python bench/bench_viewport.py [--scales HALF QUARTER] [--repeats 2]

Part 1 (core only) measures the choice behind core.geometry.dynamic_accel on a
synthetic scene of --big-triangles triangles with a small moving object:
rebuilding one Embree scene per edit against moving the object to a small
second scene (first move, later moves, settling back), and what queries pay
for tracing two scenes instead of one.

Part 2 drives restir_addon.viewport.ViewportSession on room_indirect.blend
(a 1280x720 viewport at each --scales entry) with real depsgraph updates:
steady frames per second, then for each kind of edit (camera move, object
move, material change, light change) the time from the edit to the next
finished frame, twice:
- "sync": the edit, depsgraph evaluation, sync and one render_step in a row;
- "threaded": the session's render thread running, the edit arriving at a
  random point of the frame in progress, until a frame including it is out
  (what a user waits for).
Writes bench/out/viewport.md.
"""

import argparse
import dataclasses
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from bench_common import OUT, ROOT, load_addon

BLEND = ROOT / "example_blends" / "room_indirect.blend"
TARGET_EDIT_S = 0.3     # issue 4: transform edit to next frame at 1/4 scale
TARGET_FPS = 4.0        # issue 4: frames per second at 320x180


# ------------------------------------------------------------------ part 1: accel

def grid_scene(n_tris):
    """A bumpy height field of about n_tris triangles plus a 192-triangle mover."""
    side = max(2, int(math.sqrt(n_tris / 2)))
    xs = np.linspace(-10, 10, side + 1, dtype=np.float32)
    gx, gy = np.meshgrid(xs, xs)
    gz = 0.3 * np.sin(gx * 1.3) * np.cos(gy * 0.7)
    v = np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1).astype(np.float32)
    i = (np.arange(side)[:, None] * (side + 1) + np.arange(side)[None, :]).ravel()
    t = np.concatenate([np.stack([i, i + 1, i + side + 2], 1), np.stack([i, i + side + 2, i + side + 1], 1)])
    # The mover: a 4x4x4-quad box above the field.
    u = np.linspace(-0.5, 0.5, 5, dtype=np.float32)
    faces = []
    for axis in range(3):
        for side_sign in (-0.5, 0.5):
            a, b = np.meshgrid(u, u)
            p = np.zeros((25, 3), np.float32)
            p[:, axis] = side_sign
            p[:, (axis + 1) % 3], p[:, (axis + 2) % 3] = a.ravel(), b.ravel()
            j = (np.arange(4)[:, None] * 5 + np.arange(4)[None, :]).ravel()
            faces.append((p, np.concatenate([np.stack([j, j + 1, j + 6], 1), np.stack([j, j + 6, j + 5], 1)])))
    mv, mt, off = [], [], 0
    for p, f in faces:
        mv.append(p + np.float32([0, 0, 1.5]))
        mt.append(f + off)
        off += len(p)
    mover_v, mover_t = np.concatenate(mv), np.concatenate(mt)
    vertices = np.concatenate([v, mover_v])
    triangles = np.concatenate([t, mover_t + len(v)]).astype(np.int32)
    ids = np.concatenate([np.zeros(len(t), np.int32), np.ones(len(mover_t), np.int32)])
    mover_rows = np.arange(len(v), len(vertices))
    return vertices, triangles, ids, mover_rows


def bench_rays(n, rng):
    o = np.column_stack([rng.uniform(-8, 8, n), rng.uniform(-8, 8, n), np.full(n, 6.0)]).astype(np.float32)
    d = np.column_stack([rng.normal(scale=0.3, size=(n, 2)), -np.ones(n)])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return o, d.astype(np.float32)


def timed(fn, repeats=1):
    best = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best.append(time.perf_counter() - t0)
    return statistics.median(best)


def part_accel(n_tris, n_rays, lines):
    from restir_gi.core.geometry.accel import Accel
    from restir_gi.core.geometry.dynamic_accel import DynamicAccel
    rng = np.random.default_rng(7)
    v, t, ids, mover = grid_scene(n_tris)
    print(f"accel: {len(t):,} triangles, mover {int((ids == 1).sum())} triangles", flush=True)
    full = timed(lambda: Accel(v, t).close(), 2)
    dyn = DynamicAccel(v, t, ids, [0, 1])
    moved = v.copy()

    def move():
        moved[mover] += np.float32([0.05, 0.0, 0.0])
        dyn.update(moved, t, ids, [0, 1], changed=[1])

    first = timed(move)
    later = timed(move, 5)
    o, d = bench_rays(n_rays, rng)
    ref = Accel(moved, t)
    dist = np.full(n_rays, 8.0, np.float32)
    rates = {}
    for name, acc in (("one scene", ref), ("static + dynamic", dyn)):
        acc.intersect_closest(o, d)
        rates[name] = (n_rays / timed(lambda: acc.intersect_closest(o, d), 3) / 1e6,
                       n_rays / timed(lambda: acc.occluded(o, d, dist), 3) / 1e6)
    settle = timed(dyn.settle)
    dyn.close()
    ref.close()
    lines += [f"### Acceleration structure: {len(t):,} triangles, a 192-triangle object moving", "",
              "| operation | seconds |", "|---|---:|",
              f"| rebuild one Embree scene (every edit without the dynamic scene) | {full:.3f} |",
              f"| first move of an object (static scene without it + dynamic scene) | {first:.3f} |",
              f"| later moves of the same object (dynamic scene only) | {later:.4f} |",
              f"| settle (merge back into one scene) | {settle:.3f} |", "",
              f"| queries ({n_rays:,} rays, 2 threads) | closest Mrays/s | occluded Mrays/s |",
              "|---|---:|---:|"]
    for name, (c, s) in rates.items():
        lines.append(f"| {name} | {c:.2f} | {s:.2f} |")
    c0, s0 = rates["one scene"]
    c1, s1 = rates["static + dynamic"]
    lines += ["", f"Query overhead of the second scene: closest {100 * (c0 / c1 - 1):+.0f}%, "
                  f"occluded {100 * (s0 / s1 - 1):+.0f}%.", ""]


# ------------------------------------------------------------------ part 2: viewport

def make_edits(bpy, session, rng):
    """name -> function applying one edit of that kind through bpy or set_view."""
    box = bpy.data.objects["MovingBox"]
    node = next(n for n in bpy.data.materials["BoxOrange"].node_tree.nodes if "Color" in n.inputs)
    sun = bpy.data.lights["Sun"]
    state = {"sign": 1.0, "x": box.location.x}

    def camera():
        """Turn the view by one degree about the vertical, back and forth."""
        cam = session.view
        state["sign"] = -state["sign"]
        a = math.radians(1.0) * state["sign"]
        rot = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
        m = cam.to_world.copy()
        m[:3, :3] = rot @ m[:3, :3]
        session.set_view(dataclasses.replace(cam, to_world=m))
        return None

    def move():
        state["x"] += 0.05 if rng.random() < 0.5 else -0.05
        box.location.x = state["x"]
        return "depsgraph"

    def material():
        node.inputs["Color"].default_value = (*rng.uniform(0.2, 0.9, 3), 1.0)
        return "depsgraph"

    def light():
        sun.energy = float(rng.uniform(80, 120))
        return "depsgraph"

    return {"camera move": camera, "object move": move, "material change": material,
            "light change": light}


def apply_edit(bpy, session, recorder, edit):
    if edit() == "depsgraph":
        bpy.context.view_layer.update()
        session.sync(bpy.context.evaluated_depsgraph_get(), recorder.take())


def part_viewport(args, lines):
    import bpy
    vp = sys.modules["restir_gi"].restir_addon.viewport.session
    from restir_gi.restir_addon.viewport.draw import session_settings
    from support.blender_util import Recorder      # imports restir_gi: after load_addon
    bpy.ops.wm.open_mainfile(filepath=str(args.blend))
    scene = bpy.context.scene
    recorder = Recorder()
    bpy.app.handlers.depsgraph_update_post.append(recorder)
    rng = np.random.default_rng(11)
    # What the file's viewport runs with (draw.session_settings), but for the
    # mode, the fixed scale and no sample limit; --bounces and --light-samples
    # override the file's.
    settings = session_settings(scene)
    bounces = settings["max_bounces"] if args.bounces is None else args.bounces
    base = settings["restir"]
    if args.light_samples is not None:
        base = dataclasses.replace(base, light_samples=args.light_samples)
    lines += [f"### Viewport: {args.blend.name}, {args.width}x{args.height} viewport, mode {args.mode}, "
              f"max_bounces {bounces}, light_samples {base.light_samples}, "
              f"denoiser {'on' if base.denoise else 'off'}, {'threads' if args.no_twin else 'twin process'}",
              "",
              "| scale | render size | steady frames/s | edit | sync + frame (s) | threaded, edit to frame (s) |",
              "|---|---|---:|---|---:|---:|"]
    if args.no_twin:
        vp.ViewportSession.twin_process = False     # passes on two threads, as before the twin
    for scale in args.scales:
        session = vp.ViewportSession(mode=args.mode, scale=scale, max_bounces=bounces, restir=base, samples=0,
                                     seed=settings["seed"], denoise_start=settings["denoise_start"])
        session.resize(args.width, args.height)
        session.sync(bpy.context.evaluated_depsgraph_get())
        for _ in range(2):
            session.render_step()
        w, h = session.render_size
        print(f"{scale}: {w}x{h}", flush=True)
        steady = [timed(session.render_step) for _ in range(args.frames)]
        fps = 1.0 / statistics.median(steady)
        edits = make_edits(bpy, session, rng)
        results = {}
        for name, edit in edits.items():
            direct = []
            for _ in range(args.repeats):
                t0 = time.perf_counter()
                apply_edit(bpy, session, recorder, edit)
                session.render_step()
                direct.append(time.perf_counter() - t0)
            results[name] = [statistics.median(direct)]
            print(f"  {name}: sync + frame {results[name][0]:.3f} s", flush=True)
        session.start()
        frame_s = statistics.median(steady)
        for name, edit in edits.items():
            waits = []
            for _ in range(args.repeats):
                session.wait_for_frame()
                time.sleep(rng.uniform(0, frame_s))    # the edit lands mid-frame
                t0 = time.perf_counter()
                apply_edit(bpy, session, recorder, edit)
                session.wait_for_frame(session.generation, timeout=120)
                waits.append(time.perf_counter() - t0)
            results[name].append(statistics.median(waits))
            print(f"  {name}: threaded {results[name][1]:.3f} s", flush=True)
        work = session.work
        session.close()
        for i, (name, (direct, threaded)) in enumerate(results.items()):
            lead = f"| {scale} | {w}x{h} | {fps:.2f} |" if i == 0 else "| | | |"
            lines.append(f"{lead} {name} | {direct:.3f} | {threaded:.3f} |")
        lines.append(f"| | | | work: {work.full_exports} full export, {work.mesh_exports} mesh reads, "
                     f"{work.accel_static_builds} static + {work.accel_dynamic_builds} dynamic builds, "
                     f"{work.material_updates} material / {work.light_updates} light updates | | |")
    bpy.app.handlers.depsgraph_update_post.remove(recorder)
    lines += ["", f"Targets (issue 4): under {TARGET_EDIT_S} s from a transform edit to the next frame at "
                  f"QUARTER scale; at least {TARGET_FPS:g} frames/s at 320x180.", ""]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blend", type=Path, default=BLEND)
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--scales", nargs="+", default=["HALF", "QUARTER"])
    ap.add_argument("--mode", default="RESTIR_BIASED")
    ap.add_argument("--bounces", type=int, default=None, help="max bounces (default: the file's)")
    ap.add_argument("--light-samples", type=int, default=None, help="default: the file's")
    ap.add_argument("--no-twin", action="store_true", help="the viewport's passes on threads, no twin process")
    ap.add_argument("--frames", type=int, default=3, help="steady frames timed per scale")
    ap.add_argument("--repeats", type=int, default=2, help="edits of each kind per measure")
    ap.add_argument("--big-triangles", type=int, default=1_000_000)
    ap.add_argument("--rays", type=int, default=1 << 19)
    ap.add_argument("--skip-accel", action="store_true")
    args = ap.parse_args()

    load_addon()
    lines = ["# Viewport benchmark", ""]
    if not args.skip_accel:
        part_accel(args.big_triangles, args.rays, lines)
    part_viewport(args, lines)
    text = "\n".join(lines)
    print()
    print(text)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "viewport.md").write_text(text + "\n")


if __name__ == "__main__":
    main()
