"""Progressive refinement of the rendered viewport, as Cycles users know it.

Stages of the image since the last change (an edit, a view change, a
resize), in order:

- MOVING: the frame right after a change. With the Automatic resolution it
  renders at the divisor whose frame time fits the frame budget (1, 2 or 4).
- REFINING: the view is still and the image is coarser than it can be:
  after STEP_FRAMES frames at a divisor the next frames render at half of
  it (4, 2, 1). Each step carries what was learnt to the finer image
  (core/restir/resize.py: reservoirs, G-buffer history and running means by
  nearest neighbour, the means' weight capped at a few frames; the path
  tracer's mean likewise), and at the step to full resolution the last
  coarse image is blended into the first finer ones, so the image keeps its
  level and its smoothness.
- SAMPLING: full resolution (or the fixed Viewport Resolution, or the finest
  that fits in memory); frames are added, in the ReSTIR modes as one
  running mean over every still frame (as an F12 still), until
- DONE: the sample limit (Viewport Samples, like Cycles'; 0: none) or
  convergence: the displayed image changed by under CONVERGED_CHANGE of its
  mean (mean absolute luminance difference over the mean luminance) in
  CONVERGED_RUN frames in a row, after at least CONVERGED_MIN_SAMPLES.

``Progress`` is the bookkeeping (no bpy, no numpy images); ``Refinement``,
a mixin of ViewportSession, picks each frame's divisor and carries the
state over a resolution step.
"""

import numpy as np

from ...core.restir.resize import CARRY_FRAMES, resize_image, resize_stream, upscale_bilinear
from ...core.util.vectors import luminance
from .. import memory
from ..memory import SceneTooLarge

MOVING, REFINING, SAMPLING, DONE = "moving", "refining", "sampling", "done"

SCALES = {"FULL": 1, "HALF": 2, "QUARTER": 4}
# A still view's frames at each divisor before the next finer one. The error
# of the example room's viewport is noise, not resolution: a frame at 1/2
# (1/4) resolution upscaled would differ from the converged full-size image
# by MSE 22 (44) in 8-bit values, while its noise stays above ~130 for the
# first 20 frames, and a full-size frame costs 4x a half-size one. So the
# image steps when its noise is down, not when a few frames are in:
# bench/viewport_refine.py --clock 1.0,0.45,1.45,5.0 (the real window's frame
# times), MSE at 10 / 20 / 30 / 40 s: STEP_FRAMES 6 489 / 457 / - / -,
# 12 284 / 193 / 190 / 172, 16 206 / 167 / 132 / 142, 20 (carry 2, blend 8)
# 200 / 162 / 134 / 110 (39 s to full resolution); 16 it is, ~30 s to full
# resolution in the window.
STEP_FRAMES = 16
# At the step to full resolution frames get 4x dearer and the first ones are
# noisier than the image shown: the last coarse image, upscaled, is blended
# in as BLEND_FRAMES frames at most (Refinement._blend_carried; at 40 s
# 142 -> 126). Blended at the step from 1/4 to 1/2 too, it made 10 s worse
# (206 -> 228): the 1/4 image is the blurrier and its successors cheap.
BLEND_FRAMES = 8
BLEND_MIN = 0.02            # the coarse image's share below which it is dropped
CONVERGED_CHANGE = 1e-3     # under a quarter of an 8-bit step at mid grey, on average
CONVERGED_RUN = 4
CONVERGED_MIN_SAMPLES = 32

# AUTO scale: go to a finer scale only when its predicted frame time is well
# under the budget, to a coarser one only when well over.
_FINER_BELOW = 0.7
_COARSER_ABOVE = 1.3


class Progress:
    """Where the image of a viewport stands since the last change.

    limit: samples (frames) before it stops, 0 for none. Counters:
    ``samples`` frames in the image, ``at_divisor`` frames since the last
    resolution step or change, ``since_change`` frames since the last change
    (0: the next frame follows a change)."""

    def __init__(self, limit=1024):
        self.limit = max(0, int(limit))
        self.finest = 1         # the finest divisor the image may reach
        self.divisor = None     # the divisor of the latest frame
        self.changed()

    def changed(self):
        """An edit, view change or resize: the image starts over."""
        self.samples = 0
        self.at_divisor = 0
        self.since_change = 0
        self.still_run = 0
        self.converged = False

    @property
    def moving(self):
        return self.since_change == 0

    def next_divisor(self, budget_divisor, fixed):
        """The divisor of the next frame: ``budget_divisor`` (the one that
        keeps the frame budget) after a change or with a fixed scale; on a
        still view, after STEP_FRAMES frames at a divisor, half of it, down
        to ``finest``."""
        if fixed or self.divisor is None or self.moving:
            return budget_divisor
        d = self.divisor
        if self.at_divisor >= STEP_FRAMES and d > self.finest:
            return max(self.finest, d // 2)
        return d

    def stepped(self, divisor):
        """The next frame renders at ``divisor``."""
        if divisor != self.divisor:
            self.at_divisor = 0
        self.divisor = divisor

    def frame_done(self, change=None):
        """A frame was published; ``change``: its relative change from the
        frame before at the same size (None: not comparable)."""
        self.samples += 1
        self.at_divisor += 1
        self.since_change += 1
        final = self.divisor is not None and self.divisor <= self.finest
        if final and change is not None and change < CONVERGED_CHANGE:
            self.still_run += 1
        else:
            self.still_run = 0
        self.converged = self.still_run >= CONVERGED_RUN and self.samples >= CONVERGED_MIN_SAMPLES

    @property
    def done(self):
        return (self.limit > 0 and self.samples >= self.limit) or self.converged

    @property
    def stage(self):
        if self.done:
            return DONE
        if self.moving:
            return MOVING
        if self.divisor is not None and self.divisor > self.finest:
            return REFINING
        return SAMPLING

    def text(self):
        """The header's words for the stage and how far it has got."""
        stage = self.stage
        res = "full res" if (self.divisor or 1) == 1 else f"1/{self.divisor} res"
        if stage == DONE:
            return "Done" if not self.converged or self.limit and self.samples >= self.limit \
                else f"Done (converged at sample {self.samples})"
        if stage == MOVING:
            return f"Moving, {res}"
        if stage == REFINING:
            return f"Refining {res} | sample {self.samples + 1}"
        limit = f"/{self.limit}" if self.limit else ""
        return f"Sample {self.samples + 1}{limit}" + ("" if self.divisor in (None, 1) else f", {res}")


def relative_change(a, b):
    """Mean absolute luminance difference of two (H, W, >=3) images over the
    mean luminance of ``a`` (None if their shapes differ or a is black)."""
    if a is None or b is None or a.shape != b.shape:
        return None
    la, lb = luminance(a[..., :3].reshape(-1, 3)), luminance(b[..., :3].reshape(-1, 3))
    mean = float(np.mean(la))
    if not mean > 0:
        return None
    return float(np.mean(np.abs(la - lb))) / mean


class Refinement:
    """Mixin of ViewportSession: the divisor of each frame and the carrying
    of the image's state across resolution steps."""

    def _render_resolution(self):
        if self._divisor is None:
            self._divisor = SCALES.get(self.scale, SCALES["QUARTER"])
        w, h = self._size
        d = self._divisor
        return max(1, (w + d - 1) // d), max(1, (h + d - 1) // d)

    def _choose_divisor(self, budget):
        """AUTO scale: the finest divisor whose predicted frame time fits the budget."""
        if self.scale != "AUTO":
            return SCALES[self.scale]
        current = self._divisor or SCALES["QUARTER"]
        if self._pixel_seconds is None or not budget or budget <= 0:
            return current
        w, h = self._size

        def predicted(d):
            return self._pixel_seconds * ((w + d - 1) // d) * ((h + d - 1) // d)

        if predicted(current) > _COARSER_ABOVE * budget:
            coarser = [d for d in (2, 4) if d > current]
            return next((d for d in coarser if predicted(d) <= budget), 4) if coarser else current
        finer = [d for d in (1, 2) if d < current and predicted(d) <= _FINER_BELOW * budget]
        return finer[0] if finer else current

    def _fitting_divisor(self, divisor):
        """``divisor``, or with the AUTO scale a coarser one, whose ReSTIR
        image fits in memory (memory.check_image, checked once per image size:
        the session's own buffers later lower what is available). Raises
        SceneTooLarge when none fits; the status shows its message."""
        w, h = self._size
        if self.mode == "PATH" or self._fits == (w, h, divisor):
            return divisor
        candidates = [d for d in (1, 2, 4) if d >= divisor] if self.scale == "AUTO" else [divisor]
        for d in candidates:
            try:
                memory.check_image((w + d - 1) // d, (h + d - 1) // d)
            except SceneTooLarge:
                if d == candidates[-1]:
                    raise
                continue
            self._fits = (w, h, d)
            return d
        return divisor

    def _next_divisor(self, budget):
        """The divisor of the next frame (Progress.next_divisor), within memory."""
        fixed = self.scale != "AUTO"
        p = self.progress
        floor = self._memory_floor[1] if self._memory_floor[0] == self._size else 1
        p.finest = max(SCALES[self.scale] if fixed else 1, floor)
        moving = fixed or p.moving or p.divisor is None
        wanted = p.next_divisor(self._choose_divisor(budget) if moving else p.divisor, fixed)
        divisor = self._fitting_divisor(wanted)
        if divisor > wanted:        # no finer image fits in memory
            self._memory_floor = (self._size, divisor)
            p.finest = max(p.finest, divisor)
        return divisor

    def _step_to(self, divisor):
        """Render from now on at ``divisor``: a new context, with the
        reservoirs, history and running means carried to its size."""
        old = None if self._scene is None else (self._scene.width, self._scene.height)
        shown = self.frame
        self._divisor = divisor
        self._build_context(False)
        self.progress.stepped(divisor)
        if self._scene is None:
            return
        w, h = self._scene.width, self._scene.height
        if old is None or old == (w, h):
            return
        resize_stream(self._restir, w, h)
        self._carried = None
        finest = divisor <= self.progress.finest
        if finest and shown is not None and shown.shape[:2] == (old[1], old[0]) and self.progress.samples > 0:
            weight = min(self.progress.samples, BLEND_FRAMES)
            self._carried = (upscale_bilinear(shown, w, h), float(weight))
        if self._accum is not None and self._accum_n > 0:
            mean = resize_image((self._accum / self._accum_n).reshape(old[1], old[0], 3), w, h)
            self._accum_n = min(self._accum_n, CARRY_FRAMES)
            self._accum = mean.reshape(-1, 3) * self._accum_n
        else:
            self._accum, self._accum_n = None, 0
        self._shown = None

    def _blend_carried(self, frame):
        """A ReSTIR frame (h, w, 4) after the step to full resolution, blended
        with the last coarse image shown before the step (upscaled
        bilinearly, as it was drawn): that image counts as ``weight`` frames
        against the k frames rendered at the new size, so the first finer
        frames, noisier than the image the user was looking at, take over
        gradually and the image does not get worse at the step. The carried
        image is dropped when its share falls under BLEND_MIN, and at any
        change (the view, an edit)."""
        carried = self._carried
        if carried is None:
            return frame
        if self.progress.moving or carried[0].shape != frame.shape:
            self._carried = None
            return frame
        image, weight = carried
        share = weight / (weight + self.progress.at_divisor + 1)
        if share < BLEND_MIN:
            self._carried = None
            return frame
        return (share * image + (1.0 - share) * frame).astype(np.float32)
