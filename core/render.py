"""Rendering one frame: settings in, a Film out, with progress and cancel hooks."""

import copy
import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from . import scene_patch
from .camera.projection import PixelFilter
from .camera.film import Film
from .integrators.path import camera_pass
from .workers.forked import LoopAbandoned
from .workers.parallel import Continuation, concat_rows, release_free_memory
from .util.checksum import checksum
from .restir import BIASED
from .restir.accumulation import STILL
from .object_motion import render_blurred


@dataclass
class RenderSettings:
    mode: str = "PATH"
    samples: int = 16
    max_bounces: int = 4
    seed: int = 0


CHUNK_PIXELS = 1 << 16     # pixels per batch: bounds memory and the latency of a cancel


def path_trace_pixels(ctx, seed, frame, sample, max_bounces, pixel_filter, start, stop, samples=1):
    """One path-traced sample of the pixels [start, stop), split over the
    context's workers (PassResult of those rows). With ``samples`` k > 1,
    samples ``sample`` .. ``sample + k - 1`` of the whole image in one batch
    (start and stop then index its k x P rows: row r is pixel r mod P of
    sample ``sample + r // P``)."""
    w, h = ctx.scene.width, ctx.scene.height
    n = w * h

    def part(lo, hi):
        rows = np.arange(start + lo, start + hi)
        if samples == 1:
            return camera_pass(ctx, w, h, seed, frame, sample, max_bounces, pixel_filter, pixels=rows)
        return camera_pass(ctx, w, h, seed, frame, sample + rows // n, max_bounces, pixel_filter,
                           pixels=rows % n)

    return concat_rows(ctx.workers.map(part, stop - start))


def samples_per_pass(pixels, samples):
    """Samples traced in one batch for an image of ``pixels`` pixels: as many
    as fit in CHUNK_PIXELS rows. A pass pays a fixed cost in Python calls per
    bounce whatever its size, and a small image alone would not fill both
    workers (a 64x64 render: 128 samples 3x faster in batches of 16)."""
    return max(1, min(samples, CHUNK_PIXELS // max(pixels, 1)))


def render_frame(ctx, settings, frame=0, on_sample=None, should_stop=None, first_sample=0):
    """Path-trace ``settings.samples`` passes of the whole image into a Film:
    samples first_sample .. first_sample + samples - 1 of the frame's
    sequence (the viewport asks for one more at a time).

    on_sample(film, seconds) is called after every pass; should_stop() is polled
    between batches of CHUNK_PIXELS pixels, so a cancel is noticed within one
    batch. Returns the Film with the passes completed so far.
    """
    scene = ctx.scene
    if getattr(scene, "shutter_motion", None) is not None:     # objects' motion blur (object_motion.py)
        if first_sample:
            raise ValueError("motion blur renders its samples from the first")
        return render_blurred(render_frame, ctx, settings, frame, on_sample, should_stop)
    w, h = scene.width, scene.height
    film = Film(w, h)
    pixel_filter = PixelFilter(scene.filter_width)
    start = time.perf_counter()
    n = w * h
    # A second process on Linux (core/workers/forked.py), kept for the next frame of
    # an animation if the scene changed only its camera, or objects moved
    # (core/scene_patch.py).
    keep = Continuation(lambda: _continuation_token(ctx), (ctx,), _resume_path,
                        (scene.camera, settings, frame, first_sample),
                        patch=lambda state, token: _patch(state[0], ctx, token), fingerprint=_path_fingerprint)
    batch = samples_per_pass(n, settings.samples)
    with ctx.workers.twin(n * batch, keep) as lead:
        done = 0
        while done < settings.samples:
            k = min(batch, settings.samples - done)
            if lead and should_stop is not None and should_stop():
                return film
            # k samples of the image are k x n rows (one batch when k > 1,
            # CHUNK_PIXELS-row chunks of one sample when the image is large)
            rows_total = n * k
            color = np.zeros((rows_total, 3), np.float32)
            depth = np.zeros(rows_total, np.float32)
            normal = np.zeros((rows_total, 3), np.float32)
            albedo = np.zeros((rows_total, 3), np.float32)
            alpha = np.zeros(rows_total, np.float32)
            for a in range(0, rows_total, CHUNK_PIXELS):
                if a > 0 and lead and should_stop is not None and should_stop():
                    return film
                b = min(a + CHUNK_PIXELS, rows_total)
                res = path_trace_pixels(ctx, settings.seed, frame, first_sample + done, settings.max_bounces,
                                        pixel_filter, a, b, samples=k)
                color[a:b], depth[a:b], normal[a:b], albedo[a:b] = res.color, res.depth, res.normal, res.albedo
                alpha[a:b] = res.alpha
            for j in range(k):
                rows = slice(j * n, (j + 1) * n)
                film.add(color[rows], depth=depth[rows], normal=normal[rows], albedo=albedo[rows],
                         alpha=alpha[rows])
                if lead and on_sample is not None:
                    on_sample(film, time.perf_counter() - start)
            done += k
        keep.complete = True
    return film


def settle_frames(frames):
    """Frames of a fresh start left out of a biased still's mean: the first
    frames' reservoirs hold few samples, and their noise would dominate the
    mean. From there on a still's frames use still_temporal_M_cap."""
    return min(frames // 4, 8)


# An unbiased still keeps every frame, the first ones weighted less: frame i
# of a fresh start weighs min(1, (i + 1) / STILL_RAMP_FRAMES) in the mean.
# Every frame is an unbiased estimate, and one frame's variance falls as its
# reservoirs fill, to about its final value within a few frames (courtyard,
# frames 0, 1, 2 and 15 of 16: 1.9x, 1.3x, 1.2x and 1x; room 4.6x, 1.9x,
# 1.5x, 1x): these weights are about the inverse of those variances.
STILL_RAMP_FRAMES = 4


def still_frame_weight(i):
    """Weight of frame i of an unbiased fresh start in the running means."""
    return min(1.0, (i + 1) / STILL_RAMP_FRAMES)


def render_restir(ctx, restir, settings, frame, frames=1, fresh=False, on_frame=None, should_stop=None):
    """Run ``frames`` ReSTIR GI frames of the (unchanging) scene and return the
    last FrameResult (None if stopped before the first). Each gets its own
    random numbers; on_frame(i, result) follows every frame.

    fresh: the reservoirs start empty (a still, or the first frame of an
    animation). The image is then the mean of the frames: in the unbiased
    mode of every frame, weighted by still_frame_weight; in the biased mode
    of every frame after the first settle_frames(frames). A still gets
    cleaner as ``frames`` grows (and in the unbiased mode converges to the
    path-traced image). Otherwise each pixel's running mean keeps at most
    ``settings.accumulate`` frames.
    With ``restir.keep_history`` False the state is let go at the end."""
    run = settings
    if fresh and settings.accumulate > 1:
        run = dataclasses.replace(settings, accumulate=STILL)
    settle = settle_frames(frames) if fresh else 0
    ramp = fresh and settings.mode != BIASED and settings.accumulate > 1
    result = None
    scene = ctx.scene
    # The twin process (core/workers/forked.py) goes on into the next frame's loop of
    # an animation if the scene changed only its camera since, or objects
    # moved (core/scene_patch.py), and after a frame the viewport abandoned
    # for an edit if both processes' ReSTIR states are alike.
    keep = Continuation(lambda: _continuation_token(ctx, restir), (ctx, restir), _resume_restir,
                        (scene.camera, settings, frame, frames, fresh),
                        patch=lambda state, token: _patch(state[0], ctx, token, restir),
                        fingerprint=_restir_fingerprint)
    with ctx.workers.twin(scene.width * scene.height, keep) as lead:
        for i in range(max(1, frames)):
            if lead and should_stop is not None and should_stop():
                break
            if i == settle and i > 0:
                if not ramp:
                    restir.restart_accumulation()
                # The mean of the frames converges as fast as they are independent;
                # reservoirs that keep a sample for up to temporal_M_cap frames make
                # neighbouring frames alike, so a settled still lowers the cap
                # (docs/plan-archive.md has the corpus measurements).
                run = dataclasses.replace(run, temporal_M_cap=min(run.temporal_M_cap,
                                                                  settings.still_temporal_M_cap))
            weight = still_frame_weight(i) if ramp else 1.0
            this = run if weight == run.frame_weight else dataclasses.replace(run, frame_weight=weight)
            result = restir.render_frame(ctx, this, frame * 65536 + i)
            if lead and on_frame is not None:
                on_frame(i, result)
        else:
            keep.complete = True
    if not restir.keep_history:
        restir.reset()          # the result keeps the images it shows
        release_free_memory()
    return result


def _continuation_token(ctx, restir=None):
    """What a parked twin's copies must share with (ctx, restir) to go on:
    the same acceleration structure and lights, a scene whose change
    counters (Scene.versions: geometry, lighting) and image settings are
    unchanged, and the same ReSTIR state (frames rendered, history); the
    camera may differ (it is sent). None (never) for scenes without change
    counters. Its last items are _fixed_token's, then the structure's edits."""
    s = ctx.scene
    if s.versions is None:
        return None
    return (id(ctx.accel), id(ctx.lights), ctx.eps, tuple(s.versions)) + _fixed_token(ctx, restir) \
        + (scene_patch.accel_updates(ctx),)


def _fixed_token(ctx, restir):
    """The part of the token a ScenePatch cannot bring the twin to: the
    acceleration structure under any wrapper, the image settings and the
    ReSTIR state."""
    s = ctx.scene
    token = (id(scene_patch.bare(ctx.accel)), s.width, s.height, s.filter_width,
             getattr(s, "film_transparent", None))
    if restir is not None:
        token += (id(restir), restir.frames, id(restir.history), restir.keep_history)
    return token


def _patch(old_ctx, ctx, old_token, restir=None):
    """(parent) The ScenePatch for a twin parked with old_ctx and old_token
    to go on with ctx, or None (it is then forked anew)."""
    if ctx.scene.versions is None or old_token is None:
        return None
    fixed = _fixed_token(ctx, restir)
    if old_token[-1 - len(fixed):-1] != fixed:
        return None
    return scene_patch.make(old_ctx, ctx, old_token[-1])


def _with_camera(ctx, camera):
    scene = copy.copy(ctx.scene)
    scene.camera = camera
    return dataclasses.replace(ctx, scene=scene)


def _resume_path(ctx, patch, camera, settings, frame, first_sample):
    """(in the twin) The next render_frame from the twin's copies (brought
    to the leader's scene by ``patch`` if not None)."""
    if patch is not None:
        ctx = scene_patch.apply(ctx, patch)
    ctx = _with_camera(ctx, camera)
    try:
        render_frame(ctx, settings, frame, first_sample=first_sample)
    except LoopAbandoned:
        pass        # the leader stopped the loop (forked.Twin.abandon)
    return (ctx,)


def _path_fingerprint(ctx):
    """Path tracing keeps nothing between samples: after an abandoned loop
    the twin's state is the leader's."""
    return 0


def _resume_restir(ctx, restir, patch, camera, settings, frame, frames, fresh):
    """(in the twin) The next loop of render_restir from the twin's copies,
    with the leader's new camera (and scene, by ``patch`` if not None);
    returns the state for the loop after."""
    if patch is not None:
        ctx = scene_patch.apply(ctx, patch)
    ctx = _with_camera(ctx, camera)
    try:
        render_restir(ctx, restir, settings, frame, frames, fresh)
    except LoopAbandoned:
        pass        # the leader stopped the loop; both unwound it (forked.Twin.abandon)
    return ctx, restir


def _restir_fingerprint(ctx, restir):
    """What both processes must agree on to go on after an abandoned frame:
    the ReSTIR state (frames, history, scene-change bookkeeping). A frame
    left in a pass that writes the history in place (sample validation)
    differs, and the twin is then ended."""
    return checksum(restir.frames, restir.history, restir.changes)
