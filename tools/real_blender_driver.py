"""What the scripts run in a real Blender window (tools/real_blender.py) share,
and how their log is read back.

A driver (tests/e2e/window_driver.py, bench/viewport_window_driver.py) runs
inside the window, where ``real_blender.run`` copies this file beside it; it
reports each step as a line ``DRIVER <seconds since start> <key>: <values>``
on Blender's output (``say``), runs its steps as ``bpy.app.timers`` that quit
Blender when they fail (``step``), and takes screenshots with ImageMagick
(``grab``). Outside the window, ``read_log`` turns the ``blender.log`` that
``real_blender.run`` writes into its output folder back into
``{key: [values, ...]}``.

No bpy at import: the reading side runs without it.
"""

import os
import re
import subprocess
import sys
import time
import traceback

T0 = time.time()
OUT = os.environ.get("REAL_OUT", ".")
LINE = re.compile(r"DRIVER ([\d.]+) ([^:]+): ?(.*)")


def say(key, *values):
    """A line ``DRIVER <seconds> <key>: <values>`` for the log's reader."""
    print("DRIVER", f"{time.time() - T0:.2f}", f"{key}:", *values, flush=True)


def say_versions():
    """The first line of every driver: Python's and Blender's versions."""
    import bpy
    say("versions", sys.version.split()[0], bpy.app.version_string)


def step(fn):
    """A timer callback that reports its own failure and quits, never hangs."""
    def run():
        try:
            return fn()
        except Exception:  # noqa: BLE001 (whatever failed: report it and quit)
            traceback.print_exc()
            say("failed", fn.__name__)
            import bpy
            bpy.ops.wm.quit_blender()
    return run


def grab(name, crop=None):
    """A screenshot into OUT/name (ImageMagick's import: Blender's own reads
    back black under software OpenGL); crop: (w, h, x, y) from the screen's
    top left, or the whole screen."""
    cmd = ["import", "-window", "root"]
    if crop is not None:
        cmd += ["-crop", "%dx%d+%d+%d" % crop]
    cmd.append(os.path.join(OUT, name))
    subprocess.run(cmd, check=True, timeout=30)


def read_log(folder):
    """The DRIVER lines of folder/blender.log: key -> list of value strings."""
    lines = {}
    with open(os.path.join(folder, "blender.log"), errors="replace") as fh:
        for line in fh:
            m = LINE.match(line.rstrip("\n"))
            if m:
                lines.setdefault(m.group(2), []).append(m.group(3))
    return lines
