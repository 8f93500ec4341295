#!/usr/bin/env python3
"""Blender in a real window, for end-to-end tests of what users see.

The ``bpy`` module has no window: the Render Engine dropdown, the panels,
the rendered viewport and F12 can only be seen in a real Blender. This runs
one from a Debian root (Blender 5.2 LTS with Python 3.14, Mesa's software
OpenGL, Xvfb and ImageMagick; ``tools/real_blender_setup.sh`` builds it) in
a 1280x800 virtual screen:

    python tools/real_blender.py dist/restir_gi-0.1.0-linux_x64.zip FILE.blend DRIVER.py OUTDIR 5 10 20

installs the extension zip into a fresh user folder, opens FILE.blend (the
image files beside it travel along), runs DRIVER.py in the UI (it should
quit Blender when done; ``bpy.app.timers`` work there; it finds
``tools/real_blender_driver.py`` beside it), and writes
``shot_<s>.png`` (the whole screen at those seconds after start),
``blender.log`` and ``install.log`` into OUTDIR, with whatever the driver
wrote into its ``OUT`` folder (the environment variable ``REAL_OUT``).
Environment variables named ``REAL_*`` reach the driver. The driver may run
``blender -b`` itself (``bpy.app.binary_path``): the extension is installed
for it too.

The root is ``$REAL_BLENDER_ROOT`` or ``/var/tmp/real-blender/sid``; /proc and
/dev are bound into it only while a run lasts. Needs root privileges (chroot).
Exit status: Blender's, or 2 when there is no such root.
"""

from __future__ import annotations

import argparse
import os
import shlex
import shutil
import subprocess
import sys
import tempfile

DEFAULT_ROOT = "/var/tmp/real-blender/sid"
# What every driver imports: copied beside it.
DRIVER_SHARED = os.path.join(os.path.dirname(os.path.abspath(__file__)), "real_blender_driver.py")
IMAGE_SUFFIXES = (".blend", ".png", ".jpg", ".jpeg", ".exr", ".hdr", ".tif", ".tiff")


def root_dir() -> str:
    return os.environ.get("REAL_BLENDER_ROOT", DEFAULT_ROOT)


def missing() -> str | None:
    """Why a real Blender cannot run here, or None when it can."""
    root = root_dir()
    if not os.path.isfile(os.path.join(root, "usr", "bin", "blender")):
        return f"no real Blender root at {root} (build it with tools/real_blender_setup.sh)"
    if os.geteuid() != 0:
        return "running a real Blender from its root needs root privileges (chroot)"
    return None


def _bind(root: str) -> list[str]:
    mounted = []
    for d in ("proc", "dev"):
        target = os.path.join(root, d)
        if subprocess.run(["mountpoint", "-q", target]).returncode != 0:
            subprocess.run(["mount", "--bind", "/" + d, target], check=True)
            mounted.append(target)
    return mounted


def _unbind(mounted: list[str]) -> None:
    for target in mounted:
        if subprocess.run(["umount", target], stderr=subprocess.DEVNULL).returncode != 0:
            subprocess.run(["umount", "-l", target], stderr=subprocess.DEVNULL)


def _copy_beside(blend: str, job: str) -> None:
    """The .blend and the images and libraries beside it (two folder levels
    down), so its relative paths hold."""
    top = os.path.dirname(os.path.abspath(blend))
    for folder, dirs, files in os.walk(top):
        depth = os.path.relpath(folder, top).count(os.sep) + (folder != top)
        dirs[:] = [d for d in dirs if not d.startswith(".")] if depth < 2 else []
        for name in files:
            if name.lower().endswith(IMAGE_SUFFIXES):
                src = os.path.join(folder, name)
                if os.path.getsize(src) < 200 << 20:
                    dst = os.path.join(job, os.path.relpath(src, top))
                    os.makedirs(os.path.dirname(dst), exist_ok=True)
                    shutil.copy2(src, dst)
    shutil.copy2(blend, os.path.join(job, "scene.blend"))


def run(package: str, blend: str, driver: str, outdir: str, shots: list[float],
        env: dict[str, str] | None = None, limit: float = 300.0) -> int:
    """Run ``driver`` in a real Blender window on ``blend`` with the extension
    ``package`` installed; screenshots at ``shots`` seconds. Returns
    Blender's exit status (124 when it outlived ``limit`` seconds)."""
    reason = missing()
    if reason:
        print(reason, file=sys.stderr)
        return 2
    root = root_dir()
    os.makedirs(outdir, exist_ok=True)
    job = tempfile.mkdtemp(prefix="job.", dir=os.path.join(root, "tmp"))
    inside = "/tmp/" + os.path.basename(job)
    try:
        shutil.copy2(package, os.path.join(job, "ext.zip"))
        shutil.copy2(driver, os.path.join(job, "driver.py"))
        shutil.copy2(DRIVER_SHARED, os.path.join(job, os.path.basename(DRIVER_SHARED)))
        _copy_beside(blend, job)
        os.makedirs(os.path.join(job, "out"))
        exports = {k: v for k, v in {**os.environ, **(env or {})}.items() if k.startswith("REAL_")}
        exports["REAL_OUT"] = inside + "/out"
        lines = [f"export {k}={shlex.quote(v)}" for k, v in sorted(exports.items())]
        shots = sorted(float(s) for s in shots)
        shot_lines, prev = [], 0.0
        for s in shots:
            shot_lines.append(f"sleep {s - prev:.2f}; import -window root {inside}/shot_{s:g}.png")
            prev = s
        script = "\n".join([
            "#!/bin/bash",
            f"export HOME={inside}/home BLENDER_USER_RESOURCES={inside}/user",
            "mkdir -p $HOME $BLENDER_USER_RESOURCES",
            *lines,
            f"cd {inside}",
            f"blender --command extension install-file -r user_default -e {inside}/ext.zip "
            f"> {inside}/install.log 2>&1 || {{ cat {inside}/install.log; exit 3; }}",
            "D=$(( 90 + RANDOM % 9 ))",
            f"Xvfb :$D -screen 0 1280x800x24 > {inside}/xvfb.log 2>&1 & XP=$!",
            "sleep 1; export DISPLAY=:$D",
            f"timeout {limit:.0f} blender {inside}/scene.blend --python {inside}/driver.py "
            f"> {inside}/blender.log 2>&1 < /dev/null & BP=$!",
            "( " + "; ".join(shot_lines or ["true"]) + " ) > /dev/null 2>&1 & SP=$!",
            "wait $BP; rc=$?",
            f"[ $rc = 124 ] && echo 'killed after {limit:.0f} s' >> {inside}/blender.log",
            "kill $SP $XP 2>/dev/null; wait 2>/dev/null",
            "exit $rc",
        ])
        go = os.path.join(job, "go.sh")
        with open(go, "w") as fh:
            fh.write(script + "\n")
        os.chmod(go, 0o755)
        mounted = _bind(root)
        try:
            rc = subprocess.run(["chroot", root, inside + "/go.sh"]).returncode
        finally:
            _unbind(mounted)
        for name in os.listdir(job):
            if name.startswith("shot_") or name.endswith(".log"):
                shutil.copy2(os.path.join(job, name), os.path.join(outdir, name))
        shutil.copytree(os.path.join(job, "out"), outdir, dirs_exist_ok=True)
        return rc
    finally:
        shutil.rmtree(job, ignore_errors=True)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("package", help="the extension zip (with cp314 linux-x64 wheels)")
    parser.add_argument("blend")
    parser.add_argument("driver", help="Python script run in Blender's UI")
    parser.add_argument("outdir")
    parser.add_argument("shots", nargs="*", type=float, help="seconds after start of each screenshot")
    parser.add_argument("--limit", type=float, default=300.0, help="seconds before Blender is killed")
    args = parser.parse_args(argv)
    rc = run(args.package, args.blend, args.driver, args.outdir, args.shots, limit=args.limit)
    print(f"blender exit {rc}; screenshots and logs in {args.outdir}")
    return rc


if __name__ == "__main__":
    sys.exit(main())
