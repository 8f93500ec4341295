"""How much two threads can give numpy work of a frame's size on this
machine, against two processes: the ceiling for core/workers/parallel.py's workers.

The workload is a chain of small numpy operations (ufuncs, np.take of rows,
clip) over arrays of --pixels rows, the shape of the per-pixel passes of a
ReSTIR frame split in two; it is run twice in one thread, once in each of two
threads, and once in each of two processes. Medians over --repeats.

Then single numpy calls of the kinds the passes make, each timed alone and
in two threads at once: a call that takes a few microseconds releases and
takes back the GIL for less work than the hand-over between threads costs,
so two threads run it slower than one (the passes' short arrays: paths that
ended, one material's hits).

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


def op_table(n, reps=300):
    """(name, microseconds alone, two-thread speedup) per kind of numpy call."""
    import threading
    rng = np.random.default_rng(0)
    a3 = rng.random((n, 3), dtype=np.float32)
    a1 = rng.random(n, dtype=np.float32)
    idx = rng.integers(0, n, n)
    half = rng.permutation(n)[: n // 2]
    u32 = rng.integers(0, 2 ** 32, n, dtype=np.uint32)
    ops = {
        "x * 2 + 1 (n floats)": lambda: a1 * 2.0 + 1.0,
        "hash: u * c ^ u >> 16 (uint32)": lambda: (u32 * np.uint32(0x9E3779B1)) ^ (u32 >> np.uint32(16)),
        "astype float32": lambda: u32.astype(np.float32),
        "a[idx] = v (1-D)": lambda: a1.__setitem__(half, a1[: len(half)]),
        "np.take rows (n, 3)": lambda: np.take(a3, idx, axis=0),
        "np.nonzero": lambda: np.nonzero(a1 > 0.3),
        "np.where (n, 3)": lambda: np.where((a1 > 0.3)[:, None], a3, 0.0),
        "np.bincount weighted": lambda: np.bincount(idx, weights=a1, minlength=n),
        "np.concatenate": lambda: np.concatenate([a3, a3]),
        "x[:2000] * 2": lambda: a1[:2000] * 2.0,
    }
    rows = []
    for name, fn in ops.items():
        fn()
        t1 = timed(lambda: [fn() for _ in range(reps)])
        ths = [threading.Thread(target=lambda: [fn() for _ in range(reps)]) for _ in range(2)]
        t = time.perf_counter()
        for th in ths:
            th.start()
        for th in ths:
            th.join()
        rows.append((name, t1 / reps * 1e6, 2 * t1 / (time.perf_counter() - t)))
    return rows


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
    print(f"\nsingle numpy calls over {n} rows: time alone, speedup of two threads calling at once")
    for name, us, speedup in op_table(n):
        print(f"  {name:32s} {us:8.1f} us   {speedup:.2f}x")


if __name__ == "__main__":
    main()
