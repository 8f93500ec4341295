"""ReSTIR GI (Ouyang et al. 2021) as whole-image passes, one call per frame.

Per frame: primary visibility (gbuffer.py) -> initial samples (initial.py) ->
temporal resampling (temporal.py) -> spatial resampling (spatial.py) -> final
shading (shading.py) -> reprojected accumulation of the shaded frames
(accumulation.py) -> optionally the denoiser (denoise.py); every few
frames, sample validation (validation.py).
``ReSTIRGI`` owns the state that lives between frames; everything else is
plain functions of plain arrays.
"""

import contextlib
import threading
import time
import numpy as np

from ..materials import shading as materials
from ..sampling import samplers
from ..util.errors import context
from ..camera.projection import PixelFilter
from ..workers.parallel import release_free_memory
from .reservoirs import NARROW_MIN_PIXELS
from .reservoirs import cap_history, finalize, merge
from ..util.rows import gather, scale, scatter, scatter_add
from ..util.vectors import luminance
from .accumulation import (COLUMNS, Accumulation, accumulate, geometric_edges, light_range, previous_pixels,
                           restart, same_view)
from .adaptive_direct import light_sample_counts, reprojected_hold, update_noise_hold
from .boiling import boiling_filter
from .denoise import MOMENTS, frame_moments
from .denoise import denoise as svgf        # (core.restir.denoise stays the module)
from .gbuffer import FirstPass, FrameImage, trace_rows
from .glossy_reuse import GlossySamples, reuse_glossy
from .initial import initial_samples
from .shading import carried_visibility, shade_indirect
from .shift import target_at
from .spatial import shared_terms, spatial_resample
from .silhouettes import refine_edges
from .sky import pixel_shares, point_plan, visible_sky_light
from .settings import BIASED, UNBIASED, FrameResult, ReSTIRSettings  # noqa: F401  (the package's API)
from .temporal import FrameHistory, ObjectMotion, carry_with_objects, reproject, temporal_resample
from .validation import validate

# Below this many pixels a frame's freed temporaries are left in the heaps:
# giving them back makes the next frame fault their pages in again (about
# 7 % of a 320x180 frame), and they are small (docs/plan.md, issue 12). The
# same size at which the reservoirs start to be stored narrowed.
TRIM_MIN_PIXELS = NARROW_MIN_PIXELS
MOVING_CAP = 4      # frames of accumulated history kept in a frame where objects moved
MOVING_M_CAP = 4.0  # M cap of the reservoirs of pixels on objects that moved: a moving
                    # object's light changes as it moves, and with the usual caps its
                    # reservoirs lagged (tests/core/restir/test_restir_moving_objects.py)


def stage(name):
    """Errors raised inside name the frame's stage (errors.context)."""
    return context("stage", name)


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
        self.validations = 0        # sample validations run (skipped while nothing changed)
        self.last_timings = {}      # seconds per pass of the last frame (see render_frame)
        self._lighting_key = None   # Scene.lighting_key of the last frame
        self._shading_key = None    # Scene.shading_key of the last frame
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
        return sum(r.nbytes for r in _distinct(h.temporal, h.spatial)) + sum(
            a.nbytes for a in (h.p, h.n, h.ng, h.depth, h.valid, h.object_id, h.noise_hold, h.sky_share,
                                h.visibility, h.accumulation) if a is not None)

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
        timings = {"gbuffer": 0.0, "validation": 0.0, "initial": 0.0, "temporal": 0.0,
                   "spatial": 0.0, "glossy": 0.0, "shading": 0.0, "denoise": 0.0}
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
        gb_width, gb_height = scene.width, scene.height
        n = gb_width * gb_height
        t = time.perf_counter()
        pix = np.arange(n, dtype=np.int64)
        seeds = samplers.path_seeds(settings.seed, frame, pix, 0x5EED)

        history = self.history
        with stage("object motion"):
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
        # after an edit of lights, materials or the world (in the same frame
        # as objects moved too: the lights' edit lit the whole image anew),
        # and again when validation brings the stored samples up to date with
        # that edit; all but the last MOVING_CAP frames when objects moved or
        # samples were validated after objects moved (local changes: shadows,
        # reflections).
        forget_all = forget_old = False
        if settings.validation_interval > 0 or accumulating:
            shading_key = scene.shading_key()
            key = scene.lighting_key(geometry_key, shading_key)
            relit = self._lighting_key is not None and key != self._lighting_key
            self._stale |= relit
            self._lighting_key = key
            reshaded = self._shading_key is not None and shading_key != self._shading_key
            self._shading_key = shading_key
            forget_all = (relit and not moved) or reshaded
            self._light_edit |= forget_all
            forget_old = moved
        if settings.validation_interval > 0:
            if history is not None and self._stale and (self.frames % settings.validation_interval == 0
                                                        or settings.validate_on_change):
                with stage("sample validation"):
                    validate(ctx, _distinct(history.temporal, history.spatial), settings.max_bounces)
                self.validations += 1
                self._stale = False
                if self._light_edit:
                    # Samples found under the old light stand for one
                    # candidate each: a spot widened from 20 to 120 degrees
                    # left frames 7-12 % dark for 14 frames while reservoirs of
                    # M up to the caps outweighed the new light's samples
                    # (2-3 % with this).
                    for res in _distinct(history.temporal, history.spatial):
                        cap_history(res, 1.0)
                forget_all |= self._light_edit
                forget_old = True
                self._light_edit = False
        spent("validation", t)

        # Every pass below is per pixel, so workers take pixel ranges
        # (core/workers/parallel.py); spatial reuse reads neighbours from the whole
        # image, so it waits for all temporal reservoirs. Each range's outputs
        # go straight into whole-image arrays (Workers.map_into), and its
        # G-buffer hits and shading frames live only while the range runs:
        # the second pass needs of them what the whole-image arrays hold.
        def moving_cap(object_id, cap):
            """The M cap of pixels with these object ids (-1: none): lower on moved objects."""
            if motion is None:
                return cap
            on = np.where(object_id >= 0, motion.moved_now[np.maximum(object_id, 0)], False)
            return np.where(on, min(cap, MOVING_M_CAP), cap).astype(np.float32)

        sky_on = settings.sky_samples > 0 and ctx.lights.environment is not None     # sky.py

        def new_samples(a, b):
            t = time.perf_counter()
            with stage("G-buffer"):
                part = trace_rows(ctx, settings.seed, frame, pixel_filter, True, a, b, self.frames)
            t = spent("gbuffer", t)
            with stage("reprojection"):
                prev = reproject(scene, part, history, motion) if settings.temporal \
                    else np.full(b - a, -1, np.int64)
                hold = reprojected_hold(prev, history.noise_hold) if history is not None else None
                counts = light_sample_counts(part.index, prev, hold, settings.light_samples)
            # Initial samples (several per pixel are streamed into one reservoir).
            per_frame = max(1, settings.samples)
            along = settings.sequences
            with stage("initial samples"):
                initial, direct, glossy = initial_samples(ctx, part, settings.seed, frame, 0,
                                                          settings.max_bounces, settings.initial_sampling, counts,
                                                          own_surface_glossy=not path_reuse,
                                                          stream_index=self.frames * per_frame if along else None,
                                                          sky_rays=sky_on)
                reused = GlossySamples.of_range(part, initial) if path_reuse else None
                for s in range(1, max(1, settings.samples)):
                    extra, d, g = initial_samples(ctx, part, settings.seed, frame, s, settings.max_bounces,
                                                  settings.initial_sampling, counts,
                                                  stream_index=self.frames * per_frame + s if along else None,
                                                  sky_rays=sky_on)
                    merge(initial, extra, extra.w_sum, extra.M, samplers.uniform(seeds[a:b], 10 + s))
                    direct += d
                    glossy += g
                direct /= max(1, settings.samples)
                glossy /= max(1, settings.samples)
            with stage("sky rays"):
                share = np.where(prev >= 0, history.sky_share[np.maximum(prev, 0)], np.nan) \
                    if sky_on and history is not None and history.sky_share is not None else np.full(b - a, np.nan)
                sky = visible_sky_light(ctx, part, settings.seed, frame, seeds[a:b][part.index],
                                        point_plan(settings.sky_samples, share[part.index]), settings.sky_samples,
                                        [self.frames * per_frame + s if along else None for s in range(per_frame)])
                scatter_add(direct, part.index, sky)
                sky_lum = scatter(np.zeros(b - a, np.float32), part.index, luminance(sky).astype(np.float32))
            with stage("initial samples"):
                finalize(initial, target_at(initial, part.p, part.ng, part.n))
            t = spent("initial", t)
            with stage("temporal reuse"):
                temporal = temporal_resample(initial, part, history, prev, samplers.uniform(seeds[a:b], 5),
                                             moving_cap(part.object_id, settings.temporal_M_cap),
                                             settings.max_age, biased)
            del initial
            with stage("G-buffer"):
                alpha, keep = materials.camera_alpha(scene, b - a, part.index, part.surf)
                diffuse = scatter(np.zeros((b - a, 3), np.float32), part.index, part.frame.params.diffuse)
            spent("temporal", t)
            return FirstPass(part.valid, part.depth, part.object_id, part.p, part.n, part.ng, part.albedo,
                             direct, luminance(direct).astype(np.float32), part.emission, glossy, diffuse,
                             alpha, keep, prev.astype(np.int32), hold, temporal, reused,
                             sky_lum)

        # The first pass's colours and factors go into the columns of the
        # array that the second pass turns into this frame's running means
        # (accumulation.COLUMNS), each range reading and then overwriting its
        # own rows: no whole-image arrays of their own.
        # With the denoiser the running means carry its moments too (denoise.py).
        shaded = np.empty((n, COLUMNS + (MOMENTS if settings.denoise else 0)), np.float32)
        # Objects hidden from some kinds of rays: the shadow rays of path reuse
        # would not know which kind they stand for.
        path_reuse = settings.glossy_reuse and not getattr(ctx.accel, "per_kind_visibility", False)
        one = ctx.workers.map_into(new_samples, n, out=FirstPass.allocate(
            n, shaded, history is not None, GlossySamples.allocate(n) if path_reuse else None))
        prev_pix, temporal = one.prev_pix, one.temporal
        t = time.perf_counter()
        with stage("edge refinement"):
            refined = refine_edges(ctx, settings.seed, frame, pixel_filter, one.seen, one.lum_direct,
                                   settings.edge_samples, self.frames)
        spent("gbuffer", t)
        img = FrameImage(one.valid, one.depth, one.object_id, one.p, one.n, one.ng, gb_width, gb_height)
        gate = light_range(one.lum_direct, one.valid, gb_width, gb_height) if moved else None
        # Pixels on geometric edges read their running means' history from
        # every tap (accumulation.previous_pixels): on a moving view, a history
        # of their own surface alone left each showing whichever side its one
        # ray hit (courtyard and slit room moving: MSE -27 % and -29 %).
        edges = None
        if accumulating and history is not None and (moved or not same_view(scene.camera, history.camera)):
            edges = geometric_edges(one.object_id, one.depth, one.valid, gb_width, gb_height)
        ctx.accel.poll()    # the resampling passes trace no rays until shading
        if biased:      # the filter trades a little energy for stability: not in the unbiased mode
            boiling_filter(temporal, img.width, img.height, settings.boiling_filter)
        if history is not None and getattr(ctx.accel, "interrupt", None) is None:
            # What the rest of the frame does not read of last frame's state
            # is let go now (a frame that can be interrupted, the viewport's,
            # keeps it all for the frame that follows).
            history.temporal = history.n = history.ng = history.valid = history.noise_hold = None
            history.sky_share = None

        # The unbiased mode does not carry its spatial reservoirs: with 1/Z
        # weights a carried reservoir's weight is w_sum M / Z, and once visible
        # points move (the pixel filter's jitter, a moving camera) a small Z
        # compounds frame after frame into fireflies (max indirect radiance
        # 1150 against about 10 on the room, with the file's filter). History
        # still arrives through the temporal reservoirs; MSE after 16 frames is
        # the same as with a carried M capped at 5, fireflies gone.
        cap = settings.spatial_M_cap
        carry = settings.spatial and biased and history is not None and bool((prev_pix >= 0).any())
        shared = shared_terms(temporal, biased) if settings.spatial else None
        prev_acc = None
        if accumulating and history is not None and history.accumulation is not None \
                and history.accumulation.data.shape[1] == shaded.shape[1]:    # (the denoiser toggled: none)
            prev_acc = history.accumulation
            if forget_all:
                restart(prev_acc)
            elif forget_old:
                restart(prev_acc, MOVING_CAP)

        def reuse(a, b):
            t = time.perf_counter()
            part = img.part(a, b, one.diffuse)
            known = None
            with stage("spatial reuse"):
                if not settings.spatial:
                    spatial, visible_own = temporal.rows(a, b), None
                else:
                    prev_spatial, prev_owner = None, None
                    if carry:       # last frame's spatial reservoirs of these pixels
                        found = prev_pix[a:b] >= 0
                        q = np.maximum(prev_pix[a:b], 0)
                        prev_spatial = history.spatial.take(q)
                        cap_here = moving_cap(img.object_id[a:b], cap)
                        prev_spatial.M = np.where(found, np.minimum(prev_spatial.M, cap_here), 0.0).astype(np.float32)
                        prev_spatial.age += 1
                        prev_spatial.M[prev_spatial.age > settings.max_age] = 0
                        prev_owner = gather(history.owners(spatial=True), q)
                    spatial, visible_own, from_prev = spatial_resample(
                        ctx, img, temporal, prev_spatial, prev_owner, seeds, settings.spatial_neighbors,
                        settings.spatial_radius, biased, rows=(a, b), shared=shared)
                    if carry and static and visible_own is None:
                        known = carried_visibility(np.take(history.visibility, q), from_prev, prev_owner,
                                                   img.p[a:b], spatial.x2)
            t = spent("spatial", t)
            with stage("shading"):
                indirect, visibility = shade_indirect(ctx, part, spatial, visible_own, known)
                if biased and settings.spatial:
                    # A sample hidden from its pixel is not carried to the next frame
                    # (RTXDI's "discard invisible samples"): with M up to the spatial
                    # cap it would win again and again, a black pixel for many frames.
                    # On the room this takes pixels without indirect light from 4.7 %
                    # to 1.5 % and the mean closer to the reference (bench/fig1.py's MSE
                    # is unchanged).
                    spatial.clear(visibility < 0)
                direct_total, seen = one.direct[a:b], one.seen[a:b]
                indirect += one.glossy[a:b]     # the glossy lobe's light, from this frame's own samples
            if one.glossy_samples is not None:  # ... and, on surfaces, its neighbours' (first sample)
                t = spent("shading", t)
                with stage("glossy reuse"):
                    indirect += reuse_glossy(ctx, img, one.glossy_samples, a, b) \
                        / np.float32(max(1, settings.samples))
                t = spent("glossy", t)
            with stage("shading"):
                keep = one.keep[a:b].copy()
                if (keep < 1).any():    # Holdout: the pixel's share cut out, colour and all
                    direct_total, indirect, seen = scale(direct_total, keep), scale(indirect, keep), scale(seen, keep)
                for x in (direct_total, indirect, seen):
                    np.nan_to_num(x, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
            with stage("accumulation"):
                footprint = None
                if prev_acc is not None:
                    footprint = previous_pixels(scene, part, history, motion, still_scene=not moved,
                                                edges=None if edges is None else edges[a:b])
                moments = frame_moments(indirect, one.albedo[a:b]) if settings.denoise else None
                # (without accumulation: this frame's values, as a mean of one frame)
                rows = accumulate(prev_acc, footprint, direct_total, indirect, one.albedo[a:b], img.n[a:b],
                                  settings.accumulate, one.alpha[a:b], seen,
                                  None if refined is None else refined.rows(a, b),
                                  None if gate is None else gate.rows(a, b), settings.frame_weight,
                                  moments).data
                shaded[a:b] = rows
            color = rows[:, 0:3] + rows[:, 3:6] + rows[:, 14:17]
            spent("shading", t)
            # Pixels a holdout cuts into are left out of the denoiser (it would
            # blur their neighbours' light into the hole).
            cut = (keep < 1) if settings.denoise else None
            return (None if not settings.spatial else spatial), visibility, color, cut

        spatial, visibility, color, cut = ctx.workers.map_into(reuse, n, written=(shaded,))
        if spatial is None:
            spatial = temporal      # without spatial reuse the two are one
        noisy = None
        if settings.denoise:
            @contextlib.contextmanager
            def denoising():
                t = time.perf_counter()
                try:
                    yield
                finally:
                    spent("denoise", t)

            with stage("denoising"):
                noisy, color = color, svgf(ctx.workers, shaded, img.depth, img.valid & ~cut, img.width,
                                           img.height, timed=denoising, poll=ctx.accel.poll)
        frame_acc = Accumulation(shaded)
        acc = frame_acc if accumulating else None
        direct_total, indirect, albedo, normal, alpha = frame_acc.direct, frame_acc.indirect, \
            frame_acc.albedo, frame_acc.normal, frame_acc.alpha
        hold = update_noise_hold(None, img.valid, img.width, img.height, one.hold, lum=one.lum_direct)
        sky_share = None
        if sky_on:
            lit = (luminance(direct_total) + luminance(indirect)) * img.valid     # not the world seen directly
            sky_share = pixel_shares(one.sky, lit, img.width, img.height)
        one = None     # the first pass's arrays: released before the history is made
        for r in _distinct(temporal, spatial):
            if hasattr(r, "keep_for_next_frame"):
                r.keep_for_next_frame()

        self.history = FrameHistory(
            width=img.width, height=img.height, camera=scene.camera, p=img.p, n=img.n,
            ng=img.ng, depth=img.depth, valid=img.valid, object_id=img.object_id,
            object_keys=list(scene.object_keys), object_matrices=np.asarray(scene.object_matrices),
            signature=_signature(scene), temporal=temporal, spatial=spatial, visibility=visibility,
            noise_hold=hold, accumulation=acc, sky_share=sky_share)
        self.frames += 1
        if len(img.valid) >= TRIM_MIN_PIXELS:
            release_free_memory()   # the passes' temporaries, freed in the workers' heaps
        timings["total"] = time.perf_counter() - t_start
        self.last_timings = timings
        visible_rows = prev_pix[img.valid]
        found = float((visible_rows >= 0).mean()) if len(visible_rows) else 0.0
        return FrameResult(color, direct_total, indirect, img.depth, normal, albedo,
                           spatial.M.copy(), spatial.W.copy(), found, alpha.copy(), noisy)


def _distinct(*sets):
    """The reservoir sets, each once (without spatial reuse the spatial
    reservoirs are the temporal ones)."""
    return [r for i, r in enumerate(sets) if all(r is not other for other in sets[:i])]


def _signature(scene):
    """What must not change for stored reservoirs to stay meaningful."""
    return (scene.width, scene.height, scene.triangle_count, len(scene.materials))
