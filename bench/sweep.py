#!/usr/bin/env python3
"""Render every .blend file under a folder in every mode, through the installed extension.

    .venv/bin/python bench/sweep.py DIR [--size 64x64] [--warmup 16] [--timeout 120]
                                        [--modes path,biased,unbiased] [--camera]
                                        [--jobs 1] [--output sweep] [--resume]

A robustness sweep over files made by others (e.g. the test scenes of other
projects' public repositories): does the engine render them at all? Each file
is rendered as a still (the frame it was saved at) in each mode (Path Tracing,
ReSTIR GI Biased, ReSTIR GI Unbiased), each render in a Python subprocess of
its own (``bench/sweep_render.py``) that imports the ``bpy`` module, enables
the extension installed from the built package (``make build``; installed as
``tools/render.py`` does, into ``--user-resources``), opens the file, selects
the engine and renders with ``bpy.ops.render.render``, under a time limit. The size (resolution at 100 %)
and the warm-up frames are set on every file; everything else is the file's.

Per file and mode the result is one of

- ``rendered``: finished, no NaN or Inf in any pass of the result;
- ``nan``: finished, but a pass holds NaN or Inf pixels (counted, passes named);
- ``failed``: the engine reported an error (``RenderEngine.report``, e.g.
  ``ReSTIR GI render failed: ...``, which makes Blender's render operator
  raise) or a Python exception escaped it; the first line of the error is
  kept, and where the subprocess printed a traceback, the innermost frame in
  the extension's code;
- ``crashed``: the subprocess died by a signal or exited without its result;
- ``timeout``: still running after ``--timeout`` seconds (killed);

with the render's time (the render operator alone, without Blender's start-up
and the loading of the file). Files that are not .blend files (Git LFS
pointers of repositories checked out without LFS) are listed as skipped.

With ``--camera`` every file gets a camera that frames all its visible
geometry: a file without a camera gets a new one (looking down from the front
right, like Blender's default camera); a scene camera is kept with its
direction and lens but moved (parent, constraints and animation removed) so
everything visible is in view. Real test files often have no camera, or one
pointing elsewhere.

Writes ``OUTPUT.md`` (counts per mode, a table with one row per file, the
errors in full) and ``OUTPUT.json`` (every result), both naming files by
their path relative to DIR. The JSON is rewritten after every render, and
``--resume`` keeps the results already in it for the same settings, so an
interrupted sweep carries on where it stopped. ``--logs LOGDIR`` keeps each
subprocess's output (tracebacks included), ``--images IMGDIR`` each finished
render as a PNG.

Exit status: 0 when every render finished without NaN, 1 otherwise, 2 on bad
arguments.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from sweep_report import MODE_TITLES, STATUSES, display_command, write_report  # noqa: E402

REPO_ROOT = os.path.dirname(HERE)
# One render, in a subprocess of its own (imports bpy).
RENDER = os.path.join(HERE, "sweep_render.py")

MODES = {"path": "PATH", "biased": "RESTIR_BIASED", "unbiased": "RESTIR_UNBIASED"}


def parse_size(text: str) -> tuple[int, int]:
    m = re.fullmatch(r"\s*(\d+)\s*(?:[xX]\s*(\d+)\s*)?", text)
    if m is None:
        raise argparse.ArgumentTypeError("size wants WxH (e.g. 64x64) or N")
    w = int(m.group(1))
    h = int(m.group(2)) if m.group(2) else w
    if w < 4 or h < 4:
        raise argparse.ArgumentTypeError("size must be at least 4x4")
    return w, h


def parse_modes(text: str) -> list[str]:
    modes = []
    for word in text.split(","):
        key = word.strip()
        mode = MODES.get(key.lower(), key.upper() if key.upper() in MODES.values() else None)
        if mode is None:
            raise argparse.ArgumentTypeError(
                "unknown mode {!r}: use {} (or {})".format(
                    key, ", ".join(MODES), ", ".join(MODES.values())))
        if mode not in modes:
            modes.append(mode)
    return modes


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description="Render every .blend under DIR in every mode through the installed "
                    "ReSTIR GI extension, one subprocess per render, and report per file and "
                    "mode: rendered / failed / crashed / timed out / NaN, and the time.")
    parser.add_argument("folder", metavar="DIR", nargs="?", help="folder searched for .blend files (recursively)")
    parser.add_argument("--size", type=parse_size, default=(64, 64), metavar="WxH",
                        help="render resolution (default 64x64)")
    parser.add_argument("--warmup", type=int, default=16, metavar="N",
                        help="ReSTIR warm-up frames of the still (default 16)")
    parser.add_argument("--samples", type=int, default=None, metavar="N",
                        help="samples per pixel in Path Tracing (default: the file's setting)")
    parser.add_argument("--timeout", type=float, default=120.0, metavar="S",
                        help="time limit per render in seconds, Blender's start-up included "
                             "(default 120)")
    parser.add_argument("--modes", type=parse_modes, default=list(MODES.values()),
                        metavar="M,M", help="modes to render: path, biased, unbiased "
                                            "(default: all three)")
    parser.add_argument("--camera", action="store_true",
                        help="frame all visible objects: add a camera to files without one, "
                             "move the scene camera of the others")
    parser.add_argument("--jobs", type=int, default=1, metavar="N",
                        help="renders at the same time (default 1)")
    parser.add_argument("--threads", type=int, default=None, metavar="N",
                        help="render threads per render (default: the file's setting)")
    parser.add_argument("--limit", type=int, default=None, metavar="N",
                        help="only the first N files (sorted by path)")
    parser.add_argument("--output", default="sweep", metavar="PATH",
                        help="writes PATH.md and PATH.json (default: sweep in the working folder)")
    parser.add_argument("--resume", action="store_true",
                        help="keep the results already in PATH.json made with the same settings")
    parser.add_argument("--logs", default=None, metavar="LOGDIR",
                        help="keep each render's output (stdout and stderr) in LOGDIR")
    parser.add_argument("--images", default=None, metavar="IMGDIR",
                        help="keep each finished render as a PNG in IMGDIR")
    parser.add_argument("--package", default=None, metavar="ZIP",
                        help="extension package (default: dist/<id>-<version>.zip, `make build`)")
    parser.add_argument("--user-resources", default=os.path.join(REPO_ROOT, ".blender_user"),
                        metavar="DIR", help="Blender user folder the package is installed into "
                                            "(default: .blender_user in the repository)")
    args = parser.parse_args(argv)
    if args.warmup < 1:
        parser.error("--warmup must be at least 1")
    if args.samples is not None and args.samples < 1:
        parser.error("--samples must be at least 1")
    if args.jobs < 1:
        parser.error("--jobs must be at least 1")
    if args.timeout <= 0:
        parser.error("--timeout must be positive")
    if args.folder is None:
        parser.error("the folder DIR is required")
    if not os.path.isdir(args.folder):
        parser.error("not a folder: {}".format(args.folder))
    return args


def is_blend(path: str) -> bool:
    """A .blend file: plain, gzip or zstd compressed (not a Git LFS pointer)."""
    with open(path, "rb") as fh:
        head = fh.read(7)
    return head == b"BLENDER" or head[:2] == b"\x1f\x8b" or head[:4] == b"\x28\xb5\x2f\xfd"


def find_blends(folder: str) -> list[str]:
    """Paths relative to `folder` of every *.blend below it, sorted."""
    found = []
    for root, dirs, files in os.walk(folder):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        found += [os.path.relpath(os.path.join(root, f), folder)
                  for f in files if f.lower().endswith(".blend")]
    return sorted(found, key=lambda p: p.replace(os.sep, "/"))


def settings_of(args: argparse.Namespace) -> dict:
    """What makes results comparable: --resume keeps only results made with these."""
    return {"size": "{}x{}".format(*args.size), "warmup": args.warmup, "samples": args.samples,
            "camera": args.camera, "timeout": args.timeout, "threads": args.threads}


def package_path(args: argparse.Namespace) -> str:
    if args.package is not None:
        return os.path.abspath(args.package)
    import tomllib
    with open(os.path.join(REPO_ROOT, "blender_manifest.toml"), "rb") as fh:
        manifest = tomllib.load(fh)
    return os.path.join(REPO_ROOT, "dist", "{}-{}.zip".format(manifest["id"], manifest["version"]))


# Innermost frame of a traceback inside the installed package: the path after
# the package folder (".../restir_gi/core/materials/shading.py") is the repository's.
FRAME_RE = re.compile(r'File "[^"]*[/\\]restir_gi[/\\]([^"]+)", line (\d+), in (\S+)')


def innermost_frame(output: str) -> str | None:
    frames = FRAME_RE.findall(output)
    if not frames:
        return None
    path, line, func = frames[-1]
    return "{}:{} in {}".format(path.replace("\\", "/"), line, func)


def run_one(args: argparse.Namespace, zip_path: str, rel: str, mode: str, tmp: str) -> dict:
    """Render one file in one mode in a subprocess; the result as a dict."""
    tag = "{}.{}".format(re.sub(r"[^A-Za-z0-9_.-]+", "_", rel), mode)
    spec = {"blend": os.path.join(os.path.abspath(args.folder), rel), "mode": mode,
            "size": list(args.size), "warmup": args.warmup, "samples": args.samples,
            "camera": args.camera, "threads": args.threads, "package": zip_path,
            "user_resources": os.path.abspath(args.user_resources),
            "result": os.path.join(tmp, tag + ".json"),
            "image": os.path.join(tmp, tag + ".exr"),
            "png": os.path.join(os.path.abspath(args.images), tag + ".png") if args.images else None}
    log_path = os.path.join(args.logs or tmp, tag + ".log")
    entry = {"file": rel.replace(os.sep, "/"), "mode": mode}
    t0 = time.perf_counter()
    with open(log_path, "w+", errors="replace") as log:
        # A session of its own: a render that runs over its time is killed
        # with everything it started.
        proc = subprocess.Popen([sys.executable, RENDER, json.dumps(spec)],
                                stdout=log, stderr=subprocess.STDOUT, cwd=tmp,
                                start_new_session=True)
        try:
            code = proc.wait(timeout=args.timeout)
        except subprocess.TimeoutExpired:
            if hasattr(os, "killpg"):
                os.killpg(proc.pid, signal.SIGKILL)
            else:
                proc.kill()
            proc.wait()
            code = None
        log.seek(0)
        output = log.read()
    entry["wall_seconds"] = round(time.perf_counter() - t0, 2)
    result = None
    if code is not None and os.path.isfile(spec["result"]):
        with open(spec["result"]) as fh:
            result = json.load(fh)
    for path in (spec["result"], spec["image"]) + (() if args.logs else (log_path,)):
        if os.path.exists(path):
            os.remove(path)
    if result is not None:
        entry.update(result)
    if code is None:
        entry.update(status="timeout", error="still running after {:g} s".format(args.timeout))
    elif code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = "signal {}".format(-code)
        entry.update(status="crashed", error="killed by {}{}".format(
            name, " after the render finished" if result is not None else ""))
    elif result is None:
        entry.update(status="crashed", error="exited with status {} without a result".format(code))
    if entry["status"] in ("failed", "crashed"):
        where = innermost_frame(output)
        if where:
            entry["where"] = where
    return entry


def install(args: argparse.Namespace, zip_path: str, tmp: str) -> None:
    """Install (or enable) the package once before the renders start."""
    spec = {"install_only": True, "package": zip_path,
            "user_resources": os.path.abspath(args.user_resources)}
    proc = subprocess.run([sys.executable, RENDER, json.dumps(spec)],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=tmp,
                          timeout=600)
    if proc.returncode != 0:
        sys.exit("[sweep] error: installing the extension failed:\n" + proc.stdout)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    args = parse_args(argv)
    zip_path = package_path(args)
    if not os.path.isfile(zip_path):
        sys.exit("[sweep] error: extension package not found: {} (build it with `make build`)"
                 .format(os.path.relpath(zip_path)))
    all_files = find_blends(args.folder)
    skipped = [f for f in all_files if not is_blend(os.path.join(args.folder, f))]
    files = [f for f in all_files if f not in skipped][:args.limit]
    if not files:
        sys.exit("[sweep] error: no .blend files under {}".format(args.folder))
    for folder in (args.logs, args.images):
        if folder:
            os.makedirs(folder, exist_ok=True)
    out_dir = os.path.dirname(os.path.abspath(args.output))
    os.makedirs(out_dir, exist_ok=True)
    json_path, md_path = args.output + ".json", args.output + ".md"

    settings = settings_of(args)
    results: dict[tuple[str, str], dict] = {}
    if args.resume and os.path.isfile(json_path):
        with open(json_path) as fh:
            old = json.load(fh)
        if old.get("settings") == settings:
            results = {(e["file"], e["mode"]): e for e in old["results"] if e["file"] in files}
            print("[sweep] resuming: {} results kept".format(len(results)), flush=True)
        else:
            print("[sweep] not resuming: {} was made with other settings".format(json_path))
    results = {(f.replace("/", os.sep), m): e for (f, m), e in results.items()}
    todo = [(f, m) for f in files for m in args.modes if (f, m) not in results]
    print("[sweep] {} files, {} renders to do ({} modes, {}x{}, {} s limit, {} job{})".format(
        len(files), len(todo), len(args.modes), *args.size, args.timeout, args.jobs,
        "" if args.jobs == 1 else "s"), flush=True)

    command = display_command(argv, args)
    lock = threading.Lock()

    def save() -> None:
        data = {"settings": settings, "modes": args.modes,
                "results": [results[(f, m)] for f in files for m in args.modes
                            if (f, m) in results]}
        with open(json_path + ".tmp", "w") as fh:
            json.dump(data, fh, indent=1)
        os.replace(json_path + ".tmp", json_path)
        write_report(md_path, args, files, skipped, results, command)

    with tempfile.TemporaryDirectory(prefix="restir-sweep-") as tmp:
        install(args, zip_path, tmp)
        done = [0]

        def task(item):
            rel, mode = item
            entry = run_one(args, zip_path, rel, mode, tmp)
            with lock:
                results[item] = entry
                done[0] += 1
                detail = entry.get("error", "")
                if entry["status"] == "nan":
                    detail = "{} bad pixels".format(entry["bad_pixels"])
                print("[sweep] {}/{} {} {}: {} {:.1f} s {}".format(
                    done[0], len(todo), entry["file"], MODE_TITLES[mode], entry["status"],
                    entry.get("seconds") or entry["wall_seconds"], detail).rstrip(), flush=True)
                save()

        save()
        with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
            for future in [pool.submit(task, item) for item in todo]:
                future.result()
    save()
    bad = [e for e in results.values() if e["status"] != "rendered"]
    for mode in args.modes:
        counts = {s: sum(1 for (f, m), e in results.items() if m == mode and e["status"] == s)
                  for s in STATUSES}
        print("[sweep] {}: {}".format(MODE_TITLES[mode], ", ".join(
            "{} {}".format(n, s) for s, n in counts.items())))
    print("[sweep] wrote {} and {}".format(md_path, json_path))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
