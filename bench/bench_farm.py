"""A chunked render on local Dask workers against one continuous render.

    .venv/bin/python bench/bench_farm.py [--blend FILE] [--workers 2] [--chunk 8]
        [--repeats 1]

Both through the installed extension, as users render (``make build`` first):
``tools/render.py BLEND`` (one process, both cores) and ``tools/farm.py BLEND
--chunk N --workers K`` (K processes of cores/K threads each, every chunk with
the file's chunk warm-up). Printed: wall time of each, their ratio, and the
warm-up's share of the chunked render: per chunk, its first frame's time less
the median time of its other frames, summed over chunks, over the sum of all
chunk times (the same measure for the continuous render's first frame, whose
warm-up is the file's still warm-up). Medians over --repeats.
"""

import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TOOLS = ROOT / "tools"
CHUNK_LINE = re.compile(r"chunk (-?\d+)-(-?\d+) done on \S+ in ([\d.]+) s"
                        r"(?: \(first frame ([\d.]+) s, the others ([\d.]+) s median\))?")
FRAME_LINE = re.compile(r"^\[render\] frame (-?\d+) \(\d+/\d+\): ([\d.]+) s", re.M)


def frame_range(blend):
    code = ("import bpy, sys; bpy.ops.wm.open_mainfile(filepath=sys.argv[1]); "
            "s = bpy.context.scene; print('RANGE', s.frame_start, s.frame_end)")
    out = subprocess.run([sys.executable, "-c", code, str(blend)], capture_output=True, text=True,
                         check=True).stdout
    a, b = re.search(r"RANGE (-?\d+) (-?\d+)", out).groups()
    return int(a), int(b)


def timed(cmd):
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.exit(f"failed: {' '.join(map(str, cmd))}\n{proc.stdout}\n{proc.stderr}")
    return time.perf_counter() - t0, proc.stdout


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--blend", default=str(ROOT / "example_blends" / "room_animated.blend"))
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--chunk", type=int, default=8)
    p.add_argument("--repeats", type=int, default=1)
    args = p.parse_args()
    first, last = frame_range(args.blend)
    frames = last - first + 1
    rows = {"continuous": [], "chunked": [], "warmup": [], "cont_first": []}
    for _ in range(args.repeats):
        with tempfile.TemporaryDirectory(prefix="restir-farm-bench-") as tmp:
            t, out = timed([sys.executable, TOOLS / "render.py", args.blend, "--output",
                            os.path.join(tmp, "continuous")])
            times = [float(s) for _, s in FRAME_LINE.findall(out)]
            rows["continuous"].append(t)
            rows["cont_first"].append((times[0] - statistics.median(times[1:])) / sum(times))
            t, out = timed([sys.executable, TOOLS / "farm.py", args.blend, "--frames",
                            f"{first}-{last}", "--chunk", str(args.chunk), "--workers",
                            str(args.workers), "--out", os.path.join(tmp, "chunked")])
            rows["chunked"].append(t)
            chunks = CHUNK_LINE.findall(out)
            total = sum(float(c[2]) for c in chunks)
            extra = sum(float(c[3]) - float(c[4]) for c in chunks if c[3])
            rows["warmup"].append(extra / total)
            shutil.rmtree(tmp, ignore_errors=True)
    med = {k: statistics.median(v) for k, v in rows.items()}
    lines = [f"{Path(args.blend).name}: {frames} frames, chunks of {args.chunk} on {args.workers} "
             f"local workers, {args.repeats} repeat(s), medians", "",
             "| render | wall time | first frames' extra time / render time |", "|---|---|---|",
             f"| continuous (tools/render.py) | {med['continuous']:.1f} s | "
             f"{med['cont_first'] * 100:.0f} % (still warm-up) |",
             f"| chunked (tools/farm.py) | {med['chunked']:.1f} s | "
             f"{med['warmup'] * 100:.0f} % (chunk warm-ups, summed over workers) |",
             "", f"chunked / continuous wall time: {med['chunked'] / med['continuous']:.2f}"]
    text = "\n".join(lines)
    print(text)
    out_dir = ROOT / "bench" / "out"
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "bench_farm.md").write_text(text + "\n")


if __name__ == "__main__":
    main()
