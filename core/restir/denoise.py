"""A denoiser for the running means: spatiotemporal variance-guided filtering
(SVGF, Schied et al. 2017) of the demodulated indirect light.

The running means (accumulation.py) are SVGF's temporal stage: each pixel's
light averaged over its reprojected history, restarted at disocclusions.
With ``ReSTIRSettings.denoise`` they also carry the first and second moments
of the luminance of each frame's demodulated indirect light (MOMENTS columns after
accumulation.COLUMNS), blended as the other columns are, so their spread is
the light's variance over the pixel's history. Here:

1. Demodulation: the indirect light of the visible point (both lobes)
   divided by the albedo pass, each channel at least ALBEDO_MIN. Texture
   then leaves the signal the filter blurs and comes back whole when the
   filtered light is multiplied by the albedo again. A pixel whose light
   is over FIREFLY_RATIO x its brightest neighbour's is brought down to
   that (firefly_factor): a lone bright mean the luminance weights would
   keep as it is. The direct light and
   the radiance seen directly (emitters, the world) are not filtered: their
   running means are already clean (adaptive shadow rays, edge samples),
   and what varies from frame to frame in them is mostly the pixel filter's
   jitter over sharp shadow and light edges, whose variance let the filter
   blur a sunlit patch into the floor around it. On the corpus room (frame
   32, biased, against Cycles at 1024 spp) filtering direct + indirect
   light raised the MSE from 0.0050 to 0.0117 (still camera) and 0.0054 to
   0.0106 (moving); the indirect light alone lowers it to 0.0034 and 0.0047.
2. Variance of each pixel's mean: the moments' variance over its history
   divided by the frames it holds; where the history is shorter than
   SHORT_HISTORY frames (first frames, disocclusions) from the moments of
   the 7x7 pixels around it that see the same surface (depth, normals).
3. Five iterations of an edge-avoiding a-trous wavelet filter
   (edge_filter.py): B3 spline taps (5x5) at steps 1, 2, 4, 8 and 16
   pixels, each tap weighted by depth (against the screen-space depth
   gradient), normals (power 128) and luminance (against the square root of
   the 3x3-blurred variance); the variance is filtered along (squared
   weights), so each iteration blurs less than the one before. A pixel of
   short history has a large variance, and is blurred more. The first
   iteration compares luminance blurred over each pixel's 3x3 surface
   (edge_filter.surface_blur): against each pixel's own, a bright pixel's
   neighbours gave it little weight and the filter darkened skewed noise.
4. Where the history is short, the filtered light's local energy brought
   back to the unfiltered means' (kept_energy). Remodulation by the
   albedo, plus the direct light and the radiance seen directly (where
   the direct light's history just restarted at its edges, the frame took
   more camera rays for it: edge_direct.py).

Every step is a whole-image pass over pixel ranges (core/workers/parallel.py). A
range computes the image rows it touches; the taps read neighbouring rows
from the whole-image arrays of the step before, so the image does not depend
on how the pixels are split.

Lag: the filter adds none of its own (it reads only this frame's means); the
running means' history is what lags, and it restarts where accumulation.py
restarts it (disocclusions, edits of lights and materials, the gate on
moving objects' shadows), the restarted pixels then blurred more; where
objects moved, A-SVGF's temporal gradients (gradients.py) decide how much of
the indirect light's history each pixel keeps.
"""

import numpy as np

from ..util.vectors import luminance
from ..util.windows import window_sums
from .accumulation import COLUMNS
from .adaptive_direct import neighbourhood_range
from .edge_filter import Image, atrous, depth_gradient, surface_blur, variance

MOMENTS = 2                 # columns of the running means: mean luminance of the
                            # demodulated light, and mean of its square
ALBEDO_MIN = 0.01           # albedo each channel is demodulated by at least
LIGHT_MAX = 1e15            # demodulated light is clipped to [0, LIGHT_MAX] (its square fits float32)
DEPTH_MAX = 1e9             # depths are clipped to this (misses hold 1e10; no surface is farther)
ITERATIONS = 5              # a-trous steps 1, 2, 4, 8, 16
# The filter loses energy where histories are short (the luminance weights
# give skewed noise's bright pixels little weight): corpus_movers, still
# camera, frame 32, the filtered indirect light's mean was 0.946 of the
# unfiltered means' in the moving frame (0.976 with the box held). Pixels
# whose history holds fewer than SHORT_HISTORY_ENERGY frames have it given
# back over their window (kept_energy): MSE 0.0422 -> 0.0350, mean ratio
# 0.970 -> 0.981 (moving camera 0.0464 -> 0.0376); the corpus room and slit
# room with the camera moving unchanged (0.00407, 0.1417; with the energy
# given back at every pixel the room's rose to 0.00412).
SHORT_HISTORY_ENERGY = 8.0
ENERGY_RADIUS = 8           # window half-size (pixels) of the energy's sums
ENERGY_RANGE = (0.8, 1.25)  # the factor is kept within this range
# A pixel's mean at most this x the brightest of its neighbours' (0: off),
# at any history length: the glossy interior's metal panels keep lone bright
# means for many frames (one glossy path per frame). Clamped only where
# histories are short (under SHORT_HISTORY_ENERGY), the glossy still (frame
# 32, biased, against Cycles at 1024 spp, whose own noise is 0.00066 of it)
# had MSE 0.001238; at every pixel 0.001184. The other corpus scenes moved
# by under 0.2 % (room 0.004070 -> 0.004065, corpus_movers still camera
# 0.02025 -> 0.02022, courtyard 0.0001423 -> 0.0001422, slit room and
# emitters unchanged). Giving the energy back at every pixel as well
# (kept_energy over the window) made the room worse (0.00412).
FIREFLY_RATIO = 2.0
M1, M2 = COLUMNS, COLUMNS + 1  # the moments' columns


def demodulated(light, albedo):
    """(N, 3) float32: light (N, 3) divided by albedo (N, 3), each channel by
    at least ALBEDO_MIN; non-finite light counts as 0, and the result lies
    in [0, LIGHT_MAX]."""
    light = np.nan_to_num(np.asarray(light, np.float32), nan=0.0, posinf=LIGHT_MAX, neginf=0.0)
    out = light / _clip_albedo(albedo)
    return np.clip(out, 0.0, LIGHT_MAX, out=out).astype(np.float32, copy=False)


def frame_moments(indirect, albedo):
    """(N, MOMENTS) float32: this frame's luminance of the demodulated
    indirect light and its square, the values accumulation.accumulate averages."""
    lum = luminance(demodulated(indirect, albedo)).astype(np.float32)
    return np.stack([lum, lum * lum], axis=1)


def denoise(workers, data, depth, valid, width, height, iterations=ITERATIONS, timed=None, poll=None):
    """(P, 3) float32: the filtered image of the running means ``data`` (P,
    accumulation.COLUMNS + MOMENTS), from this frame's view depth (P,) and
    valid (P,) bool. Pixels that see no surface this frame (or that valid
    leaves out) keep their means. timed: a context manager factory called
    around each range's work (the frame's timings), or None; poll: called
    before every pass (Accel.poll: where an interruptible frame, the
    viewport's, may be abandoned), or None."""
    n = width * height
    if n == 0:
        return np.zeros((0, 3), np.float32)
    cols = data.shape[1]
    if cols < COLUMNS + MOMENTS:
        raise ValueError(f"the running means hold {cols} columns: no moments (ReSTIRSettings.denoise)")
    shape = (height, width)

    def run(fn):
        if poll is not None:
            poll()

        def part(a, b):
            if timed is None:
                return fn(a, b)
            with timed():
                return fn(a, b)
        return part

    # 1. Pointwise: demodulated light, its luminance, unit normals (zero where
    # no surface is seen: every tap to such a pixel then weighs 0), depth.
    def prepare(a, b):
        rows = data[a:b]
        c = demodulated(_finite(rows[:, 3:6]), _albedo(rows))
        ok = valid[a:b]
        nrm = np.clip(np.nan_to_num(rows[:, 9:12], nan=0.0, posinf=0.0, neginf=0.0), -1e6, 1e6)
        length = np.sqrt(nrm[:, 0] * nrm[:, 0] + nrm[:, 1] * nrm[:, 1] + nrm[:, 2] * nrm[:, 2])
        inv = np.where(ok & (length > 1e-6), 1.0 / np.maximum(length, 1e-6), 0.0).astype(np.float32)
        zr = np.nan_to_num(np.asarray(depth[a:b], np.float32), nan=0.0, posinf=0.0, neginf=0.0)
        zr = np.where(inv > 0, np.clip(zr, -DEPTH_MAX, DEPTH_MAX), np.float32(0)).astype(np.float32)
        m1, m2 = _moments(rows)
        count = np.clip(np.nan_to_num(rows[:, 12], nan=1.0), 1.0 / 64, 1e9).astype(np.float32)
        lengths = np.where(inv > 0, length, 0.0).astype(np.float32)    # of the mean normals (edge_filter)
        return (c[:, 0].copy(), c[:, 1].copy(), c[:, 2].copy(), luminance(c).astype(np.float32),
                nrm[:, 0] * inv, nrm[:, 1] * inv, nrm[:, 2] * inv, zr, m1, m2, count, lengths)

    red, green, blue, lum, nx, ny, nz, z, m1, m2, count, lengths = workers.map_into(run(prepare), n)
    lengths = lengths.reshape(shape)
    frames = count
    raw = lum
    if FIREFLY_RATIO > 0 and iterations:       # (no filter: the means as they are)
        def clamp(a, b):
            r0, r1 = a // width, (b - 1) // width + 1
            lo, hi = a - r0 * width, b - r0 * width
            k = firefly_factor(lum, valid, width, height, r0, r1)[lo:hi]
            return red[a:b] * k, green[a:b] * k, blue[a:b] * k, lum[a:b] * k

        red, green, blue, lum = workers.map_into(run(clamp), n)
    nimg = np.stack([nx, ny, nz]).reshape(3, *shape)
    zimg = z.reshape(shape)
    moments = [m1.reshape(shape), m2.reshape(shape), count.reshape(shape)]
    del m1, m2, count

    # 2. Depth gradient, variance, and the luminance the first iteration
    # compares (neighbouring rows: 3x3 and 7x7 windows).
    def spread(a, b):
        r0, r1 = a // width, (b - 1) // width + 1
        lo, hi = a - r0 * width, b - r0 * width
        grad_x, grad_y = depth_gradient(zimg, nimg, r0, r1)
        guide = surface_blur(lum.reshape(shape), zimg, nimg, grad_x, grad_y, r0, r1)
        return (variance(*moments, zimg, nimg, grad_x, grad_y, r0, r1)[lo:hi],
                grad_x.ravel()[lo:hi], grad_y.ravel()[lo:hi], guide.ravel()[lo:hi])

    var, gx, gy, guide = workers.map_into(run(spread), n)
    moments.clear()     # (freed before the iterations)
    img = Image(red, green, blue, lum, var, guide)
    gimg = (gx.reshape(shape), gy.reshape(shape))

    # 3. The a-trous iterations.
    for i in range(iterations):
        step = 1 << i
        last = i == iterations - 1

        def iteration(a, b, img=img, step=step, last=last):
            r0, r1 = a // width, (b - 1) // width + 1
            out = atrous(img, zimg, nimg, gimg, r0, r1, step, need_var=not last, lengths=lengths)
            lo, hi = a - r0 * width, b - r0 * width
            return tuple(x.ravel()[lo:hi] for x in (out[:3] if last else out))

        if not last:
            img = Image(*workers.map_into(run(iteration), n))
        else:
            red, green, blue = workers.map_into(run(iteration), n)
            img = None

    # 4. The energy short histories lost, and remodulation.
    def finish(a, b):
        r0, r1 = a // width, (b - 1) // width + 1
        lo, hi = a - r0 * width, b - r0 * width
        c = np.stack([red[a:b], green[a:b], blue[a:b]], axis=1)
        if iterations:
            c *= kept_energy(raw, (red, green, blue), frames, valid, width, height, r0, r1)[lo:hi, None]
        return remodulate(c, data[a:b], valid[a:b])

    return workers.map_into(run(finish), n)


def firefly_factor(lum, valid, width, height, r0, r1):
    """(rows r0..r1 of the image x width,) float32: the factor that brings
    the demodulated light of a pixel down to FIREFLY_RATIO x the brightest
    of its 8 neighbours that see a surface (1 elsewhere). lum, valid: (P,)
    of the whole image."""
    a0, a1 = max(r0 - 1, 0), min(r1 + 1, height)
    rows = slice(a0 * width, a1 * width)
    mx, _ = neighbourhood_range(lum[rows], valid[rows], width, a1 - a0, centre=False)
    own = slice((r0 - a0) * width, (r1 - a0) * width)
    mx, x = mx[own], lum[r0 * width:r1 * width]
    cut = FIREFLY_RATIO * np.maximum(mx, 0.0)
    hot = valid[r0 * width:r1 * width] & np.isfinite(mx) & (x > cut)
    factor = np.ones(len(x), np.float32)
    factor[hot] = cut[hot] / x[hot]
    return factor


def kept_energy(raw, filtered, frames, valid, width, height, r0, r1):
    """(rows r0..r1 of the image x width,) float32: the factor that gives
    the filtered demodulated light back the energy of the unfiltered one
    over each pixel's window of ENERGY_RADIUS, where the pixel's history is
    shorter than SHORT_HISTORY_ENERGY frames (1 elsewhere), within
    ENERGY_RANGE. raw (P,): the unfiltered light's luminance; filtered:
    (red, green, blue) (P,) each; frames (P,): the frames the means hold."""
    r = ENERGY_RADIUS
    a0, a1 = max(r0 - r, 0), min(r1 + r, height)
    rows = slice(a0 * width, a1 * width)
    seen = valid[rows]
    lum = luminance(np.stack([filtered[0][rows], filtered[1][rows], filtered[2][rows]], axis=1))
    num = window_sums(np.where(seen, raw[rows], 0.0), width, a1 - a0, r)[r0 - a0:r1 - a0].ravel()
    den = window_sums(np.where(seen, lum, 0.0), width, a1 - a0, r)[r0 - a0:r1 - a0].ravel()
    with np.errstate(invalid="ignore", divide="ignore"):
        factor = np.where(den > 0, num / np.maximum(den, 1e-30), 1.0)
    factor = np.clip(np.nan_to_num(factor, nan=1.0), *ENERGY_RANGE)
    own = slice(r0 * width, r1 * width)
    short = valid[own] & (frames[own] < SHORT_HISTORY_ENERGY)
    return np.where(short, factor, 1.0).astype(np.float32)


def _clip_albedo(albedo):
    """Albedo as the light is demodulated by: each channel in [ALBEDO_MIN, 1]."""
    return np.clip(np.nan_to_num(np.asarray(albedo, np.float32), nan=0.0), ALBEDO_MIN, 1.0)


def _albedo(rows):
    return _clip_albedo(rows[:, 6:9])


def remodulate(c, rows, valid):
    """(N, 3) float32 colour of filtered demodulated indirect light c (N, 3)
    for the running means' rows (N, columns): c times the albedo plus the
    direct light and the radiance seen directly; rows that see no surface
    keep their means."""
    out = np.where(valid[:, None], c * _albedo(rows), _finite(rows[:, 3:6]))
    out += _finite(rows[:, 0:3])
    out += _finite(rows[:, 14:17])
    return out.astype(np.float32, copy=False)


def _finite(x):
    """x with non-finite values replaced, in [0, LIGHT_MAX]."""
    return np.clip(np.nan_to_num(x, nan=0.0, posinf=LIGHT_MAX, neginf=0.0), 0.0, LIGHT_MAX)


def _moments(rows):
    """The moments' columns of rows of the running means, finite and in range."""
    m1 = np.clip(np.nan_to_num(rows[:, M1], nan=0.0, posinf=LIGHT_MAX), 0.0, LIGHT_MAX)
    m2 = np.clip(np.nan_to_num(rows[:, M2], nan=0.0, posinf=LIGHT_MAX * LIGHT_MAX), 0.0, LIGHT_MAX * LIGHT_MAX)
    return m1.astype(np.float32), m2.astype(np.float32)
