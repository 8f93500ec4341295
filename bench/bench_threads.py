"""How much two threads can give numpy work of a frame's size on this
machine, against two processes: the ceiling for core/parallel.py's workers.

The workload is a chain of small numpy operations (ufuncs, np.take of rows,
clip) over arrays of --pixels rows, the shape of the per-pixel passes of a
ReSTIR frame split in two; it is run twice in one thread, once in each of two
threads, and once in each of two processes. Medians over --repeats.

    .venv/bin/python bench/bench_threads.py [--pixels 28800] [--repeats 5]
"""

import argparse
import statistics
import time
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor

import numpy as np


def work(pixels, ops=300):
    rng = np.random.default_rng(1)
    x = rng.random((pixels, 3), dtype=np.float32)
    idx = rng.integers(0, pixels, pixels)
    for _ in range(ops):
        y = np.sqrt(x * x + 1.0) * 0.5 + x.take(idx, axis=0) - np.exp(-x)
        x = np.clip(y, 0, 1)
    return float(x.sum())


def timed(fn):
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pixels", type=int, default=28800, help="rows per worker (320x180 / 2)")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    n = args.pixels
    work(n)
    with ThreadPoolExecutor(2) as threads, ProcessPoolExecutor(2) as procs:
        list(procs.map(work, [n, n]))           # start the processes
        one, two_t, two_p = [], [], []
        for _ in range(args.repeats):
            one.append(timed(lambda: (work(n), work(n))))
            two_t.append(timed(lambda: list(threads.map(work, [n, n]))))
            two_p.append(timed(lambda: list(procs.map(work, [n, n]))))
    m1, mt, mp = (statistics.median(v) for v in (one, two_t, two_p))
    print(f"numpy op chain over {n} rows, two jobs, medians of {args.repeats}")
    print(f"one thread     {m1:.3f} s")
    print(f"two threads    {mt:.3f} s   speedup {m1 / mt:.2f}x")
    print(f"two processes  {mp:.3f} s   speedup {m1 / mp:.2f}x")


if __name__ == "__main__":
    main()
