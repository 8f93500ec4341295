"""ReSTIR GI (Ouyang et al. 2021) as whole-image passes, one call per frame.

A frame is a sequence of named stages over one declared per-frame state
(frame.py): scene changes and sample validation (validation.py), the G-buffer
(gbuffer.py), initial samples (initial.py), temporal reuse (temporal.py),
spatial reuse (spatial.py), shading (shading.py), the running means
(accumulation.py) and the denoiser (denoise.py). ``ReSTIRGI`` owns the state
that lives between frames; everything else is plain functions of plain arrays.
"""

import time

from ..workers.parallel import release_free_memory
from .frame import STAGES, FrameState, next_history
from .reservoirs import NARROW_MIN_PIXELS, distinct
from .scene_changes import SceneChanges
from .timings import Timings
from .accumulation import restart
from .settings import BIASED, UNBIASED, FrameResult, ReSTIRSettings  # noqa: F401  (the package's API)

# Below this many pixels a frame's freed temporaries are left in the heaps:
# giving them back makes the next frame fault their pages in again (about
# 7 % of a 320x180 frame), and they are small. The same size at which the
# reservoirs start to be stored narrowed.
TRIM_MIN_PIXELS = NARROW_MIN_PIXELS


class ReSTIRGI:
    """Reservoirs and the previous frame: the temporal state of one image stream."""

    def __init__(self):
        # False: core.render.render_restir lets the state go after its last
        # frame (a still render, which nothing continues), before the caller
        # copies the images out; reset() leaves it as set.
        self.keep_history = True
        self.reset()

    def reset(self):
        self.history = None
        self.frames = 0
        self.changes = SceneChanges()
        self.last_timings = {}      # seconds per pass of the last frame (see render_frame)

    @property
    def validations(self):
        """Sample validations run (skipped while nothing changed)."""
        return self.changes.validations

    def restart_accumulation(self):
        """The next frame starts every pixel's running mean over (accumulation.py)."""
        if self.history is not None:
            restart(self.history.accumulation)

    @property
    def nbytes(self):
        h = self.history
        if h is None:
            return 0
        return sum(r.nbytes for r in distinct(h.temporal, h.spatial)) + sum(
            a.nbytes for a in (h.p, h.n, h.ng, h.depth, h.valid, h.object_id, h.sample_value, h.light_probe,
                                h.noise_hold, h.sky_share, h.visibility, h.accumulation) if a is not None)

    def render_frame(self, ctx, settings, frame):
        """One frame. Afterwards ``last_timings`` holds seconds per pass: wall
        time for 'validation' and 'total', and for the passes the workers run
        ('gbuffer', 'initial', 'temporal', 'spatial', 'glossy', 'shading', and
        'denoise' with ReSTIRSettings.denoise) the sum over workers, i.e.
        what they would take on one thread."""
        try:
            return self._render_frame(ctx, settings, frame)
        except BaseException:
            if self.history is not None and self.history.temporal is None:
                self.reset()        # last frame's state was partly let go (see _render_frame)
            raise

    def _render_frame(self, ctx, settings, frame):
        t_start = time.perf_counter()
        if self.history is not None and self.history.signature != _signature(ctx.scene):
            self.reset()    # new resolution, or stored triangle/material ids mean nothing now
        timings = Timings()
        state = FrameState.begin(ctx, settings, frame, self.frames, self.history, self.changes, timings)
        for run_stage in STAGES:
            run_stage(state)
        visible_rows = state.prev_pix[state.img.valid]
        self.history, acc = next_history(state, _signature(ctx.scene))
        self.frames += 1
        if len(state.img.valid) >= TRIM_MIN_PIXELS:
            release_free_memory()   # the passes' temporaries, freed in the workers' heaps
        timings.seconds["total"] = time.perf_counter() - t_start
        self.last_timings = timings.seconds
        found = float((visible_rows >= 0).mean()) if len(visible_rows) else 0.0
        img, spatial = state.img, state.spatial
        return FrameResult(state.color, acc.direct, acc.indirect, img.depth, acc.normal, acc.albedo,
                           spatial.M.copy(), spatial.W.copy(), found, acc.alpha.copy(), state.noisy)


def _signature(scene):
    """What must not change for stored reservoirs to stay meaningful."""
    return (scene.width, scene.height, scene.triangle_count, len(scene.materials))
