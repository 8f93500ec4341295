"""ReSTIR GI (Ouyang et al. 2021) as whole-image passes, one call per frame.

Per frame: primary visibility (gbuffer.py) -> initial samples (initial.py) ->
temporal resampling (temporal.py) -> spatial resampling (spatial.py) -> final
shading (shading.py) -> reprojected accumulation of the shaded frames
(accumulation.py); every few frames, sample validation (validation.py).
``ReSTIRGI`` owns the state that lives between frames; everything else is
plain functions of plain arrays.
"""

import threading
import time
from dataclasses import dataclass

import numpy as np

from .. import materials, samplers
from ..camera import PixelFilter
from ..parallel import concat_rows
from ..rows import gather, scale
from .accumulation import STILL, accumulate, previous_pixels, restart
from .adaptive_direct import light_sample_counts, reprojected_hold, update_noise_hold
from ..reservoirs import finalize, merge
from .boiling import boiling_filter
from .gbuffer import trace_gbuffer
from .initial import COSINE, initial_samples
from .shading import carried_visibility, shade_indirect
from .shift import target_at
from .spatial import reuse_weights, spatial_resample
from .temporal import FrameHistory, ObjectMotion, carry_with_objects, reproject, temporal_resample
from .validation import validate

BIASED = "RESTIR_BIASED"
MOVING_CAP = 4      # frames of accumulated history kept in a frame where objects moved
UNBIASED = "RESTIR_UNBIASED"


@dataclass
class ReSTIRSettings:
    mode: str = BIASED
    samples: int = 1                # initial samples per pixel per frame
    max_bounces: int = 4
    seed: int = 0
    initial_sampling: str = COSINE  # or "UNIFORM"
    temporal: bool = True
    spatial: bool = True
    temporal_M_cap: float = 20.0
    spatial_M_cap: float = 500.0
    max_age: int = 30
    spatial_neighbors: int = 4
    spatial_radius: float = 16.0    # pixels
    validation_interval: int = 4    # frames; 0 turns validation off
    boiling_filter: float = 0.2     # strength (boiling.py), biased mode only; 0 turns it off
    light_samples: int = 4          # shadow rays for the direct light of visible points in
                                    # penumbrae (one elsewhere: adaptive_direct.py). 16 was
                                    # worth it before accumulation; now 4 gives the same room
                                    # MSE and costs far less where most pixels are flagged
                                    # (glossy corpus scene: 716 -> 376 ms per frame)
    accumulate: int = 16            # frames in each pixel's running mean (accumulation.py);
                                    # 1 turns it off, accumulation.STILL averages every frame


@dataclass
class FrameResult:
    """One frame, full-image rows (pixel index y * width + x)."""
    color: np.ndarray       # (P, 3) direct + indirect
    direct: np.ndarray      # (P, 3) emission seen directly + direct light (accumulated)
    indirect: np.ndarray    # (P, 3) (accumulated)
    depth: np.ndarray       # (P,) this frame's
    normal: np.ndarray      # (P, 3) accumulated
    albedo: np.ndarray      # (P, 3) accumulated
    M: np.ndarray           # (P,) spatial reservoir M
    W: np.ndarray           # (P,) spatial reservoir W
    history_found: float    # fraction of visible pixels with accepted temporal history
    alpha: np.ndarray = None  # (P,) coverage by geometry (accumulated; Film > Transparent)


class ReSTIRGI:
    """Reservoirs and the previous frame: the temporal state of one image stream."""

    def __init__(self):
        self.reset()

    def reset(self):
        self.history = None
        self.frames = 0
        self.validations = 0        # sample validations run (skipped while nothing changed)
        self.last_timings = {}      # seconds per pass of the last frame (see render_frame)
        self._lighting_key = None   # Scene.lighting_key of the last frame
        self._geometry_key = None   # Scene.geometry_key of the last frame
        self._stale = False         # the lighting changed since the last validation
        self._light_edit = False    # lights, materials or world changed since the last validation

    def restart_accumulation(self):
        """The next frame starts every pixel's running mean over (accumulation.py)."""
        if self.history is not None:
            restart(self.history.accumulation)

    @property
    def nbytes(self):
        h = self.history
        if h is None:
            return 0
        return h.temporal.nbytes + h.spatial.nbytes + sum(
            a.nbytes for a in (h.p, h.n, h.ng, h.depth, h.valid, h.object_id, h.noise_hold,
                                h.visibility, h.accumulation) if a is not None)

    def render_frame(self, ctx, settings, frame):
        """One frame. Afterwards ``last_timings`` holds seconds per pass: wall
        time for 'gbuffer', 'validation' and 'total', and for the passes the
        workers run ('initial', 'temporal', 'spatial', 'shading') the sum
        over workers, i.e. what they would take on one thread."""
        t_start = time.perf_counter()
        timings = {"gbuffer": 0.0, "validation": 0.0, "initial": 0.0, "temporal": 0.0,
                   "spatial": 0.0, "shading": 0.0}
        lock = threading.Lock()

        def spent(name, t0):
            with lock:
                timings[name] += time.perf_counter() - t0
            return time.perf_counter()

        scene = ctx.scene
        if self.history is not None and self.history.signature != _signature(scene):
            self.reset()    # new resolution, or stored triangle/material ids mean nothing now
        biased = settings.mode != UNBIASED
        pixel_filter = PixelFilter(scene.filter_width)
        gb = trace_gbuffer(ctx, settings.seed, frame, pixel_filter)
        t = spent("gbuffer", t_start)
        n = len(gb.valid)
        pix = np.arange(n, dtype=np.int64)
        seeds = samplers.path_seeds(settings.seed, frame, pix, 0x5EED)

        history = self.history
        if history is not None:
            carry_with_objects(scene, history)     # samples and owners ride with moved objects
        motion = ObjectMotion.between(scene, history)     # None if nothing moved

        # Last frame's traced visibility is reused only if no triangle moved.
        geometry_key = scene.geometry_key()
        moved = history is not None and geometry_key != self._geometry_key
        static = history is not None and history.visibility is not None and not moved
        self._geometry_key = geometry_key
        # Stored samples are re-traced only if the lighting changed since the
        # last validation: in an unchanged scene a re-traced path (same seed)
        # gives exactly its stored radiance.
        accumulating = settings.accumulate > 1
        # What the pixels' running means forget (accumulation.py): everything
        # after an edit of lights, materials or the world (the lighting key
        # changed with the geometry as it was), and again when validation
        # brings the stored samples up to date with that edit; all but the
        # last MOVING_CAP frames when objects moved or samples were validated
        # after objects moved (local changes: shadows, reflections).
        forget_all = forget_old = False
        if settings.validation_interval > 0 or accumulating:
            key = scene.lighting_key(geometry_key)
            relit = self._lighting_key is not None and key != self._lighting_key
            self._stale |= relit
            self._lighting_key = key
            forget_all = relit and not moved
            self._light_edit |= forget_all
            forget_old = moved
        if settings.validation_interval > 0:
            if history is not None and self._stale and self.frames % settings.validation_interval == 0:
                validate(ctx, [history.temporal, history.spatial], settings.max_bounces)
                self.validations += 1
                self._stale = False
                forget_all |= self._light_edit
                forget_old = True
                self._light_edit = False
        spent("validation", t)

        # Every pass below is per pixel, so workers take pixel ranges
        # (core/parallel.py); spatial reuse reads neighbours from the whole
        # image, so it waits for all temporal reservoirs.
        def new_samples(a, b):
            t = time.perf_counter()
            part = gb.part(a, b)
            prev = reproject(scene, part, history, motion) if settings.temporal else np.full(b - a, -1, np.int64)
            hold = reprojected_hold(prev, history.noise_hold) if history is not None else None
            acc_prev = None
            if accumulating and history is not None and history.accumulation is not None:
                acc_prev = previous_pixels(scene, part, history, motion, still_scene=not moved)
            counts = light_sample_counts(part.index, prev, hold, settings.light_samples)
            # Initial samples (several per pixel are streamed into one reservoir).
            initial, direct, glossy = initial_samples(ctx, part, settings.seed, frame, 0,
                                                      settings.max_bounces, settings.initial_sampling, counts)
            for s in range(1, max(1, settings.samples)):
                extra, d, g = initial_samples(ctx, part, settings.seed, frame, s, settings.max_bounces,
                                              settings.initial_sampling, counts)
                merge(initial, extra, extra.w_sum, extra.M, samplers.uniform(seeds[a:b], 10 + s))
                direct += d
                glossy += g
            direct /= max(1, settings.samples)
            glossy /= max(1, settings.samples)
            finalize(initial, target_at(initial, part.p, part.ng, part.n))
            t = spent("initial", t)
            temporal = temporal_resample(initial, part, history, prev, samplers.uniform(seeds[a:b], 5),
                                         settings.temporal_M_cap, settings.max_age, biased)
            spent("temporal", t)
            return prev, hold, direct, glossy, temporal, acc_prev

        prev_pix, hold, direct, glossy, temporal, acc_pix = concat_rows(ctx.workers.map(new_samples, n),
                                                                          consume=True)
        ctx.accel.poll()    # the resampling passes trace no rays until shading
        if biased:      # the filter trades a little energy for stability: not in the unbiased mode
            boiling_filter(temporal, gb.width, gb.height, settings.boiling_filter)

        gb.images()     # the whole-image arrays, made before the workers read them
        # The unbiased mode does not carry its spatial reservoirs: with 1/Z
        # weights a carried reservoir's weight is w_sum M / Z, and once visible
        # points move (the pixel filter's jitter, a moving camera) a small Z
        # compounds frame after frame into fireflies (max indirect radiance
        # 1150 against about 10 on the room, with the file's filter). History
        # still arrives through the temporal reservoirs; MSE after 16 frames is
        # the same as with a carried M capped at 5, fireflies gone.
        cap = settings.spatial_M_cap
        carry = settings.spatial and biased and history is not None and bool((prev_pix >= 0).any())
        lum_wm = reuse_weights(temporal) if settings.spatial else None

        def reuse(a, b):
            t = time.perf_counter()
            known = None
            if not settings.spatial:
                spatial, visible_own = temporal.rows(a, b), None
            else:
                prev_spatial, prev_owner = None, None
                if carry:       # last frame's spatial reservoirs of these pixels
                    found = prev_pix[a:b] >= 0
                    q = np.maximum(prev_pix[a:b], 0)
                    prev_spatial = history.spatial.take(q)
                    prev_spatial.M = np.where(found, np.minimum(prev_spatial.M, cap), 0.0).astype(np.float32)
                    prev_spatial.age += 1
                    prev_spatial.M[prev_spatial.age > settings.max_age] = 0
                    prev_owner = gather(history.p, q)
                spatial, visible_own, from_prev = spatial_resample(
                    ctx, gb, temporal, prev_spatial, prev_owner, seeds, settings.spatial_neighbors,
                    settings.spatial_radius, biased, rows=(a, b), lum_wm=lum_wm)
                if carry and static and visible_own is None:
                    known = carried_visibility(np.take(history.visibility, q), from_prev, prev_owner,
                                               gb.p[a:b], spatial.x2)
            t = spent("spatial", t)
            part = gb.part(a, b)
            indirect, visibility = shade_indirect(ctx, part, spatial, visible_own, known)
            alpha, keep = materials.camera_alpha(scene, b - a, part.index, part.surf)
            spent("shading", t)
            return spatial, visibility, indirect, alpha, keep

        spatial, visibility, indirect, alpha_now, keep = concat_rows(ctx.workers.map(reuse, n), consume=True)
        if biased and settings.spatial:
            # A sample hidden from its pixel is not carried to the next frame
            # (RTXDI's "discard invisible samples"): with M up to the spatial
            # cap it would win again and again, a black pixel for many frames.
            # On the room this takes pixels without indirect light from 4.7 %
            # to 1.5 % and the mean closer to the reference (bench/fig1.py's MSE
            # is unchanged).
            spatial.clear(visibility < 0)
        direct_total = gb.emission + direct
        indirect += glossy      # the glossy lobe's light, from this frame's own samples
        if (keep < 1).any():    # Holdout: the pixel's share cut out, colour and all
            direct_total, indirect = scale(direct_total, keep), scale(indirect, keep)
        for a in (direct_total, indirect):
            np.nan_to_num(a, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
        acc = None
        if accumulating:
            prev_acc = history.accumulation if history is not None and acc_pix is not None else None
            if forget_all:
                restart(prev_acc)
            elif forget_old:
                restart(prev_acc, MOVING_CAP)
            acc = accumulate(prev_acc, acc_pix if prev_acc is not None else None,
                             direct_total, indirect, gb.albedo, gb.n, settings.accumulate, alpha_now)
            direct_total, indirect, albedo, normal = acc.direct, acc.indirect, acc.albedo, acc.normal
            alpha = acc.alpha
        else:
            albedo, normal, alpha = gb.albedo, gb.n, alpha_now
        color = direct_total + indirect

        self.history = FrameHistory(
            width=gb.width, height=gb.height, camera=scene.camera, p=gb.p, n=gb.n,
            ng=gb.ng, depth=gb.depth, valid=gb.valid, object_id=gb.object_id,
            object_keys=list(scene.object_keys), object_matrices=np.asarray(scene.object_matrices),
            signature=_signature(scene), temporal=temporal, spatial=spatial, visibility=visibility,
            noise_hold=update_noise_hold(direct, gb.valid, gb.width, gb.height, hold),
            accumulation=acc)
        self.frames += 1
        timings["total"] = time.perf_counter() - t_start
        self.last_timings = timings
        found = float((prev_pix[gb.index] >= 0).mean()) if len(gb.index) else 0.0
        return FrameResult(color, direct_total, indirect, gb.depth, normal, albedo,
                           spatial.M.copy(), spatial.W.copy(), found, alpha.copy())


def _signature(scene):
    """What must not change for stored reservoirs to stay meaningful."""
    return (scene.width, scene.height, scene.triangle_count, len(scene.materials))
