"""Reprojected accumulation of the shaded frames: the static part of the image.

The reservoirs reuse indirect-light samples, but every frame still takes one
camera sample per pixel: primary visibility (anti-aliasing over the pixel
filter), the direct light of the visible point and the final shading are new
each frame. On a still or slowly moving view that noise averages away if
each pixel keeps a running mean of what it showed over the last frames.

Each pixel finds where it was last frame: its visible point is carried to
the previous frame (the object's motion, then the previous camera), and the
motion of that point on the film is applied to the pixel's centre (not to its
jittered sample; a still view maps every pixel onto itself). The history is
read there through a 4x4 Catmull-Rom window (bilinearly where some pixel of
the window saw another surface), and kept if the pixel's surface was seen in
the 3x3 pixels around that place last frame (a pixel on an edge sees both
sides over its filter footprint, so its own last sample need not match this
one); disocclusions start over. The mean is over at most ``cap`` frames (an
exponential average once full), so light that changes shows after about
``cap`` frames; the caller restarts every pixel when lights, materials or
the world change, and keeps a few frames where objects moved.
"""

from dataclasses import dataclass

import numpy as np

from ..camera.projection import generate_rays, project
from ..util.rows import gather
from ..util.vectors import luminance
from .adaptive_direct import neighbourhood_range
from .similarity import DEPTH_REL_MAX
STILL = 1 << 30             # cap for a still image: the plain mean of every frame


COLUMNS = 17        # direct 3, indirect 3, albedo 3, normal 3, count 1, alpha 1, seen 3

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


def same_view(a, b):
    """True if two cameras image every point at the same place."""
    fa, fb = vars(a), vars(b)
    return all(np.array_equal(np.asarray(fa[k]), np.asarray(fb[k])) for k in fa)


def film_motion(scene, history, p, motion=None):
    """Film positions (N, 2) of world points p now and in the previous frame,
    and their previous view depth. motion: per-point 4x4 matrices taking
    current positions to last frame's (moving objects), or None."""
    cur, _ = project(scene.camera, scene.width, scene.height, p)
    q = np.asarray(p, np.float64)
    if motion is not None:
        q = np.einsum("nij,nj->ni", motion[:, :3, :3], q) + motion[:, :3, 3]
    prev, depth = project(history.camera, history.width, history.height, q)
    return cur, prev, depth


@dataclass
class Footprint:
    """Where each pixel's history lies in last frame's image: up to sixteen
    pixels around the reprojected centre (a Catmull-Rom window, or its inner
    2x2 read bilinearly, which come first) and their weights, which sum to one
    where history was found and to zero where the pixel starts over."""
    taps: np.ndarray        # (N, 16) int64 pixel indices (0 where unused)
    weights: np.ndarray     # (N, 16) float32 (Catmull-Rom's can be negative)
    exact: bool = False     # every pixel is where it was (a still view of a still scene)
    window: bool = False    # taps are the 4x4 window around each reprojected centre (a moving view)
    inside: np.ndarray = None   # (N,) bool: the reprojected centre lies in last frame's image

    @property
    def found(self):
        return self.weights.sum(axis=1) > 0.5

    def nearest(self):
        """The tap of largest weight, -1 where nothing was found."""
        k = self.weights.argmax(axis=1)
        q = np.take_along_axis(self.taps, k[:, None], axis=1)[:, 0]
        return np.where(self.found, q, -1)

    @classmethod
    def none(cls, n):
        return cls(np.zeros((n, 16), np.int64), np.zeros((n, 16), np.float32))


def geometric_edges(object_id, depth, valid, width, height):
    """(P,) bool: pixels whose 3x3 neighbourhood holds more than one surface
    (another object, a miss beside a hit, or a depth more than
    DEPTH_REL_MAX away)."""
    oid = np.where(valid, object_id, -1).reshape(height, width)
    d = np.where(valid, depth, np.inf).astype(np.float32).reshape(height, width)
    out = np.zeros((height, width), bool)
    po = np.pad(oid, 1, mode="edge")
    pd = np.pad(d, 1, mode="edge")
    for dy in range(3):
        for dx in range(3):
            if dy == 1 and dx == 1:
                continue
            o2 = po[dy:dy + height, dx:dx + width]
            d2 = pd[dy:dy + height, dx:dx + width]
            out |= o2 != oid
            with np.errstate(invalid="ignore"):
                out |= np.abs(d2 - d) > DEPTH_REL_MAX * np.minimum(d, d2)
    return out.ravel()


def previous_pixels(scene, gb, history, motion=None, still_scene=False, edges=None):
    """Footprint of last frame's history of every pixel of the part ``gb``.

    motion: temporal.ObjectMotion.between(scene, history) (None: nothing
    moved); still_scene: no triangle moved
    (with an unchanged camera, every pixel is then where it was).

    A moving view reads the history bilinearly at the reprojected centre:
    taking the nearest pixel instead rounds by up to half a pixel every
    frame, and those errors add up into streaks along the motion.

    edges ((N,) bool, geometric_edges of this frame): pixels that cover
    several surfaces read every tap, not only those that saw their own
    surface: their history is the mix they cover, as on a still view."""
    n = len(gb.valid)
    if history is None or (history.width, history.height) != (gb.width, gb.height):
        return Footprint.none(n)
    w, h = gb.width, gb.height
    pix = np.arange(gb.offset, gb.offset + n, dtype=np.int64)
    if still_scene and same_view(scene.camera, history.camera):
        out = Footprint.none(n)
        out.taps[:, 0] = pix    # a still view: every pixel is where it was
        out.weights[:, 0] = 1.0
        out.exact = True
        return out
    centre = np.stack([pix % w, pix // w], axis=1).astype(np.float32) + 0.5
    idx = gb.index
    miss = np.nonzero(~gb.valid)[0]
    # Visible points, and for pixels that see no surface a far point on the
    # ray through their centre (the world moves with the view direction).
    o, d, tmax = generate_rays(scene.camera, w, h, centre[miss])
    far = o + d * np.minimum(tmax, 1e4)[:, None]
    cur_v, prev_v, depth_v = film_motion(scene, history, gb.surf.p,
                                         None if motion is None else motion.of(gb.object_id[idx]))
    cur_m, prev_m, _ = film_motion(scene, history, far)
    target = np.empty((n, 2), np.float32)
    target[idx] = centre[idx] + (prev_v - cur_v)
    target[miss] = centre[miss] + (prev_m - cur_m)
    x = np.floor(target[:, 0]).astype(np.int64)
    y = np.floor(target[:, 1]).astype(np.int64)
    inside = (x >= 0) & (x < w) & (y >= 0) & (y < h)
    depth = np.zeros(n, np.float32)
    depth[idx] = depth_v
    inside[idx] &= depth_v > 0
    obj = gb.object_id
    moved = motion is not None
    if moved:
        now, before = motion.moved_now, motion.moved_before
        moving_now = np.where(obj >= 0, now[np.maximum(obj, 0)], False)

    tolerance = DEPTH_REL_MAX * np.maximum(depth, 1e-6)
    tolerance[~gb.valid] = np.inf

    def like(qn):
        """Last frame's sample of pixels qn was this pixel's kind of surface:
        the same object at a similar depth, or for a pixel that sees nothing,
        nothing (object id -1 on misses). Pixels on geometric edges (edges)
        take every tap: their history is the mix of the surfaces they cover."""
        obj_prev = np.take(history.object_id, qn)
        same = obj_prev == obj
        same &= np.abs(np.take(history.depth, qn) - depth) <= tolerance
        if edges is not None:
            same |= edges
        return same, obj_prev

    # Taps of a 4x4 Catmull-Rom window around the reprojected centre, the
    # inner 2x2 (the bilinear taps) first. Bilinear reads blur a little every
    # frame, and over a history of 16 frames that widened a sunlit stripe by
    # pixels on a moving view; Catmull-Rom keeps it sharp. Rows where a tap's
    # last sample was another surface (or outside the image) read bilinearly
    # from the taps that match instead (the nearest pixel if none does).
    fx, fy = target[:, 0] - 0.5, target[:, 1] - 0.5
    x0, y0 = np.floor(fx).astype(np.int64), np.floor(fy).astype(np.int64)
    tx, ty = (fx - x0).astype(np.float32), (fy - y0).astype(np.float32)
    nearest = np.clip(y, 0, h - 1) * w + np.clip(x, 0, w - 1)
    cr_x, cr_y = _catmull_rom(tx), _catmull_rom(ty)
    bilinear = {(0, 0): (1 - tx) * (1 - ty), (1, 0): tx * (1 - ty), (0, 1): (1 - tx) * ty, (1, 1): tx * ty}
    # Disocclusion: this pixel's surface was nowhere in the 3x3 pixels around
    # where it was (a pixel on an edge sees both sides over its filter
    # footprint, so the pixel's own last sample need not be like this one).
    # Those 3x3 pixels lie in the window (x is x0 or x0 + 1, y likewise).
    # Built tap-major, (16, N), and handed out transposed: a column of an
    # (N, 16) array is written with a stride of 16 items, a pass over the
    # whole array per tap (the window took as long as the rest of the frame's
    # shading on a moving view).
    taps = np.empty((16, n), np.int64)
    weights = np.zeros((16, n), np.float32)
    sharp_weights = np.empty((16, n), np.float32)
    seen = np.zeros(n, bool)
    sharp = inside.copy()
    # Per column and per row of the window (four each): the clamped pixel
    # coordinate, whether it lies in the image, and whether it is within one
    # pixel of the nearest pixel (the 3x3 of the disocclusion test).
    cols = {dx: (np.clip(x0 + dx, 0, w - 1), (x0 + dx >= 0) & (x0 + dx < w), np.abs(x0 + dx - x) <= 1)
            for dx in range(-1, 3)}
    rows = {dy: (np.clip(y0 + dy, 0, h - 1) * w, (y0 + dy >= 0) & (y0 + dy < h), np.abs(y0 + dy - y) <= 1)
            for dy in range(-1, 3)}
    for k, (dx, dy) in enumerate(TAPS):
        (xc, x_in, x_near), (yc, y_in, y_near) = cols[dx], rows[dy]
        qn = np.add(yc, xc, out=taps[k])
        same, obj_prev = like(qn)
        seen |= same & x_near & y_near
        keep = same & x_in & y_in
        if moved:
            # Where a moving object passed, history shows it: no trails.
            moving_prev = np.where(obj_prev >= 0, before[np.maximum(obj_prev, 0)], False)
            keep &= ~((obj_prev != obj) & (moving_now | moving_prev))
        sharp &= keep
        np.multiply(cr_x[dx + 1], cr_y[dy + 1], out=sharp_weights[k])
        if k < 4:
            weights[k] = np.where(keep, bilinear[(dx, dy)], 0.0)
    ok = inside & seen
    sharp &= ok
    total = (weights[0] + weights[1]) + (weights[2] + weights[3])   # (the only taps weighted yet)
    alone = ok & (total <= 1e-6)
    if moved:                   # the nearest pixel must not be a trail either
        obj_prev = history.object_id[nearest]
        moving_prev = np.where(obj_prev >= 0, before[np.maximum(obj_prev, 0)], False)
        alone &= ~((obj_prev != obj) & (moving_now | moving_prev))
    taps[0, alone], weights[:, alone] = nearest[alone], 0.0
    weights[0, alone] = 1.0
    total = np.where(alone, 1.0, total)
    weights *= np.where(ok & (total > 1e-6), 1.0 / np.maximum(total, 1e-6), 0.0)
    return Footprint(taps.T, np.where(sharp, sharp_weights, weights).T, window=True, inside=inside)


# Offsets of the 4x4 window from the tap left of and below the centre, inner 2x2 first.
TAPS = [(0, 0), (1, 0), (0, 1), (1, 1)] + [(dx, dy) for dy in (-1, 0, 1, 2) for dx in (-1, 0, 1, 2)
                                           if not (dx in (0, 1) and dy in (0, 1))]


def _catmull_rom(t):
    """Catmull-Rom weights of the samples at -1, 0, 1, 2 for a position t in [0, 1)."""
    t2, t3 = t * t, t * t * t
    return (0.5 * (-t3 + 2 * t2 - t), 0.5 * (3 * t3 - 5 * t2 + 2), 0.5 * (-3 * t3 + 4 * t2 + t),
            0.5 * (t3 - t2))


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
        if self.moments is not None:
            new[:, COLUMNS:] = self.moments
        return new


def accumulate(prev, footprint, values, cap, refined=None, direct_range=None):
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
    often lies below their mean); a neighbourhood that agrees is neither."""
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
                hist[out, 12] = 0.0
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
        hist[away, 12] = 0.0
    count = np.minimum(hist[:, 12], cap - weight) + weight
    hist -= new
    hist *= (1.0 - weight / count)[:, None]     # = old + (new - old) weight / count
    hist += new
    hist[:, 12] = count
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


def restart(acc, cap=0):
    """Forget the history (cap 0) or keep at most ``cap`` frames of it, in place."""
    if acc is not None:
        np.minimum(acc.count, cap, out=acc.count)
