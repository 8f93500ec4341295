"""Chunk warm-up: the first frame of a chunk (an animation render that starts
after the scene's first frame, as a farm renders it) against the same frame
of one continuous render, for several warm-up lengths.

    .venv/bin/python bench/bench_chunks.py [--blend FILE] [--chunk 8]
        [--warmups 0,2,4,8,16] [--seeds 0,1,2] [--ref-spp 1024] [--mode biased]

Per seed: one continuous render of the file's frame range, then, for each
warm-up length W and each chunk start S (frame_start + k * chunk, k >= 1), a
job of frame S alone with ``chunk_warmup_frames`` = W (W = 0: a cold start,
the file's still warm-up at frame S; a warm-up that starts after frame_start
starts with the file's still warm-up, or --fresh-frames). MSE against a Cycles reference of frame
S (--ref-spp, cached in bench/out/refs/). Printed per W: the MSE of the chunk
starts relative to the continuous render's MSE of the same frames (mean over
starts and seeds; 1.00 = the same quality), its spread over the seeds, and
the time the start frame took relative to a continuous frame (the warm-up's
cost). Renders through ``bpy.ops.render.render`` as bench/equal_time.py does.
"""

import argparse
import hashlib
import json
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import OUT, ROOT, load_addon, render_frames

MODES = {"biased": "RESTIR_BIASED", "unbiased": "RESTIR_UNBIASED"}


def ints(text):
    return [int(v) for v in text.split(",") if v.strip()]


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--blend", default=str(ROOT / "example_blends" / "corpus_room.blend"))
    p.add_argument("--chunk", type=int, default=8)
    p.add_argument("--warmups", type=ints, default=[0, 2, 4, 8, 16])
    p.add_argument("--seeds", type=ints, default=[0, 1, 2])
    p.add_argument("--ref-spp", type=int, default=1024)
    p.add_argument("--mode", choices=sorted(MODES), default="biased")
    p.add_argument("--fresh-frames", type=int, default=None,
                   help="frames on the still scene where a warm-up starts after frame_start "
                        "(default: the file's warm-up frames)")
    return p.parse_args()


def ours(mode, seed, warmup=None):
    def setup(scene):
        scene.render.engine = "RESTIR_GI"
        s = scene.restir_gi
        s.mode, s.seed = mode, seed
        if warmup is not None:
            s.chunk_warmup_frames = warmup
    return setup


def cycles_reference(blend, frame, spp):
    """Cycles at ``spp`` of one frame of the file (cached)."""
    from restir_gi.core.camera.film import read_exr, write_exr
    sha = hashlib.sha1(Path(blend).read_bytes()).hexdigest()[:12]
    path = OUT / "refs" / f"chunks_{Path(blend).stem}_f{frame}_{spp}spp_{sha}.exr"
    if path.exists():
        return read_exr(path)

    def setup(scene):
        scene.render.engine = "CYCLES"
        c = scene.cycles
        c.device, c.samples, c.seed = "CPU", spp, 1234
        c.use_denoising = c.use_adaptive_sampling = False

    print(f"  reference: Cycles {spp} spp of frame {frame} ...", flush=True)
    images, _, _ = render_frames(blend, [frame], setup)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_exr(path, images[frame])
    return images[frame]


def main():
    args = parse_args()
    addon = load_addon()
    addon.restir_addon.final.CHUNK_FRESH_FRAMES = args.fresh_frames
    import bpy
    bpy.ops.wm.open_mainfile(filepath=args.blend, load_ui=False)
    first, last = bpy.context.scene.frame_start, bpy.context.scene.frame_end
    starts = list(range(first + args.chunk, last + 1, args.chunk))
    if not starts:
        sys.exit(f"the frame range {first}..{last} has no chunk start after its first frame")
    mode = MODES[args.mode]
    refs = {s: cycles_reference(args.blend, s, args.ref_spp) for s in starts}

    def mse(img, ref):
        return float(((img - ref) ** 2).mean())

    ratios = {w: [] for w in args.warmups}
    times = {w: [] for w in args.warmups}
    for seed in args.seeds:
        images, seconds, _ = render_frames(args.blend, list(range(first, last + 1)), ours(mode, seed))
        frame_s = statistics.median(seconds[f] for f in range(first + 1, last + 1))
        cont = {s: mse(images[s], refs[s]) for s in starts}
        print(f"seed {seed}: continuous {frame_s * 1000:.0f} ms/frame, MSE at starts "
              + ", ".join(f"{s}: {e:.5f}" for s, e in cont.items()), flush=True)
        for w in args.warmups:
            row = []
            for s in starts:
                imgs, secs, _ = render_frames(args.blend, [s], ours(mode, seed, w), scene_start=first)
                e = mse(imgs[s], refs[s])
                row.append(e / cont[s])
                times[w].append(secs[s] / frame_s)
            ratios[w].append(statistics.mean(row))
            print(f"  warm-up {w:3d}: MSE / continuous " + ", ".join(f"{r:.2f}" for r in row)
                  + f"  (start frame {statistics.mean(times[w][-len(starts):]):.1f} frames' time)",
                  flush=True)

    fresh = "" if args.fresh_frames is None else f", {args.fresh_frames} fresh frame(s)"
    lines = [f"Chunk starts of {Path(args.blend).name} ({args.mode}{fresh}, chunks of {args.chunk}, starts "
             f"{starts}, seeds {args.seeds}, reference Cycles {args.ref_spp} spp)", "",
             "| chunk warm-up | MSE / continuous (mean) | per seed | start frame time / frame time |",
             "|---|---|---|---|"]
    for w in args.warmups:
        label = "0 (cold start)" if w == 0 else str(w)
        lines.append(f"| {label} | {statistics.mean(ratios[w]):.2f} | "
                     + ", ".join(f"{r:.2f}" for r in ratios[w])
                     + f" | {statistics.median(times[w]):.1f} |")
    text = "\n".join(lines)
    print("\n" + text)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "bench_chunks.md").write_text(text + "\n")
    (OUT / "bench_chunks.json").write_text(json.dumps({"ratios": ratios, "times": times}))


if __name__ == "__main__":
    main()
