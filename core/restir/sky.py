"""The world's light on the diffuse lobe of visible points, from sky rays.

ReSTIR GI's reservoirs hold secondary surface points; direct light, the
world's included, is estimated apart (Ouyang et al. treat the environment as
a light of the direct pass). A sample ray that escapes could be kept as a
far "sky sample" and resampled like indirect light, but a reservoir keeps
one direction for several frames and lends it to its neighbours, and sky
light is mostly visibility: whether a direction is open or blocked, which a
neighbour's open direction says little about. On an open courtyard under a
sky the stills kept the sky's noise through every warm-up frame (their
error was the sky light carried by reservoirs; docs/plan.md).

So each visible point with a diffuse lobe casts cosine-weighted occlusion
rays toward the world each frame (4 where the sky gave at least a tenth of
the light around the pixel last frame, else one in half of the frames:
point_plan): diffuse x L_world(wi) x V(wi) averaged over them is the
diffuse lobe's world light, without bias (f cos / pdf of a Lambert lobe
under cosine sampling is its colour). The world's
share that the points' NEE already takes (an HDRI's bright regions:
initial.world_share) is left out, as for the sky samples this replaces. On
a still view a pixel's rays follow its own Sobol points over the frames of
its stream (aligned runs of ``count`` points per frame), so a still's mean
of frames covers the hemisphere evenly. Occlusion rays are the cheapest
query (no hit record, no shading at the far end).
"""

import numpy as np

from ..sampling import samplers
from ..lights.analytic import INF_DIST
from ..integrators.base import shadow_rays
from ..util.rows import gather, row_max, scale, scatter
from ..util.vectors import dot, to_world
from ..util.windows import window_sums
from ..sampling.warps import square_to_cosine_hemisphere
from .initial import world_share

SKY_SAMPLE = 0x5C1E5        # key of each pixel's scrambles of its sky ray sequence
SKY_SHARE_MIN = 0.1         # below this share of a pixel's light last frame, fewer sky rays
SHARE_RADIUS = 4            # pixels around each whose sky share decides its rays (pixel_shares)
SKY_KEEP_MIN = 0.5          # the least share of frames in which a point casts a sky ray (fewer
                            # left the sky's light noisier than without sky rays)
_GOLDEN = 0.6180339887498949
SKY_DIM = 7                 # a bounce-0 dimension no other decision reads (hashed uniforms)


def sky_directions(keys, counts, run, stream_index=None, seeds=None):
    """(sum(counts), 2) uniforms for counts[i] rays of row i, row after row:
    with stream_index, points stream_index * run + k (k < counts[i] <= run)
    of each row's Sobol points (keys (N,) uint64 per row); else hashed from
    seeds (N,) uint64."""
    k = np.arange(counts.sum(), dtype=np.int64) - np.repeat(np.cumsum(counts) - counts, counts)
    if stream_index is not None:
        bits = np.repeat(samplers.scrambles(keys, 0, 3), counts, axis=0)
        index = samplers.shuffled_index(stream_index * run + k, bits[:, 2])
        return samplers.sobol(index, bits[:, :2], samplers.SOBOL_CAMERA)
    own = samplers.hash_keys(np.repeat(seeds, counts), k)
    return samplers.uniform2(own, samplers.bounce_dim(0, SKY_DIM))


def sky_light(ctx, surf, frame, count, keys=None, stream_index=None, seeds=None, run=None):
    """(N, 3) the world's light reflected by the diffuse lobe of surface
    points ``surf`` (shading frame ``frame``) toward their viewers, from
    ``count`` occlusion rays each (an integer, or (N,) integers of at most
    ``run``, by default max(count): the length of each pixel's Sobol run
    per stream index; see sky_directions for keys, stream_index and
    seeds). Zeros without a world or where count is 0."""
    n = len(surf)
    out = np.zeros((n, 3), np.float32)
    lights = ctx.lights
    counts = np.broadcast_to(np.asarray(count, np.int64), (n,))
    if n == 0 or lights.environment is None or counts.max(initial=0) <= 0:
        return out
    run = int(counts.max()) if run is None else run
    diffuse = frame.params.diffuse
    rows = np.nonzero((row_max(diffuse) > 0) & (counts > 0))[0]
    if len(rows) == 0:
        return out
    per = counts[rows]
    u = sky_directions(None if keys is None else keys[rows], per, run, stream_index,
                       None if seeds is None else seeds[rows])
    rep = np.repeat(rows, per)
    local = square_to_cosine_hemisphere(u)
    wi = to_world(local, gather(frame.t, rep), gather(frame.b, rep), gather(surf.ns, rep)).astype(np.float32)
    ng = gather(surf.ng, rep)
    # Only directions on the side of the surface the lobe faces (shading and
    # geometric normals can disagree near silhouettes of smooth meshes).
    up = dot(wi, ng) > 0
    radiance = scale(lights.world_radiance(wi), (1.0 - world_share(lights, wi)) * up / np.repeat(per, per))
    live = np.nonzero(row_max(radiance) > 0)[0]
    if len(live) == 0:
        return out
    blocked = ctx.accel.occluded(*shadow_rays(ctx, gather(surf.p, rep[live]), gather(ng, live), gather(wi, live),
                                              np.full(len(live), INF_DIST, np.float32)))
    open_ = live[~blocked]
    for c in range(3):
        out[:, c] = np.bincount(rep[open_], weights=radiance[open_, c], minlength=n)
    out *= diffuse
    return out


def point_plan(sky_samples, share):
    """(rays (N,), share of frames they are cast in (N,)) for points whose
    sky rays gave ``share`` (N,) of their light last frame (NaN: no
    history; pixel_shares). Where the sky lights a point (an open
    courtyard) it casts ``sky_samples`` each frame; where it gives little
    (a closed room under a world, a dim world) the point casts one ray in
    a share of the frames, in proportion down to SKY_KEEP_MIN, weighted by
    the inverse of that share (Russian roulette: unbiased, and the sky's
    light is too small a part there for its added noise to show). Taken
    per point: a room's world gave 0.4 % of its image's direct light but
    more beside its window, where one ray in a sixteenth of the frames for
    the whole image put that light in noise (room still +10 % MSE). The
    plan never depends on this frame's own sky rays, so each frame's
    estimate stays unbiased."""
    share = np.asarray(share, np.float32)
    if sky_samples <= 0:
        return np.zeros(share.shape, np.int64), np.zeros(share.shape, np.float32)
    full = ~(share < SKY_SHARE_MIN)        # NaN: no history, all rays
    counts = np.where(full, sky_samples, 1)
    keep = np.where(full, 1.0, np.maximum(np.nan_to_num(share) / SKY_SHARE_MIN, SKY_KEEP_MIN))
    return counts, keep.astype(np.float32)


def visible_sky_light(ctx, gb, seed, frame, seeds, plan, run, stream_indices):
    """(len(gb.index), 3) the sky light of the visible points of G-buffer
    range gb, averaged over one estimate per entry of stream_indices (each
    the point of the pixels' Sobol sequences, keyed by seed and pixel, or
    None for rays hashed from ``seeds``, the visible points' path seeds),
    with ``plan`` = point_plan(...) of those points and ``run`` the largest
    count of any frame (the pixels' Sobol runs). A point casts in a share
    ``keep`` of the frames where frac(pixel x golden ratio + r) < keep, r
    random per frame: each pixel with that probability, spread evenly."""
    counts, keep = plan
    out = np.zeros((len(gb.index), 3), np.float32)
    if run <= 0 or len(gb.index) == 0 or ctx.lights.environment is None:
        return out
    pixels = gb.ids(gb.index)
    r = float(samplers.uniform(samplers.hash_keys(seed, frame, SKY_SAMPLE), 0))
    cast = (counts > 0) & ((keep >= 1.0) | (np.modf(pixels * _GOLDEN + r)[0] < keep))
    rows = None if cast.all() else np.nonzero(cast)[0]
    if rows is not None:
        if len(rows) == 0:
            return out
        pixels, counts, keep, seeds = pixels[rows], counts[rows], keep[rows], seeds[rows]
    surf = gb.surf if rows is None else gb.surf.subset(rows)
    sh = gb.frame if rows is None else gb.frame.subset(rows)
    keys = samplers.hash_keys(seed, pixels, SKY_SAMPLE) \
        if any(i is not None for i in stream_indices) else None
    total = np.zeros((len(pixels), 3), np.float32)
    for s, index in enumerate(stream_indices):
        total += sky_light(ctx, surf, sh, counts, keys=keys, stream_index=index, run=run,
                           seeds=None if index is not None else samplers.hash_keys(seeds, SKY_SAMPLE, s))
    total = scale(total, 1.0 / (keep * len(stream_indices))).astype(np.float32)
    return total if rows is None else scatter(out, rows, total)


def pixel_shares(sky, light, width, height, radius=SHARE_RADIUS):
    """(P,) float16 the sky rays' share of each pixel's light, over the
    (2 radius + 1)^2 pixels around it (sky and light (P,) luminances; the
    light all of it, not its direct part: in a room lit indirectly the sky
    through a window was all of most walls' direct light):
    one pixel's share from four rays is noise (all blocked in one frame
    put it at 0 and its next frame at one ray weighted 16), and the sky's
    openness changes slowly across the image."""
    d = window_sums(light, width, height, radius, mode="edge")
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(d > 0, window_sums(sky, width, height, radius, mode="edge") / d, 0.0)
    return share.reshape(-1).astype(np.float16)
