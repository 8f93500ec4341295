#!/usr/bin/env python3
"""Render an animation in chunks of frames on a Dask cluster.

    python tools/farm.py BLEND --frames A-B --chunk N --out DIR
        [--scheduler ADDRESS] [--workers K] [--retries R] [--threads T]
        [--chunk-warmup W] [--samples S]

The frame range is split into chunks of N frames; each chunk is one task on a
Dask distributed cluster (``--scheduler tcp://host:8786``, or without it a
LocalCluster of K worker processes on this machine). A task runs the headless
render of its chunk, ``tools/render.py BLEND --frames a-b --output DIR
--skip-existing`` (the ``make render`` path: the installed extension, EXR and
PNG per frame), in a subprocess. The engine's chunk warm-up renders the frames
before a chunk (not written), so a chunk's first frame continues from the
history a continuous render would have there.

Nothing is lost or written twice: render.py writes each frame under
DIR/.partial/ and renames it into DIR once complete, and skips frames already
in DIR, so a rerun of this command resumes and a retried chunk renders only
its missing frames. A chunk whose render fails (its process dies, or Blender
reports an error) is retried, up to R times, preferably on another worker.
Progress (frames in DIR out of the range, seconds per frame, time left) is
printed while it runs, and a summary at the end. Exit status: 0 when every
frame of the range is in DIR, 1 when some are missing, 2 on bad arguments, an
unreachable scheduler or a configuration error (nothing written then).

Configuration is checked once, before any chunk is submitted (farm_setup.py):
the .blend, the extension package (built for this platform and the workers'
Python), the workers' Python (with bpy) and repository, the output folder. On
a cluster every worker checks its own. A problem stops the farm at once with what to do
about it; so does a chunk whose render refuses its configuration (render.py's
exit status 2), instead of being retried.

Cluster workers need this repository (at the same path, or --worker-repo) and
its Python environment (``make venv``; --worker-python), with the extension
package built (``make build``); the .blend and DIR must be at the same paths
on every worker (a shared file system).
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field

import farm_setup
from frame_range import chunks, parse_range

REPO_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DASK_WORKER_ENV = ("MALLOC_TRIM_THRESHOLD_",)
FRAME_LINE = re.compile(r"^\[render\] frame (-?\d+) \(\d+/\d+\): ([\d.]+) s")


def log(msg: str) -> None:
    print("[farm] " + msg, flush=True)


def fail(msg: str, code: int = 2) -> None:
    print("[farm] error: " + msg, file=sys.stderr, flush=True)
    sys.exit(code)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(
        description="Render BLEND's frames A-B in chunks of N frames on a Dask cluster "
                    "(a LocalCluster of --workers processes without --scheduler), "
                    "EXR + PNG per frame into DIR; rerun to resume.")
    p.add_argument("blend", help=".blend file to render")
    p.add_argument("--frames", required=True, metavar="A-B", help="frame range, e.g. 1-240")
    p.add_argument("--chunk", required=True, type=int, metavar="N", help="frames per task")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of a Dask scheduler (tcp://host:8786); default: a LocalCluster")
    p.add_argument("--workers", type=int, default=2, metavar="K",
                   help="worker processes of the LocalCluster (default 2)")
    p.add_argument("--retries", type=int, default=2, metavar="R",
                   help="times a failed chunk is tried again (default 2)")
    p.add_argument("--threads", type=int, default=None, metavar="T",
                   help="render threads per chunk (default: this machine's cores / workers for a "
                        "LocalCluster, the file's setting on a cluster)")
    p.add_argument("--chunk-warmup", type=int, default=None, metavar="W",
                   help="frames rendered (not written) before each chunk (default: the file's "
                        "Chunk Warm-up setting)")
    p.add_argument("--samples", type=int, default=None, help="override the file's samples")
    p.add_argument("--timeout", type=float, default=10.0,
                   help="seconds to wait for the scheduler (default 10)")
    p.add_argument("--worker-python", default=sys.executable,
                   help="Python with bpy on the workers (default: this one)")
    p.add_argument("--worker-repo", default=REPO_ROOT,
                   help="this repository's path on the workers (default: the same as here)")
    p.add_argument("--package", default=None, metavar="ZIP",
                   help="extension package the renders install (default: render.py's, "
                        "dist/<id>-<version>.zip in the workers' repository)")
    p.add_argument("--user-resources", default=None, metavar="DIR",
                   help="Blender user folder the renders use (default: render.py's, .blender_user/)")
    args = p.parse_args(argv)
    rng = parse_range(args.frames)
    if rng is None:
        fail(f"--frames {args.frames!r}: want A-B with A <= B (an empty range renders nothing)")
    args.first, args.last = rng
    for name, low in (("chunk", 1), ("workers", 1), ("retries", 0)):
        if getattr(args, name) < low:
            fail(f"--{name} must be at least {low} (got {getattr(args, name)})")
    if args.threads is not None and args.threads < 1:
        fail("--threads must be at least 1")
    if args.chunk_warmup is not None and args.chunk_warmup < 0:
        fail("--chunk-warmup must be at least 0")
    if not os.path.isfile(args.blend):
        fail(f"blend file not found: {args.blend}")
    args.blend = os.path.abspath(args.blend)
    args.out = os.path.abspath(args.out)
    return args


def check_setup(args, client=None) -> None:
    """Stops the farm with every configuration problem, before any task is
    submitted: checked here (a LocalCluster's workers are this machine), or
    by each worker of a cluster (client)."""
    package = os.path.abspath(args.package) if args.package is not None else None
    user = os.path.abspath(args.user_resources) if args.user_resources is not None else None
    call = (args.blend, args.out, args.worker_repo, args.worker_python, package, user)
    if client is None:
        found = {"": farm_setup.setup_problems(*call)}
    else:
        # Sent by value: a worker need not find tools/ on its Python path.
        import cloudpickle
        cloudpickle.register_pickle_by_value(farm_setup)
        found = client.run(farm_setup.setup_problems, *call)
    lines = [(f"{worker}: " if worker else "") + problem
             for worker, problems in sorted(found.items()) for problem in problems]
    if lines:
        fail("configuration (nothing was rendered):\n  " + "\n  ".join(lines))


def frame_files(out: str, frame: int) -> list[str]:
    return [os.path.join(out, f"frame_{frame:04d}.{ext}") for ext in ("exr", "png")]


def frames_done(out: str, frames: range) -> set[int]:
    return {f for f in frames if all(os.path.isfile(p) for p in frame_files(out, f))}


class ChunkFailed(RuntimeError):
    """A chunk's render exited with an error: which worker, which frames it
    wrote before that, and the end of its output."""

    def __init__(self, worker: str, written: list[int], message: str, config: bool = False):
        super().__init__(worker, written, message, config)
        self.worker, self.written, self.message = worker, written, message
        # render.py's exit status 2: bad arguments or missing files, which a
        # retry does not mend.
        self.config = config

    def __str__(self):
        return self.message


def render_chunk(python: str, repo: str, blend: str, first: int, last: int, out: str,
                 options: list[str]) -> tuple[str, dict[int, float], float]:
    """One task: the headless render of frames first..last in a subprocess.
    Returns (worker address, {frame written: seconds it took}, seconds in
    all); raises ChunkFailed."""
    try:
        from distributed import get_worker
        worker = get_worker().address
    except (ImportError, ValueError):
        worker = "local"
    cmd = [python, os.path.join(repo, "tools", "render.py"), blend,
           "--frames", f"{first}-{last}", "--output", out, "--skip-existing", *options]
    # Dask's worker processes set MALLOC_TRIM_THRESHOLD_ low for themselves;
    # inherited, it makes every large array a fresh mmap and page faults take
    # over the render (three times slower, half of it system time).
    env = {k: v for k, v in os.environ.items() if k not in DASK_WORKER_ENV}
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=repo, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          text=True, errors="replace")
    written = {int(m.group(1)): float(m.group(2))
               for m in map(FRAME_LINE.match, proc.stdout.splitlines()) if m}
    if proc.returncode != 0:
        lines = [line for line in proc.stdout.splitlines() if line.strip()]
        errors = [line for line in lines if "error" in line.lower()]
        tail = (errors or lines)[-3:]
        how = (f"killed by signal {-proc.returncode}" if proc.returncode < 0
               else f"exit status {proc.returncode}")
        raise ChunkFailed(worker, sorted(written), f"frames {first}-{last} on {worker}: render {how}"
                          + (": " + " | ".join(tail) if tail else ""), config=proc.returncode == 2)
    return worker, written, time.perf_counter() - t0


@dataclass
class Summary:
    frames: int = 0                   # in the range
    skipped: int = 0                  # already in DIR at the start
    written: list = field(default_factory=list)     # frame numbers, every attempt
    retries: int = 0
    failures: list = field(default_factory=list)    # messages of failed attempts
    config_error: str = ""            # a chunk refused its configuration: the farm stopped
    seconds: float = 0.0


def connect(args):
    """A Dask client: the given scheduler, or a LocalCluster on this machine."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        fail("the farm needs the packages dask and distributed (make venv installs them)")
    import logging
    logging.getLogger("distributed").setLevel(logging.ERROR)
    if args.scheduler is None:
        cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=logging.ERROR)
        return Client(cluster), cluster
    try:
        return Client(args.scheduler, timeout=args.timeout), None
    except (OSError, TimeoutError) as exc:
        fail(f"cannot reach the Dask scheduler at {args.scheduler}: {exc}")


def render_options(args) -> list[str]:
    options = []
    threads = args.threads
    if threads is None and args.scheduler is None:
        threads = max(1, (os.cpu_count() or 1) // args.workers)
    if threads is not None:
        options += ["--threads", str(threads)]
    if args.chunk_warmup is not None:
        options += ["--chunk-warmup", str(args.chunk_warmup)]
    if args.samples is not None:
        options += ["--samples", str(args.samples)]
    for flag, value in (("--package", args.package), ("--user-resources", args.user_resources)):
        if value is not None:
            options += [flag, os.path.abspath(value)]
    return options


def run(args) -> Summary:
    from distributed import as_completed

    frames = range(args.first, args.last + 1)
    summary = Summary(frames=len(frames))
    done_before = frames_done(args.out, frames) if os.path.isdir(args.out) else set()
    summary.skipped = len(done_before)
    todo = [c for c in chunks(args.first, args.last, args.chunk)
            if not set(range(c[0], c[1] + 1)) <= done_before]
    if not todo:
        log(f"all {len(frames)} frames are already in {args.out}")
        return summary

    if args.scheduler is None:
        check_setup(args)
    client, cluster = connect(args)
    if cluster is None:
        try:
            check_setup(args, client)
        except SystemExit:
            client.close()
            raise
    os.makedirs(args.out, exist_ok=True)
    options = render_options(args)
    workers = sorted(client.scheduler_info()["workers"])
    log(f"{len(frames)} frames ({summary.skipped} already done) in {len(todo)} chunks of up to "
        f"{args.chunk} on {len(workers)} workers; output {args.out}")
    attempts = {}
    live = {}
    t0 = time.perf_counter()

    def submit(chunk, avoid=None):
        others = [w for w in workers if w != avoid]
        fut = client.submit(render_chunk, args.worker_python, args.worker_repo, args.blend,
                            chunk[0], chunk[1], args.out, options, pure=False,
                            workers=others or None, allow_other_workers=True)
        attempts[fut.key] = chunk
        live[fut.key] = fut
        return fut

    tries = {c: 0 for c in todo}
    stop = threading.Event()

    def report_progress():
        while not stop.wait(5.0):
            progress(args, frames, done_before, time.perf_counter() - t0)

    reporter = threading.Thread(target=report_progress, daemon=True)
    reporter.start()
    pending = as_completed([submit(c) for c in todo])
    try:
        for fut in pending:
            chunk = attempts.pop(fut.key)
            live.pop(fut.key, None)
            try:
                worker, written, seconds = fut.result()
                summary.written += sorted(written)
                times = [written[f] for f in sorted(written)]
                rest = sorted(times[1:])
                detail = (f" (first frame {times[0]:.1f} s, the others {rest[len(rest) // 2]:.2f} s "
                          f"median)" if rest else "")
                log(f"chunk {chunk[0]}-{chunk[1]} done on {worker} in {seconds:.1f} s{detail}")
            except Exception as exc:        # noqa: BLE001 -- ChunkFailed, a lost worker, ...
                summary.written += getattr(exc, "written", [])
                summary.failures.append(str(exc) or type(exc).__name__)
                log(f"chunk {chunk[0]}-{chunk[1]} failed: {summary.failures[-1]}")
                if getattr(exc, "config", False):
                    # The same on every try: stop, and say so once.
                    summary.config_error = summary.failures[-1]
                    client.cancel(list(live.values()))
                    break
                if tries[chunk] < args.retries:
                    tries[chunk] += 1
                    summary.retries += 1
                    log(f"chunk {chunk[0]}-{chunk[1]}: retry {tries[chunk]} of {args.retries}")
                    pending.add(submit(chunk, avoid=getattr(exc, "worker", None)))
        progress(args, frames, done_before, time.perf_counter() - t0)
    finally:
        stop.set()
        summary.seconds = time.perf_counter() - t0
        client.close()
        if cluster is not None:
            cluster.close()
    return summary


def progress(args, frames, done_before, elapsed):
    done = frames_done(args.out, frames)
    new = len(done - done_before)
    left = len(frames) - len(done)
    eta = f", about {elapsed / new * left:.0f} s left" if new and left else ""
    log(f"{len(done)}/{len(frames)} frames done ({elapsed:.0f} s{eta})")


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    summary = run(args)
    frames = range(args.first, args.last + 1)
    missing = sorted(set(frames) - frames_done(args.out, frames)) if os.path.isdir(args.out) \
        else list(frames)
    new = len(summary.written)
    per_frame = summary.seconds / new if new else 0.0
    log(f"summary: {summary.frames} frames, {new} rendered ({per_frame:.2f} s per frame "
        f"over {summary.seconds:.1f} s), {summary.skipped} already done, "
        f"{summary.retries} retries, {len(summary.failures)} failed attempts")
    for msg in summary.failures:
        log("  failure: " + msg)
    if summary.config_error:
        fail("a render refused its configuration, so the farm stopped without retrying: "
             + summary.config_error)
    if missing:
        log(f"missing frames: {', '.join(map(str, missing))}")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
