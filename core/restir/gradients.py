"""Temporal gradients: where the light changed since last frame, so that the
history forgets only there (A-SVGF, Schied et al. 2018).

When objects move, the light of the surfaces around them changes (their
shadows, the light they reflect, what they hide) while the rest of the image
stays as it was. Without a measure of where, the reservoirs kept their full
history everywhere (a floor next to a box sliding into the sun got half of
the light the box now reflects onto it, the frame 5 % dark) and every
pixel's running mean dropped to MOVING_CAP frames (moved_history.py): the whole
image as noisy as after a cut for as long as anything moved.

A-SVGF's gradient re-shades some of last frame's samples, with their own
random numbers, in the new scene: where nothing changed the result is the
same to the bit, where the light changed it differs by the change. Here,
one pixel per STRATUM x STRATUM block of last frame's image has its camera
ray (last frame's camera and pixel filter offset) and its first initial
sample (the BSDF direction and the path from the point it hits) drawn again
with last frame's frame number and stream index (a pixel whose point lay
on an object that moved has its ray aimed at where that point went, A-SVGF's
forward projection, so a moving object's own light is measured too); the
sample's weight (initial.py: luminance of its radiance times the cosine
over its pdf) is compared with the one last frame stored
(FrameHistory.sample_value). The direct light is left out (light_probes.py
measures it): a moving shadow has the running means' gate
(accumulation.light_range), and its estimate takes as many light samples
as each pixel's noise asks for, which would differ.

The single values are noisy, so as in A-SVGF they are summed over a window
before the ratio is taken:

    lambda = sum |new - old| / sum max(new, old)

0 where nothing changed, 1 where the light was replaced. The running mean's
weight of the new frame becomes A-SVGF's

    alpha' = lambda + (1 - lambda) / cap,

so a history keeps at most 1 / alpha' - 1 frames (history_frames), and a
reservoir the same share of its M cap (kept_share).
"""

import copy

import numpy as np

from ..sampling import samplers
from ..util.rows import gather
from ..util.windows import window_sums
from .gbuffer import trace_rows
from .initial import initial_samples

STRATUM = 3             # one re-drawn sample per STRATUM x STRATUM pixels
RADIUS = 5              # window half-size (pixels) of the sums: about 13 re-drawn samples
GRADIENT_PIXELS = 0x6AD1    # random-number domain of the strata's choice of pixel
# lambda is the window's relative change times GAIN: a light that changes by
# a few percent a frame (a box sliding into the sun) gives single sums of
# 0.01-0.05, under which A-SVGF's alpha' keeps nearly the whole history;
# where nothing changed the sums are 0 to the bit, so a high gain costs no
# history there. corpus_movers, still camera, biased + denoiser, frame 32
# MSE with GAIN set to each value (bench/equal_time.py --scenes movers
# --cameras still --modes biased): 0.1383 at 1, 0.1309 at 4, 0.1285 at 10,
# 0.1264 at 30; with the light probes and forward projection, 0.0501 at 10,
# 0.0469 at 30, 0.0422 at 100, 0.0427 at 1000 (moving camera 0.0548 at 10,
# 0.0510 at 30).
GAIN = 100.0
SAME_POINT = 1e-4       # a re-drawn camera ray's hit within this share of its depth of last frame's


def stratum_pixels(width, height, seed, frame):
    """One pixel index per STRATUM x STRATUM block of the image, at a random
    place in its block (new each frame), inside the image."""
    bx = np.arange(0, width, STRATUM, dtype=np.int64)
    by = np.arange(0, height, STRATUM, dtype=np.int64)
    x0, y0 = np.meshgrid(bx, by)
    block = (y0 * width + x0).ravel()
    u = samplers.uniform2(samplers.hash_keys(seed, frame, block + GRADIENT_PIXELS), 0)
    x = np.minimum(x0.ravel() + (u[:, 0] * STRATUM).astype(np.int64), width - 1)
    y = np.minimum(y0.ravel() + (u[:, 1] * STRATUM).astype(np.int64), height - 1)
    return y * width + x


def redrawn_values(ctx, history, seed, pixel_filter, how, stream_index, motion=None):
    """(pixels, old, new, valid): for one pixel per stratum of last frame's
    image, the first initial sample's weight last frame stored and the
    weight the same random numbers give in the current scene, seen through
    last frame's camera. how: initialSampling as last frame drew with
    (its light sample counts do not enter the weight); stream_index: of
    last frame's first sample, or None. motion: temporal.ObjectMotion, or
    None: a pixel whose surface moved has its ray aimed at where its point
    went (A-SVGF's forward projection), so its sample is drawn again there."""
    w, h = history.width, history.height
    pixels = stratum_pixels(w, h, seed, history.frame)
    then = copy.copy(ctx.scene)
    then.camera = history.camera
    view = copy.copy(ctx)
    view.scene = then
    p_then = gather(history.p, pixels)
    aim = moved_points(history, pixels, p_then, motion)

    def part(a, b):         # the strata a..b, on the context's workers
        sub = None
        if aim is not None:
            inside = (aim[0] >= a) & (aim[0] < b)
            sub = (aim[0][inside] - a, aim[1][inside])
        gb = trace_rows(view, seed, history.frame, pixel_filter, True, 0, 0, history.index, pixels=pixels[a:b],
                        aim=sub)
        res, _, _ = initial_samples(view, gb, seed, history.frame, 0, how, stream_index=stream_index)
        p_now = np.zeros((b - a, 3), np.float32)
        p_now[gb.index] = gb.surf.p
        return gb.valid, gb.object_id, p_now, res.w_sum.astype(np.float32)

    seen, object_id, p_now, new = ctx.workers.map_into(part, len(pixels))
    old = gather(history.sample_value, pixels)
    # Only where the camera ray found the surface it found last frame (where
    # it moved to, on a moved object): a pixel that now sees another surface
    # (a moving object's silhouette) tells nothing of the light.
    if aim is not None:
        p_then[aim[0]] = aim[1]
    apart = np.linalg.norm(p_now - p_then, axis=1)
    same = (object_id == gather(history.object_id, pixels)) & \
        (apart <= SAME_POINT * np.maximum(gather(history.depth, pixels), 1e-6))
    valid = seen & gather(history.valid, pixels) & same
    return pixels, old, new, valid


def moved_points(history, pixels, p_then, motion):
    """(rows, points) of the ``pixels`` whose visible point last frame lay on
    an object that moved since, and where those points are now (p_then:
    their points, (N, 3)); None if there are none."""
    if motion is None or motion.to_current is None:
        return None
    moved = p_then.copy()
    rows = motion.carry_forward(gather(history.object_id, pixels), gather(history.valid, pixels), points=(moved,))
    return (rows, moved[rows]) if len(rows) else None


def temporal_gradient(pixels, old, new, valid, width, height, radius=RADIUS, gain=GAIN):
    """lambda (P,) float32 in [0, 1] per pixel of a width x height image:
    the relative change of the light around it (times ``gain``), from the
    values ``old`` and ``new`` of the re-drawn samples at ``pixels`` (where
    ``valid``), summed over windows of half-size ``radius``."""
    ok = valid & np.isfinite(old) & np.isfinite(new)
    at = pixels[ok]
    a = np.maximum(old[ok], 0.0)
    b = np.maximum(new[ok], 0.0)
    diff = np.zeros(width * height)
    top = np.zeros(width * height)
    diff[at] = np.abs(b - a)
    top[at] = np.maximum(a, b)
    num = window_sums(diff, width, height, radius).reshape(-1)
    den = window_sums(top, width, height, radius).reshape(-1)
    lam = np.where(den > 0, gain * num / np.maximum(den, 1e-30), 0.0)
    return np.clip(lam, 0.0, 1.0).astype(np.float32)


def history_frames(lam, cap):
    """Frames of history a running mean of at most ``cap`` frames may keep
    where its light changed by lambda (the new frame then weighs alpha')."""
    alpha = lam + (1.0 - lam) / float(cap)
    return np.maximum(1.0 / alpha - 1.0, 0.0).astype(np.float32)


def kept_share(lam, cap):
    """Share of its history cap a reservoir keeps where the light changed by
    lambda: history_frames over the cap's own (1 at lambda 0, 0 at 1)."""
    return history_frames(lam, cap) / max(float(cap) - 1.0, 1.0)


def cap_reservoirs(res, cap):
    """Bound each row's M by ``cap`` (P,), at least 1, in place. The next
    frame reads the history's W and M only, so a lower M is a history that
    weighs less; one frame's worth stays (emptied reservoirs left blocks of
    the biased mode's frame dark)."""
    np.minimum(res.M, np.maximum(cap, 1.0).astype(np.float32), out=res.M)
