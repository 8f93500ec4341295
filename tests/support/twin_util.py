"""Helpers for the twin-process tests (core/workers/forked.py)."""

import copy
import os

import numpy as np


def gone(pid):
    """The process ``pid`` has exited (and been reaped)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


def moving(scene, f, versions=(0, 0)):
    """The scene seen from a camera moved along x for frame f."""
    s = copy.copy(scene)
    cam = copy.copy(scene.camera)
    m = np.array(cam.to_world, np.float32)
    m[0, 3] += 0.01 * f
    cam.to_world = m
    s.camera, s.versions = cam, versions
    return s


def parked_pid(ctx):
    """The pid of the twin parked for the context's next loop, or None."""
    parked = ctx.workers._parked
    return None if parked is None else parked[0].pid
