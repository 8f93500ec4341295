"""Animation renders of a production-size scene: what a frame spends preparing
the scene (export from Blender, Embree) against rendering it.

The scene is example_blends/room_animated.blend (camera and a box moving)
plus a generated heightfield of ``--tris`` triangles standing in the room, as
a sculpted or scanned asset would. Frames are rendered as a user renders an
animation (``bpy.ops.render.render(animation=True)``) in ReSTIR GI biased mode
at the file's 320x180, with persistent data off and on (Render Properties >
Performance > Final Render > Persistent Data).

Printed per run: the first frame's export and Embree times, the median over
frames 2.. of (export + Embree) / render time, and the resident memory of the
process after the first and the last frame (``--frames 500`` for issue 11's
memory target).

    .venv/bin/python bench/bench_anim.py [--frames 24] [--tris 1000000]
"""

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import OUT, ROOT, captured_output, load_addon

BLEND = ROOT / "example_blends" / "room_animated.blend"


def rss_mb():
    """Resident memory of this process in MB (Linux /proc; peak elsewhere)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    import resource
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def add_heightfield(bpy, n_tris, location=(1.2, -0.9, 0.0), size=1.0):
    """A bumpy square of about ``n_tris`` triangles, built with foreach_set."""
    n = max(2, int(round((n_tris / 2) ** 0.5)) + 1)       # vertices per side
    u = np.linspace(-0.5, 0.5, n, dtype=np.float32) * size
    x, y = np.meshgrid(u, u, indexing="xy")
    z = 0.08 * (1.2 + np.sin(x * 23.0) * np.cos(y * 17.0)) + 0.02 * np.sin(x * 97.0 + y * 61.0)
    pos = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    i = np.arange(n - 1)
    a = (i[None, :] + i[:, None] * n).ravel()
    quads = np.stack([a, a + 1, a + n + 1, a + n], axis=1).astype(np.int32)
    me = bpy.data.meshes.new("Heightfield")
    me.vertices.add(len(pos))
    me.vertices.foreach_set("co", pos.ravel())
    me.loops.add(quads.size)
    me.loops.foreach_set("vertex_index", quads.ravel())
    me.polygons.add(len(quads))
    me.polygons.foreach_set("loop_start", np.arange(0, quads.size, 4, dtype=np.int32))
    me.polygons.foreach_set("loop_total", np.full(len(quads), 4, np.int32))
    me.update(calc_edges=True)
    me.validate()
    obj = bpy.data.objects.new("Heightfield", me)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    mat = bpy.data.materials.new("Clay")
    mat.diffuse_color = (0.6, 0.5, 0.4, 1.0)
    me.materials.append(mat)
    return len(quads) * 2


def run(bpy, final, frames, n_tris, persistent, log):
    bpy.ops.wm.open_mainfile(filepath=str(BLEND), load_ui=False)
    scene = bpy.context.scene
    tris = add_heightfield(bpy, n_tris)
    scene.render.engine = "RESTIR_GI"
    scene.restir_gi.mode = "RESTIR_BIASED"
    scene.render.use_persistent_data = persistent
    scene.frame_start, scene.frame_end = 1, frames
    r = scene.render
    r.image_settings.file_format = "PNG"
    per_frame, memory = {}, {}

    def post(sc, *_):
        per_frame[sc.frame_current] = dict(final.state.stream_for(sc.name, sc.view_layers[0].name).timings)
        memory[sc.frame_current] = rss_mb()

    with tempfile.TemporaryDirectory(prefix="restir-anim-") as tmp, captured_output(log):
        r.filepath = os.path.join(tmp, "frame_####")
        bpy.app.handlers.render_post.append(post)
        t0 = time.perf_counter()
        try:
            bpy.ops.render.render(animation=True, scene=scene.name)
        finally:
            bpy.app.handlers.render_post.remove(post)
        wall = time.perf_counter() - t0
    return tris, per_frame, memory, wall


def summary(per_frame):
    first = per_frame[min(per_frame)]
    later = [t for f, t in sorted(per_frame.items())[1:]]

    def prep(t):
        return t.get("export", 0.0) + t.get("accel", 0.0)

    share = statistics.median(prep(t) / max(t["render"], 1e-9) for t in later) if later else float("nan")
    return first, share, statistics.median(prep(t) for t in later) if later else float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--tris", type=int, default=1_000_000)
    ap.add_argument("--persistent", choices=["off", "on", "both"], default="both")
    args = ap.parse_args()
    load_addon()
    import bpy
    from restir_gi.restir_addon import final
    OUT.mkdir(parents=True, exist_ok=True)
    log = OUT / "bench_anim.log"
    modes = {"off": [False], "on": [True], "both": [False, True]}[args.persistent]
    run(bpy, final, 1, 1000, False, log)       # one-time costs (imports, tables) out of the figures
    print(f"room_animated.blend + heightfield, ReSTIR biased, {args.frames} frames")
    print(f"{'persistent':>10} {'tris':>9} {'1st export':>10} {'1st accel':>9} {'1st render':>10} "
          f"{'prep 2..':>9} {'render 2..':>10} {'prep/render':>11} {'RSS 1st':>8} {'RSS last':>8} {'wall':>7}")
    for persistent in modes:
        tris, per_frame, memory, wall = run(bpy, final, args.frames, args.tris, persistent, log)
        if not per_frame:
            print(f"{persistent!s:>10}: no frame rendered; see {log}")
            continue
        first, share, prep = summary(per_frame)
        later_render = statistics.median(t["render"] for f, t in sorted(per_frame.items())[1:]) \
            if len(per_frame) > 1 else float("nan")
        print(f"{'on' if persistent else 'off':>10} {tris:>9} {first.get('export', 0):>9.3f}s "
              f"{first.get('accel', 0):>8.3f}s {first['render']:>9.3f}s {prep:>8.3f}s {later_render:>9.3f}s "
              f"{100 * share:>10.1f}% {memory[min(memory)]:>7.0f}M {memory[max(memory)]:>7.0f}M {wall:>6.1f}s")


if __name__ == "__main__":
    main()
