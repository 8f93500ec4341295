"""Reprojected accumulation of the shaded frames: the static part of the image.

The reservoirs reuse indirect-light samples, but every frame still takes one
camera sample per pixel: primary visibility (anti-aliasing over the pixel
filter), the direct light of the visible point and the final shading are new
each frame. On a still or slowly moving view that noise averages away if
each pixel keeps a running mean of what it showed over the last frames.

Each pixel reads its history where it was last frame
(reprojection.previous_pixels: a Footprint of taps and weights, none where
the pixel was disoccluded and starts over). The mean is over at most
``cap`` frames (an exponential average once full), so light that changes
shows after about
``cap`` frames; the caller restarts every pixel when lights, materials or
the world change, and keeps a few frames where objects moved.

On a moving view, the direct light, the radiance seen directly and what
describes the surface (albedo, normal, alpha) keep a frame count of their
own: ghosts.kept_frames shortens it where the history saw a surface the
pixel no longer covers, or where an edge's surfaces move apart on the film.
The indirect light keeps the full count: the denoiser filters it, and needs
its history (see LIGHT_GROUP).
"""

from dataclasses import dataclass

import numpy as np

from ..util.rows import gather
from ..util.vectors import luminance
from .adaptive_direct import neighbourhood_range
from .ghosts import kept_frames

STILL = 1 << 30             # cap for a still image: the plain mean of every frame


COLUMNS = 18        # direct 3, indirect 3, albedo 3, normal 3, count 1, alpha 1, seen 3, light frames 1
LIGHT_FRAMES = 17   # frames in the mean of the light group's columns
# Column ranges of the two groups. The indirect light (and the denoiser's
# moments, after COLUMNS) hold ``count`` frames; the direct light, the
# radiance seen directly and what describes the surface (albedo, normal,
# alpha) hold LIGHT_FRAMES frames, which ghosts.kept_frames cuts where the
# history saw another surface. (Cutting the indirect light's too left the
# denoiser shorter histories to blur: corpus room, moving camera, +7 % MSE.)
LIGHT_GROUP = ((0, 3), (6, 12), (13, 17))
INDIRECT_GROUP = ((3, 6), (COLUMNS, None))

# Where objects moved, a pixel starts over when this frame's direct light in
# its 3x3 neighbourhood agrees within this share and its history lies outside
# that range by more than this share (accumulate's ``light_range``).
GATE_RELATIVE = 0.1


@dataclass
class Accumulation:
    """Running means per pixel (full-image rows) and the frames each holds,
    packed in one (P, COLUMNS) array so a history read is one gather per tap."""
    data: np.ndarray        # (P, COLUMNS) float32: direct light, indirect, albedo, normal, count,
                            # alpha, seen directly (and with the denoiser, its moments after them)

    @property
    def direct(self):
        """Radiance seen directly plus the direct light (a new array)."""
        return self.data[:, 0:3] + self.data[:, 14:17]

    @property
    def seen(self):
        """Radiance seen directly (emitters, visible lamps, the world)."""
        return self.data[:, 14:17]

    @property
    def indirect(self):
        return self.data[:, 3:6]

    @property
    def albedo(self):
        return self.data[:, 6:9]

    @property
    def normal(self):
        """Mean of the shading normals (not renormalised)."""
        return self.data[:, 9:12]

    @property
    def count(self):
        """Frames in the mean (fractional after interpolated reads)."""
        return self.data[:, 12]

    @property
    def alpha(self):
        """Mean coverage by geometry (Film > Transparent's alpha)."""
        return self.data[:, 13]

    @property
    def moments(self):
        """The columns after COLUMNS (the denoiser's moments), or None."""
        return self.data[:, COLUMNS:] if self.data.shape[1] > COLUMNS else None

    @property
    def nbytes(self):
        return self.data.nbytes


@dataclass
class FrameValues:
    """What one frame adds to the running means of N rows (accumulate)."""
    direct: np.ndarray              # (N, 3) direct light of the visible point
    indirect: np.ndarray            # (N, 3)
    albedo: np.ndarray              # (N, 3)
    normal: np.ndarray              # (N, 3) shading normal
    alpha: object = 1.0             # (N,) coverage by geometry, or a scalar
    seen: object = 0.0              # (N, 3) radiance seen directly, or a scalar
    weight: float = 1.0             # this frame's weight in the mean, in frames
    moments: np.ndarray = None      # (N, k) further values averaged alike (the
                                    # denoiser's, denoise.frame_moments), or None

    def rows(self):
        """The values as Accumulation rows, count = weight."""
        extra = 0 if self.moments is None else self.moments.shape[1]
        new = np.empty((len(self.direct), COLUMNS + extra), np.float32)
        new[:, 0:3], new[:, 3:6], new[:, 6:9], new[:, 9:12] = self.direct, self.indirect, self.albedo, self.normal
        new[:, 12] = self.weight
        new[:, 13] = self.alpha
        new[:, 14:17] = self.seen
        new[:, LIGHT_FRAMES] = self.weight
        if self.moments is not None:
            new[:, COLUMNS:] = self.moments
        return new


def accumulate(prev, footprint, values, cap, refined=None, direct_range=None, surface=None):
    """This frame's Accumulation: the history over ``footprint`` (rows of the
    part) blended with this frame's ``values`` (FrameValues), over at most
    ``cap`` frames. prev: last frame's Accumulation (whole image) or None;
    with moments in values, prev holds them too.

    refined: silhouettes.RefinedSeen of the part's rows, or None. The
    radiance seen directly (seen) of its ``own`` pixels (the brightest
    silhouettes, which take several camera rays) keeps a history only where the
    footprint is exact (a still view); elsewhere it is this frame's: a
    history read between pixels mixes a small bright emitter with what lies
    beside it, and on the corpus's room of small emitters, with a moving
    camera, the emitters' pixels came out 5-7 % dark and held most of the
    error. Off a still view the history of the other pixels' radiance seen
    directly is held under ``refined.ceiling``: a refined pixel holds part
    of an emitter under another object's id, which the trail test of
    previous_pixels cannot see.

    direct_range: DirectRange of the part's rows (light_range below), given
    when objects moved. Pixels whose neighbourhood agrees (spans under GATE_RELATIVE of
    its top) and whose history lies away from it start over. A moving
    object's shadow changes the light of surfaces that stay put, whose
    history the footprint keeps: with MOVING_CAP frames of it, the floor
    under the quick-start example's sliding box stayed lit where its shadow
    had arrived. A test of each pixel against its own history's spread
    instead left stripes (neighbours whose histories were already mixed kept
    them), and clipping every history to the neighbourhood's range darkens
    noisy direct light (many lights: the range of nine one-sample pixels
    often lies below their mean); a neighbourhood that agrees is neither.

    surface: ghosts.SurfaceRange of the part's rows, or None. On a moving
    view a history whose mean albedo and normal lie outside this frame's
    range around the pixel is a ghost of a surface it no longer sees, and
    is kept only in part (ghosts.history_share)."""
    new = values.rows()
    weight = values.weight
    if prev is None or cap <= 1 or footprint is None:
        return Accumulation(new)
    wts = footprint.weights
    hist = lo = hi = None
    # A still view reads each pixel's own history (one tap of weight one).
    columns = [0] if footprint.exact else range(wts.shape[1])
    for k in columns:
        weighted = bool(wts[:, k].any())         # (skipping zero taps adds nothing)
        bounds = footprint.window and k < 4      # the inner 2x2, for the clip below
        if not (weighted or bounds):
            continue
        v = gather(prev.data, footprint.taps[:, k])
        if bounds:
            lo = v.copy() if lo is None else np.minimum(lo, v, out=lo)
            hi = v.copy() if hi is None else np.maximum(hi, v, out=hi)
        if weighted:
            v *= wts[:, k, None]
            hist = v if hist is None else np.add(hist, v, out=hist)
    if not footprint.window:    # a still view (each pixel's own history), or given taps
        if hist is None:
            return Accumulation(new)
    else:
        # A moving view: every row is clipped to the range of its inner 2x2
        # taps. Reads through Catmull-Rom's outer taps overshoot at edges
        # (its negative lobes), and rows whose taps were all rejected
        # (disocclusions, trails of moving objects: zero weights) take the
        # lower end of that range (the darkest history around where they
        # were) instead of starting over, which left black speckle behind the
        # quick start's sliding box (bench/quick_start.py: black 0.31 and
        # 0.44 % of frames 12 and 24 against 0.63 and 0.91). Decided per row:
        # a row must not depend on the other rows of its pass's range
        # (core/workers/parallel.py); the clip was applied to a whole range when any
        # of its rows read outer taps, so images differed with the workers.
        if hist is None:
            hist = np.zeros_like(new)
        np.clip(hist, lo, hi, out=hist)
        # Rows whose centre lay outside last frame's image start over: their
        # taps, clamped to its border, saw another part of the scene. (A pan's
        # uncovered sky took the wall's history at the border and carried it
        # for 16 frames: a translucent wall trailing the motion, the panned
        # frame 9 % too bright.)
        if footprint.inside is not None:
            out = ~footprint.inside
            if out.any():
                hist[out] = new[out]
                hist[out, 12] = hist[out, LIGHT_FRAMES] = 0.0
    if refined is not None and not footprint.exact:
        h_seen = hist[:, 14:17]
        over = luminance(h_seen) > refined.ceiling
        if over.any():
            h_seen[over] *= (refined.ceiling[over] / np.maximum(luminance(h_seen[over]), 1e-30))[:, None]
        h_seen[refined.own] = new[refined.own, 14:17]
    if direct_range is not None:
        lo, hi = direct_range.lo, direct_range.hi
        m = np.maximum(luminance(hist[:, 0:3]), direct_range.floor)
        away = (hi - lo <= GATE_RELATIVE * hi) & ((m - hi > GATE_RELATIVE * m) | (lo - m > GATE_RELATIVE * lo))
        hist[away] = new[away]
        hist[away, 12] = hist[away, LIGHT_FRAMES] = 0.0
    count = np.minimum(hist[:, 12], cap - weight) + weight
    frames = hist[:, LIGHT_FRAMES]
    if surface is not None and footprint.window:
        frames = kept_frames(frames, hist[:, 6:12], surface, luminance(hist[:, 0:3] + hist[:, 14:17]))
    light_count = np.minimum(frames, cap - weight) + weight
    hist -= new
    # = old + (new - old) weight / count, over each group's frames
    keep = (1.0 - weight / count)[:, None]
    keep_light = (1.0 - weight / light_count)[:, None]
    for a, b in LIGHT_GROUP:
        hist[:, a:b] *= keep_light
    for a, b in INDIRECT_GROUP:
        hist[:, a:b] *= keep
    hist += new
    hist[:, 12] = count
    hist[:, LIGHT_FRAMES] = light_count
    return Accumulation(hist)


@dataclass
class DirectRange:
    """This frame's direct light's luminance over each pixel's 3x3
    neighbourhood, for accumulate: both bounds at least ``floor``, the
    image's faintest light worth telling apart, so a dark neighbourhood
    agrees with itself and with a dark history."""
    lo: np.ndarray          # (N,) float32
    hi: np.ndarray          # (N,) float32
    floor: np.float32

    def rows(self, a, b):
        return DirectRange(self.lo[a:b], self.hi[a:b], self.floor)


def light_range(lum_direct, valid, width, height):
    """DirectRange of the direct light's luminance lum_direct (P,) over the
    valid pixels of each 3x3 neighbourhood; the floor is 1e-3 of the image's
    mean (and both bounds where no neighbour is valid)."""
    hi, lo = neighbourhood_range(lum_direct, valid, width, height)
    floor = np.float32(1e-3 * float(lum_direct[valid].mean())) if valid.any() else np.float32(0)
    none = ~np.isfinite(lo)
    hi = np.maximum(hi, floor)
    lo = np.maximum(lo, floor)
    hi[none] = lo[none] = floor
    return DirectRange(lo.astype(np.float32), hi.astype(np.float32), floor)


def restart(acc, cap=0, light_cap=None):
    """Forget the history (cap 0) or keep at most ``cap`` frames of it (a
    number, or one per row), in place; the light group's at most
    ``light_cap`` (default: cap)."""
    if acc is not None:
        np.minimum(acc.count, cap, out=acc.count)
        light_cap = cap if light_cap is None else light_cap
        np.minimum(acc.data[:, LIGHT_FRAMES], light_cap, out=acc.data[:, LIGHT_FRAMES])
