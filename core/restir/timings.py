"""A ReSTIR frame's timings per pass, and the stage named in its errors."""

import contextlib
import threading
import time

from ..util.errors import context

PASSES = ("gbuffer", "validation", "initial", "temporal", "spatial", "glossy", "shading", "denoise")


def stage(name):
    """Errors raised inside name the frame's stage (errors.context)."""
    return context("stage", name)


class Timings:
    """Seconds per pass, added up over the workers' ranges."""

    def __init__(self):
        self.seconds = dict.fromkeys(PASSES, 0.0)
        self._lock = threading.Lock()

    def spent(self, name, t0):
        """Adds the time since t0 to pass ``name``; returns the time now."""
        with self._lock:
            self.seconds[name] += time.perf_counter() - t0
        return time.perf_counter()

    @contextlib.contextmanager
    def timed(self, name):
        t = time.perf_counter()
        try:
            yield
        finally:
            self.spent(name, t)
