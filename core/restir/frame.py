"""One ReSTIR GI frame as named stages over one declared per-frame state.

``FrameState`` declares everything a frame reads and writes; each stage is a
function of it, run in this order by ``STAGES`` (the wavefront of pbrt-v4's
``Render()``, one whole-image pass per stage or per pair of stages):

    scene changes  (scene_changes.py) objects that moved carry their samples;
                   lights, materials and the world compared with last
                   frame's; sample validation
    temporal gradients (gradients.py) where objects moved, some of last
                   frame's samples drawn again in this frame's scene: where
                   the light changed, reservoirs and running means forget
    first pass     per pixel range: G-buffer, reprojection, initial samples,
                   sky rays, temporal reuse
    light probes   (light_probes.py) where objects moved, last frame's light
                   probes again in this frame's scene: where the direct
                   light changed, its running means forget
    between passes edge refinement, the gates of the running means, the
                   boiling filter, last frame's state let go
    second pass    per pixel range: spatial reuse, shading, glossy reuse,
                   accumulation
    denoise        the denoiser over the running means (with Denoise on)

Every per-range pass runs over pixel ranges on the workers
(core/workers/parallel.py); spatial reuse reads neighbours from the whole
image, so it waits for the whole first pass. Each range's outputs go straight
into whole-image arrays (Workers.map_into), and its G-buffer hits and shading
frames live only while the range runs: the second pass needs of them what the
whole-image arrays hold.
"""

import time
from dataclasses import dataclass, replace

import numpy as np

from ..camera.projection import PixelFilter
from ..materials import shading as materials
from ..sampling import samplers
from ..util.rows import gather, scale, scatter, scatter_add
from ..util.vectors import luminance
from .accumulation import COLUMNS, Accumulation, FrameValues, accumulate, light_range, restart
from .adaptive_direct import light_sample_counts, reprojected_hold, update_noise_hold
from .boiling import boiling_filter
from .denoise import MOMENTS, frame_moments
from .denoise import denoise as svgf
from .gbuffer import FirstPass, FrameImage, trace_rows
from .ghosts import SurfaceRange, parallax, surface_range
from .glossy_reuse import GlossySamples, reuse_glossy
from .moved_history import forget_where_changed, light_probes, temporal_gradients
from .initial import InitialSampling, initial_samples
from .reprojection import film_shift, geometric_edges, previous_pixels, same_view
from .reservoirs import distinct, finalize, merge
from .scene_changes import SceneChanges, scene_changes
from .settings import UNBIASED
from .shading import carried_visibility, shade_indirect
from .shift import target_at
from .sky import pixel_shares, point_plan, visible_sky_light
from .spatial import CarriedSpatial, SpatialReuse, shared_terms, spatial_resample
from .silhouettes import refine_edges
from .edge_direct import refine_direct_edges
from .temporal import FrameHistory, reproject, temporal_resample
from .timings import Timings, stage

MOVING_NEIGHBORS = 1      # spatial neighbours more on objects that moved, per neighbour
MOVING_M_CAP = 4.0  # M cap of the reservoirs of pixels on objects that moved: a moving
                    # object's light changes as it moves, and with the usual caps its
                    # reservoirs lagged (tests/core/restir/test_restir_moving_objects.py)


@dataclass
class FrameState:
    """Everything one frame reads and writes, stage after stage."""
    # Given
    ctx: object                     # RenderContext
    settings: object                # ReSTIRSettings
    frame: int                      # the frame number (random numbers)
    index: int                      # frames rendered before this one in the stream
    history: object                 # last frame's FrameHistory, or None
    changes: SceneChanges
    timings: Timings
    # Derived from the given
    biased: bool = False
    pixel_filter: object = None
    width: int = 0
    height: int = 0
    n: int = 0
    seeds: np.ndarray = None        # (n,) per-pixel seeds of this frame
    sky_on: bool = False            # sky rays (sky.py)
    path_reuse: bool = False        # the glossy lobe's path reuse (glossy_reuse.py)
    # Scene changes
    motion: object = None           # ObjectMotion, None if nothing moved
    moved: bool = False             # triangles moved since last frame
    static: bool = False            # last frame's traced visibility still holds
    still_view: bool = False        # nothing moved, the camera included, since last frame
    forget_all: bool = False        # the running means start over
    forget_old: bool = False        # the running means keep their last MOVING_CAP frames (with a
                                    # gradient: where the light changed, and on moved objects)
    gradient: np.ndarray = None     # (P_prev,) lambda of temporal_gradients, or None
    # First pass
    shaded: np.ndarray = None       # (n, COLUMNS [+ MOMENTS]) colours, then running means
    first: FirstPass = None
    prev_pix: np.ndarray = None     # (n,) last frame's pixel of each pixel (-1: none)
    # Between passes
    img: FrameImage = None
    refined: object = None          # silhouettes.RefinedSeen, or None
    gate: object = None             # accumulation.light_range, or None
    edges: np.ndarray = None        # geometric edges, or None
    light_change: np.ndarray = None     # light_probes' lambda over last frame's pixels, or None
    light_probe: np.ndarray = None      # this frame's light probes (light_probes.py), or None
    surface: SurfaceRange = None    # this frame's albedo and normal ranges (moving views), or None
    film: tuple = None              # reprojection.film_shift of every pixel (moving views), or None
    carry: bool = False             # last frame's spatial reservoirs are candidates
    shared: object = None           # spatial.shared_terms, or None
    prev_acc: object = None         # last frame's Accumulation, or None
    # Second pass and denoise
    temporal: object = None         # Reservoirs after temporal reuse
    spatial: object = None          # Reservoirs after spatial reuse
    visibility: np.ndarray = None   # carried visibility of the chosen samples
    color: np.ndarray = None        # (n, 3) the frame's colour
    cut: np.ndarray = None          # pixels a holdout cuts into (denoiser's mask), or None
    noisy: np.ndarray = None        # the colour before the denoiser, or None

    @staticmethod
    def begin(ctx, settings, frame, index, history, changes, timings):
        scene = ctx.scene
        n = scene.width * scene.height
        return FrameState(
            ctx, settings, frame, index, history, changes, timings,
            biased=settings.mode != UNBIASED, pixel_filter=PixelFilter(scene.filter_width),
            width=scene.width, height=scene.height, n=n,
            seeds=samplers.path_seeds(settings.seed, frame, np.arange(n, dtype=np.int64), 0x5EED),
            sky_on=settings.sky_samples > 0 and ctx.lights.environment is not None,
            # Objects hidden from some kinds of rays: the shadow rays of path
            # reuse would not know which kind they stand for.
            path_reuse=settings.glossy_reuse and not getattr(ctx.accel, "per_kind_visibility", False))

    @property
    def accumulating(self):
        return self.settings.accumulate > 1

    def moving_cap(self, object_id, cap):
        """The M cap of pixels with these object ids (-1: none): lower on moved objects."""
        if self.motion is None:
            return cap
        on = np.where(object_id >= 0, self.motion.moved_now[np.maximum(object_id, 0)], False)
        return np.where(on, min(cap, MOVING_M_CAP), cap).astype(np.float32)


def first_pass(s):
    """G-buffer, initial samples and temporal reuse of every pixel range."""
    # The first pass's colours and factors go into the columns of the array
    # that the second pass turns into this frame's running means
    # (accumulation.COLUMNS), each range reading and then overwriting its own
    # rows: no whole-image arrays of their own. With the denoiser the running
    # means carry its moments too (denoise.py).
    s.shaded = np.empty((s.n, COLUMNS + (MOMENTS if s.settings.denoise else 0)), np.float32)

    def new_samples(a, b):
        return first_pass_rows(s, a, b)

    s.first = s.ctx.workers.map_into(new_samples, s.n, out=FirstPass.allocate(
        s.n, s.shaded, s.history is not None, GlossySamples.allocate(s.n) if s.path_reuse else None))
    s.temporal, s.prev_pix = s.first.temporal, s.first.prev_pix


def first_pass_rows(s, a, b):
    """The first pass over pixels a:b: a FirstPass of those rows."""
    ctx, settings, history, timings = s.ctx, s.settings, s.history, s.timings
    scene = ctx.scene
    t = time.perf_counter()
    with stage("G-buffer"):
        part = trace_rows(ctx, settings.seed, s.frame, s.pixel_filter, True, a, b, s.index)
    t = timings.spent("gbuffer", t)
    with stage("reprojection"):
        prev = reproject(scene, part, history, s.motion) if settings.temporal else np.full(b - a, -1, np.int64)
        hold = reprojected_hold(prev, history.noise_hold) if history is not None else None
        counts = light_sample_counts(part.index, prev, hold, settings.light_samples)
    with stage("initial samples"):
        initial, direct, glossy, reused, value = _initial(s, part, counts, a, b)
    with stage("sky rays"):
        sky_lum = _sky_rays(s, part, prev, direct, a, b)
    with stage("initial samples"):
        finalize(initial, target_at(initial, part.p, part.ng, part.n))
    t = timings.spent("initial", t)
    with stage("temporal reuse"):
        temporal = temporal_resample(initial, part, history, prev, samplers.uniform(s.seeds[a:b], 5),
                                     s.moving_cap(part.object_id, settings.temporal_M_cap),
                                     settings.max_age, s.biased)
    del initial
    with stage("G-buffer"):
        alpha, keep = materials.camera_alpha(scene, b - a, part.index, part.surf)
        diffuse = scatter(np.zeros((b - a, 3), np.float32), part.index, part.frame.params.diffuse)
    timings.spent("temporal", t)
    return FirstPass(part.valid, part.depth, part.object_id, part.p, part.n, part.ng, part.albedo,
                     direct, luminance(direct).astype(np.float32), part.emission, glossy, diffuse,
                     alpha, keep, prev.astype(np.int32), hold, temporal, reused, sky_lum, value)


def _initial(s, part, counts, a, b):
    """Initial samples (several per pixel are streamed into one reservoir),
    the direct light and the glossy lobe's light, averaged over them; the
    first sample's points for path reuse (GlossySamples), or None."""
    settings = s.settings
    per_frame = max(1, settings.samples)
    along = settings.sequences
    first = InitialSampling(settings.max_bounces, settings.initial_sampling, counts,
                            own_surface_glossy=not s.path_reuse, sky_rays=s.sky_on)
    initial, direct, glossy = initial_samples(s.ctx, part, settings.seed, s.frame, 0, first,
                                              stream_index=s.index * per_frame if along else None)
    value = initial.w_sum.astype(np.float32)       # (the next frame's temporal gradients)
    reused = GlossySamples.of_range(part, initial) if s.path_reuse else None
    more = replace(first, own_surface_glossy=True)
    for k in range(1, per_frame):
        extra, d, g = initial_samples(s.ctx, part, settings.seed, s.frame, k, more,
                                      stream_index=s.index * per_frame + k if along else None)
        merge(initial, extra, extra.w_sum, extra.M, samplers.uniform(s.seeds[a:b], 10 + k))
        direct += d
        glossy += g
    direct /= per_frame
    glossy /= per_frame
    return initial, direct, glossy, reused, value


def _sky_rays(s, part, prev, direct, a, b):
    """The sky's light through the sky rays (sky.py), added to direct; the
    luminance of it per pixel."""
    settings, history = s.settings, s.history
    per_frame = max(1, settings.samples)
    along = settings.sequences
    share = np.where(prev >= 0, history.sky_share[np.maximum(prev, 0)], np.nan) \
        if s.sky_on and history is not None and history.sky_share is not None else np.full(b - a, np.nan)
    sky = visible_sky_light(s.ctx, part, settings.seed, s.frame, s.seeds[a:b][part.index],
                            point_plan(settings.sky_samples, share[part.index]), settings.sky_samples,
                            [s.index * per_frame + k if along else None for k in range(per_frame)])
    scatter_add(direct, part.index, sky)
    return scatter(np.zeros(b - a, np.float32), part.index, luminance(sky).astype(np.float32))


def between_passes(s):
    """Edge refinement, the gates of the running means, the boiling filter;
    what the second pass does not read of last frame's state is let go."""
    ctx, settings, history, one = s.ctx, s.settings, s.history, s.first
    t = time.perf_counter()
    with stage("edge refinement"):
        s.refined = refine_edges(ctx, settings.seed, s.frame, s.pixel_filter, one.seen, one.lum_direct,
                                 settings.edge_samples, s.index)
    s.timings.spent("gbuffer", t)
    s.img = FrameImage(one.valid, one.depth, one.object_id, one.p, one.n, one.ng, s.width, s.height)
    s.still_view = history is not None and not s.moved and same_view(ctx.scene.camera, history.camera)
    # Pixels on geometric edges read their running means' history from every
    # tap (reprojection.previous_pixels): on a moving view, a history of their
    # own surface alone left each showing whichever side its one ray hit.
    if s.accumulating and history is not None and not s.still_view:
        s.edges = geometric_edges(one.object_id, one.depth, one.valid, s.width, s.height)
        s.surface = surface_range(one.albedo, one.n, one.lum_direct + luminance(one.seen), s.width, s.height)
        s.film = film_shift(ctx.scene, history, np.arange(s.n), one.p[one.valid], one.valid, one.object_id,
                            s.motion)
        s.surface.edges, s.surface.parallax = s.edges, parallax(s.film[0], s.width)
    ctx.accel.poll()    # the resampling passes trace no rays until shading
    if s.biased:        # the filter trades a little energy for stability: not in the unbiased mode
        boiling_filter(s.temporal, s.width, s.height, settings.boiling_filter)
    if history is not None and getattr(ctx.accel, "interrupt", None) is None:
        # What the rest of the frame does not read of last frame's state is
        # let go now (a frame that can be interrupted, the viewport's, keeps
        # it all for the frame that follows).
        history.temporal = history.n = history.ng = history.valid = history.noise_hold = None
        history.sky_share = None

    # The unbiased mode does not carry its spatial reservoirs: with 1/Z
    # weights a carried reservoir's weight is w_sum M / Z, and once visible
    # points move (the pixel filter's jitter, a moving camera) a small Z
    # compounds frame after frame into fireflies. History still arrives
    # through the temporal reservoirs.
    s.carry = settings.spatial and s.biased and history is not None and bool((s.prev_pix >= 0).any())
    s.shared = shared_terms(s.temporal, s.biased) if settings.spatial else None
    if s.accumulating and history is not None and history.accumulation is not None \
            and history.accumulation.data.shape[1] == s.shaded.shape[1]:    # (the denoiser toggled: none)
        s.prev_acc = history.accumulation
        if s.forget_all:
            restart(s.prev_acc)
        elif s.forget_old:
            forget_where_changed(s)
    if s.moved and s.accumulating and s.prev_acc is not None and max(1, settings.samples) == 1:
        with stage("direct edges"):
            t = time.perf_counter()
            refine_direct_edges(ctx, settings.seed, s.frame, s.pixel_filter, one, s.prev_acc, s.index,
                                settings.sequences, InitialSampling(settings.max_bounces, settings.initial_sampling,
                                                                    settings.light_samples))
            s.timings.spent("gbuffer", t)
    s.gate = light_range(one.lum_direct, one.valid, s.width, s.height) if s.moved else None


def second_pass(s):
    """Spatial reuse, shading and accumulation of every pixel range."""
    def reuse(a, b):
        return second_pass_rows(s, a, b)

    spatial, s.visibility, s.color, s.cut = s.ctx.workers.map_into(reuse, s.n, written=(s.shaded,))
    s.spatial = s.temporal if spatial is None else spatial     # without spatial reuse the two are one


def _spatial(s, a, b):
    """Spatial reservoirs of pixels a:b, the visibility of their samples from
    their own points (unbiased mode), and what is known of it from last frame."""
    settings, history, img = s.settings, s.history, s.img
    if not settings.spatial:
        return s.temporal.rows(a, b), None, None
    prev_spatial, prev_owner, q = None, None, None
    if s.carry:       # last frame's spatial reservoirs of these pixels
        prev_pix = s.prev_pix
        found = prev_pix[a:b] >= 0
        q = np.maximum(prev_pix[a:b], 0)
        prev_spatial = history.spatial.take(q)
        cap_here = s.moving_cap(img.object_id[a:b], settings.spatial_M_cap)
        prev_spatial.M = np.where(found, np.minimum(prev_spatial.M, cap_here), 0.0).astype(np.float32)
        prev_spatial.age += 1
        prev_spatial.M[prev_spatial.age > settings.max_age] = 0
        prev_owner = gather(history.owners(spatial=True), q)
    # A still view's neighbours lie closer: they share more of the pixel's
    # light, and the blotches a small radius leaves do not crawl there
    # (corpus stills, biased + denoiser, at half the radius: courtyard
    # MSE -15 %, glossy -1 %, emitters 0, room +2 %, slit room +9 %;
    # docs/validation.md).
    radius = settings.spatial_radius * (settings.still_radius_scale if s.still_view else 1.0)
    # Pixels on objects that moved hold at most MOVING_M_CAP frames in their
    # reservoirs: they draw as many neighbours again (biased mode).
    reuse = SpatialReuse(settings.spatial_neighbors, radius, s.biased, MOVING_NEIGHBORS * settings.spatial_neighbors)
    carried = None if prev_spatial is None else CarriedSpatial(prev_spatial, prev_owner)
    oid = img.object_id[a:b]
    more = None if s.motion is None else s.motion.moved_now[np.maximum(oid, 0)] & (oid >= 0)
    spatial, visible_own, from_prev = spatial_resample(s.ctx, img, s.temporal, s.seeds, reuse, carried,
                                                       rows=(a, b), shared=s.shared, more=more)
    known = None
    if s.carry and s.static and visible_own is None:
        known = carried_visibility(np.take(history.visibility, q), from_prev, prev_owner, img.p[a:b], spatial.x2)
    return spatial, visible_own, known


def second_pass_rows(s, a, b):
    """The second pass over pixels a:b: (spatial reservoirs or None,
    visibility, colour, holdout cut) of those rows; the running means go into
    s.shaded's rows."""
    ctx, settings, one, img, timings = s.ctx, s.settings, s.first, s.img, s.timings
    t = time.perf_counter()
    part = img.part(a, b, one.diffuse)
    with stage("spatial reuse"):
        spatial, visible_own, known = _spatial(s, a, b)
    t = timings.spent("spatial", t)
    with stage("shading"):
        indirect, visibility = shade_indirect(ctx, part, spatial, visible_own, known)
        if s.biased and settings.spatial:
            # A sample hidden from its pixel is not carried to the next frame
            # (RTXDI's "discard invisible samples"): with M up to the spatial
            # cap it would win again and again, a black pixel for many frames.
            spatial.clear(visibility < 0)
        direct_total, seen = one.direct[a:b], one.seen[a:b]
        indirect += one.glossy[a:b]     # the glossy lobe's light, from this frame's own samples
    if one.glossy_samples is not None:  # ... and, on surfaces, its neighbours' (first sample)
        t = timings.spent("shading", t)
        with stage("glossy reuse"):
            indirect += reuse_glossy(ctx, img, one.glossy_samples, a, b) / np.float32(max(1, settings.samples))
        t = timings.spent("glossy", t)
    with stage("shading"):
        keep = one.keep[a:b].copy()
        if (keep < 1).any():    # Holdout: the pixel's share cut out, colour and all
            direct_total, indirect, seen = scale(direct_total, keep), scale(indirect, keep), scale(seen, keep)
        for x in (direct_total, indirect, seen):
            np.nan_to_num(x, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
    with stage("accumulation"):
        footprint = None
        if s.prev_acc is not None:
            footprint = previous_pixels(ctx.scene, part, s.history, s.motion, still_scene=not s.moved,
                                        edges=None if s.edges is None else s.edges[a:b],
                                        film=None if s.film is None else (s.film[0][a:b], s.film[1][a:b]))
        moments = frame_moments(indirect, one.albedo[a:b]) if settings.denoise else None
        # (without accumulation: this frame's values, as a mean of one frame)
        values = FrameValues(direct_total, indirect, one.albedo[a:b], img.n[a:b], one.alpha[a:b], seen,
                             settings.frame_weight, moments)
        rows = accumulate(s.prev_acc, footprint, values, settings.accumulate,
                          None if s.refined is None else s.refined.rows(a, b),
                          None if s.gate is None else s.gate.rows(a, b),
                          None if s.surface is None else s.surface.rows(a, b)).data
        s.shaded[a:b] = rows
    color = rows[:, 0:3] + rows[:, 3:6] + rows[:, 14:17]
    timings.spent("shading", t)
    # Pixels a holdout cuts into are left out of the denoiser (it would blur
    # their neighbours' light into the hole).
    cut = (keep < 1) if settings.denoise else None
    return (None if not settings.spatial else spatial), visibility, color, cut


def denoise(s):
    """The denoiser over this frame's running means (denoise.py)."""
    if not s.settings.denoise:
        return
    img = s.img
    with stage("denoising"):
        s.noisy, s.color = s.color, svgf(s.ctx.workers, s.shaded, img.depth, img.valid & ~s.cut, img.width,
                                         img.height, timed=lambda: s.timings.timed("denoise"),
                                         poll=s.ctx.accel.poll)


STAGES = (scene_changes, temporal_gradients, first_pass, light_probes, between_passes, second_pass, denoise)


def next_history(s, signature):
    """What the next frame reads of this one (FrameHistory); this frame's
    Accumulation of the running means."""
    img, one = s.img, s.first
    frame_acc = Accumulation(s.shaded)
    hold = update_noise_hold(None, img.valid, img.width, img.height, one.hold, lum=one.lum_direct)
    sky_share = None
    if s.sky_on:
        lit = (luminance(frame_acc.direct) + luminance(frame_acc.indirect)) * img.valid  # not the world seen directly
        sky_share = pixel_shares(one.sky, lit, img.width, img.height)
    sample_value = one.sample_value
    s.first = None     # the first pass's arrays: released before the history is made
    for r in distinct(s.temporal, s.spatial):
        if hasattr(r, "keep_for_next_frame"):
            r.keep_for_next_frame()
    scene = s.ctx.scene
    history = FrameHistory(
        width=img.width, height=img.height, camera=scene.camera, p=img.p, n=img.n,
        ng=img.ng, depth=img.depth, valid=img.valid, object_id=img.object_id,
        object_keys=list(scene.object_keys), object_matrices=np.asarray(scene.object_matrices),
        signature=signature, temporal=s.temporal, spatial=s.spatial, visibility=s.visibility,
        noise_hold=hold, accumulation=frame_acc if s.accumulating else None, sky_share=sky_share,
        sample_value=sample_value, frame=s.frame, index=s.index, light_probe=s.light_probe)
    return history, frame_acc
