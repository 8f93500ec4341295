"""Ghosts in the running means: history of a surface the pixel no longer sees.

reprojection.previous_pixels keeps a pixel's history when last frame's
sample near its reprojected centre saw the pixel's kind of surface. But a
running mean holds up to ``cap`` frames, and a pixel that sat on an edge a
few frames ago still holds the other side's share in its mean, even if its
last sample (the one the test reads) saw its own surface. Where an edge
sweeps across the image (an object's silhouette against what lies behind it,
with the camera moving), every pixel it leaves behind keeps that share and
lets it fade over ``cap`` frames: a trail behind the edge, the moving view's
edges lagging and blurred (on the corpus's courtyard, moving camera, most of
the direct light's error).

The test here is TAA's neighbourhood clamp (Karis 2014; Salvi 2016) on the
values that do not carry the light's noise: a pixel's mean albedo and mean
normal describe the surfaces its history saw. This frame's samples of the
3x3 pixels around it (each jittered over the pixel filter, so together they
cover the surfaces the pixel's footprint can hold) give a range per channel.
A history mixed over the pixel's footprint lies inside that range; a ghost
lies outside, and its history is kept only in proportion to how far it is
from the range (none beyond the tolerances). A history whose light lies in
the range of this frame's light around the pixel is kept whatever its albedo
says: it shows what the pixel shows now (an emitter's surface, a texture's
detail finer than the 3x3). Light itself is never clamped: the 3x3 range of
one-sample light is mostly noise, and clipping to it darkens
(accumulation.accumulate's notes).

A pixel on an edge keeps the mix of the surfaces its footprint covers, read
where its own surface was last frame (reprojection.previous_pixels). The
other surface moved by another amount on the film (parallax), so its share
in a mean of n frames sits on average (n - 1) / 2 frames' parallax away
from where it belongs: edges lag behind the motion. On edges the history
keeps at most the frames that hold that shift under EDGE_SHIFT pixels.
"""

from dataclasses import dataclass

import numpy as np

from .adaptive_direct import neighbourhood_range

ALBEDO_TOLERANCE = 0.1     # albedo outside the neighbourhood's range by this much: no history kept
NORMAL_TOLERANCE = 0.25    # the same for each component of the mean normal
LIGHT_MARGIN = 0.1         # history light within the 3x3 light range, widened by this share: kept
# Mean shift, in pixels, of the other surface's share on an edge. Corpus,
# moving camera, biased + denoiser, frame 32 (bench/equal_time.py): 0.1 and
# 0.15 gave the courtyard 1.62e-4 (no cap: 1.97e-4), 0.25 1.66e-4, 0.5
# 1.77e-4; a fixed cap of 5 frames on every edge gave it 1.62e-4 too, but
# the emitters' room 0.00277 where no cap and this one give 0.00238.
EDGE_SHIFT = 0.15
EDGE_MIN = 2.0             # frames an edge keeps however fast it moves


@dataclass
class SurfaceRange:
    """Per pixel, the range of this frame's samples over its 3x3
    neighbourhood: albedo 3, normal 3 and light luminance 1 (misses count,
    with albedo and normal 0); ``edges``: reprojection.geometric_edges of the
    same pixels, or None; ``parallax``: parallax() of this frame's motion."""
    lo: np.ndarray      # (N, 7) float32
    hi: np.ndarray      # (N, 7) float32
    edges: np.ndarray = None        # (N,) bool, or None
    parallax: np.ndarray = None     # (N,) float32, pixels per frame (parallax()), or None

    def rows(self, a, b):
        part = lambda x: None if x is None else x[a:b]   # noqa: E731
        return SurfaceRange(self.lo[a:b], self.hi[a:b], part(self.edges), part(self.parallax))


def surface_range(albedo, normal, light, width, height):
    """SurfaceRange of every pixel from this frame's (P, 3) albedo and normal
    samples and (P,) light luminance (whole image, rows first)."""
    lo = np.empty((len(light), 7), np.float32)
    hi = np.empty((len(light), 7), np.float32)
    columns = [albedo[:, c] for c in range(3)] + [normal[:, c] for c in range(3)] + [light]
    for c, v in enumerate(columns):     # one channel at a time: 3x3 passes over 7 interleaved ones are slower
        hi[:, c], lo[:, c] = neighbourhood_range(np.ascontiguousarray(v, np.float32), None, width, height)
    return SurfaceRange(lo, hi)


_TOLERANCE = np.array([ALBEDO_TOLERANCE] * 3 + [NORMAL_TOLERANCE] * 3, np.float32)


def history_share(surface_values, rng, light=None):
    """(N,) float32 in [0, 1]: how much of each history to keep, from its
    mean albedo and normal (N, 6) against this frame's range (SurfaceRange
    of the same rows): 1 inside the range, falling linearly to 0 at the
    tolerance beyond it; 1 where the history's light luminance (N,) lies in
    the light range (widened by LIGHT_MARGIN)."""
    over = np.zeros(len(surface_values), np.float32)
    for c in range(6):      # (column by column: a reduction over 6 columns is slower)
        v = surface_values[:, c]
        np.maximum(over, np.maximum(rng.lo[:, c] - v, v - rng.hi[:, c]) / _TOLERANCE[c], out=over)
    share = np.clip(1.0 - over, 0.0, 1.0).astype(np.float32)
    if light is not None:
        inside = (light >= rng.lo[:, 6] * (1 - LIGHT_MARGIN)) & (light <= rng.hi[:, 6] * (1 + LIGHT_MARGIN))
        share[inside] = 1.0
    return share


def parallax(shift, width):
    """(P,) float32: per pixel of the image, the largest difference between
    its film motion ``shift`` (P, 2, pixels; rows first) and that of its
    neighbours (left, right, above, below and diagonal)."""
    sx = np.ascontiguousarray(shift[:, 0]).reshape(-1, width)
    sy = np.ascontiguousarray(shift[:, 1]).reshape(-1, width)
    out = np.zeros(sx.shape, np.float32)
    # each pair of neighbours once: right, below, below right, below left
    for (ay, ax), (by, bx) in (((slice(None), slice(0, -1)), (slice(None), slice(1, None))),
                               ((slice(0, -1), slice(None)), (slice(1, None), slice(None))),
                               ((slice(0, -1), slice(0, -1)), (slice(1, None), slice(1, None))),
                               ((slice(0, -1), slice(1, None)), (slice(1, None), slice(0, -1)))):
        d = np.fmax(np.abs(sx[ay, ax] - sx[by, bx]), np.abs(sy[ay, ax] - sy[by, bx]))
        np.fmax(out[ay, ax], d, out=out[ay, ax])     # (fmax: a motion that is not a number counts as none)
        np.fmax(out[by, bx], d, out=out[by, bx])
    return out.ravel()


def kept_frames(frames, surface_values, rng, light=None):
    """(N,) float32: frames of history the light columns of rows keep, from
    the frames they hold, their mean albedo and normal (N, 6), this frame's
    SurfaceRange of the rows and the history's light luminance (N,):
    history_share of them, and on edges at most the frames of an EDGE_SHIFT
    lag at the rows' parallax."""
    out = frames * history_share(surface_values, rng, light)
    if rng.edges is not None and rng.parallax is not None:
        lag = np.maximum(1.0 + 2.0 * EDGE_SHIFT / np.maximum(rng.parallax, 1e-6), EDGE_MIN)
        out = np.where(rng.edges, np.minimum(out, lag), out)
    return out.astype(np.float32)
