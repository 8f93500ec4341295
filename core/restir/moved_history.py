"""What history survives where objects moved: the stages that measure where
the light changed (gradients.py for the indirect light, light_probes.py for
the direct light) and cap the reservoirs there, and the caps of the running
means that follow from them (frame.py runs them)."""

import time

import numpy as np

from .accumulation import STILL, restart
from .gradients import cap_reservoirs, history_frames, kept_share, redrawn_values, temporal_gradient
from .initial import InitialSampling
from .light_probes import image_probes, light_change, probes_moved
from .shadow_reach import reached
from .timings import stage

MOVING_CAP = 4      # frames of accumulated history kept in a frame where objects moved


def temporal_gradients(s):
    """Where objects moved: how much the light changed around each pixel of
    last frame (gradients.py); reservoirs there keep a shorter history, and
    so do the running means (forget_where_changed)."""
    history, settings = s.history, s.settings
    if not (s.moved and settings.temporal and history is not None and history.sample_value is not None
            and (history.width, history.height) == (s.width, s.height)):
        return
    t = time.perf_counter()
    with stage("temporal gradients"):
        per_frame = max(1, settings.samples)
        how = InitialSampling(settings.max_bounces, settings.initial_sampling, 1,
                              own_surface_glossy=not s.path_reuse, sky_rays=s.sky_on)
        pixels, old, new, valid = redrawn_values(
            s.ctx, history, settings.seed, s.pixel_filter, how,
            history.index * per_frame if settings.sequences else None, s.motion)
        s.gradient = temporal_gradient(pixels, old, new, valid, s.width, s.height)
        share = kept_share(s.gradient, settings.temporal_M_cap)
        cap_reservoirs(history.temporal, share * np.float32(settings.temporal_M_cap))
        if history.spatial is not history.temporal:
            cap_reservoirs(history.spatial, share * np.float32(settings.spatial_M_cap))
    s.timings.spent("validation", t)


def light_probes(s):
    """Where objects moved: last frame's light probes again in the current
    scene, and how much the direct light changed around each of last
    frame's pixels (s.light_change, light_probes.py); this frame's own
    probes for the next frame (s.light_probe)."""
    if not (s.moved and s.accumulating):
        return
    t = time.perf_counter()
    history, seed = s.history, s.settings.seed
    with stage("light probes"):
        if history is not None and history.light_probe is not None and history.n is not None \
                and (history.width, history.height) == (s.width, s.height):
            new = probes_moved(s.ctx, history, s.motion, seed)
            s.light_change = light_change(history.light_probe, new, s.width, s.height)
        one = s.first
        s.light_probe = image_probes(s.ctx, one.p, one.n, one.ng, one.valid, seed)
    s.timings.spent("validation", t)


def forget_where_changed(s):
    """The running means after objects moved: all keep at most MOVING_CAP
    frames, unless temporal_gradients measured where the light changed. Then
    the indirect light keeps what its gradient allows (a pixel far from
    anything that moved, all of it), the rest MOVING_CAP frames (a moving
    shadow: the gate of accumulate stops its history inside, this its
    edges), and pixels on the objects that moved MOVING_CAP frames of both.
    Where light_probes measured the direct light's change, the rest keeps
    what that change allows instead (pixels on moved objects too).
    (The indirect light of the whole image held 4 frames while anything
    moved: corpus_movers, still camera, frame 32 MSE 0.1645 -> 0.1285 with
    the reservoirs' caps.)"""
    history = s.history
    local = s.gradient is not None and (s.motion is not None or not s.moved)
    if not local:
        restart(s.prev_acc, MOVING_CAP)
        return
    frames = history_frames(s.gradient, s.settings.accumulate)
    light = MOVING_CAP
    if s.motion is not None:
        oid = history.object_id
        on = np.where(oid >= 0, s.motion.moved_before[np.clip(oid, 0, len(s.motion.moved_before) - 1)], False)
        frames[on] = np.minimum(frames[on], MOVING_CAP)
        reach = None if s.light_change is not None else \
            reached(s.ctx.scene, s.ctx.lights, s.motion, history.p, oid >= 0, frames=MOVING_CAP)
        if reach is not None:
            light = np.where(reach | on, np.float32(MOVING_CAP), np.float32(STILL))
    if s.light_change is not None:
        light = history_frames(s.light_change, STILL)
    restart(s.prev_acc, frames, light_cap=light)
