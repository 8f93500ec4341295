"""Where each pixel's history lies in last frame's image: reprojection of
the visible points through objects' motion and the cameras, and the taps and
weights that read the history there (accumulation.accumulate blends it).

Each pixel finds where it was last frame: its visible point is carried to
the previous frame (the object's motion, then the previous camera), and the
motion of that point on the film is applied to the pixel's centre (not to its
jittered sample; a still view maps every pixel onto itself). The history is
read there through a 4x4 Catmull-Rom window (bilinearly where some pixel of
the window saw another surface), and kept if the pixel's surface was seen in
the 3x3 pixels around that place last frame (a pixel on an edge sees both
sides over its filter footprint, so its own last sample need not match this
one); disocclusions start over.
"""

from dataclasses import dataclass

import numpy as np

from ..camera.projection import generate_rays, project
from .similarity import DEPTH_REL_MAX


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


def film_shift(scene, history, pix, p, valid, object_id, motion=None):
    """Film motion (n, 2) from this frame to the last of the pixels ``pix``
    (image indices) and the previous view depth (n,) of what they see (0 on
    misses). p: (V, 3) the visible points of the pixels where ``valid``
    (n,), in order; object_id: (n,); motion: temporal.ObjectMotion.between,
    or None. For pixels that see no surface, a far point on the ray through
    their centre moves (the world moves with the view direction)."""
    w, h = scene.width, scene.height
    n = len(pix)
    idx = np.flatnonzero(valid)
    miss = np.flatnonzero(~valid)
    centre = np.stack([pix[miss] % w, pix[miss] // w], axis=1).astype(np.float32) + 0.5
    o, d, tmax = generate_rays(scene.camera, w, h, centre)
    far = o + d * np.minimum(tmax, 1e4)[:, None]
    cur_v, prev_v, depth_v = film_motion(scene, history, p, None if motion is None else motion.of(object_id[idx]))
    cur_m, prev_m, _ = film_motion(scene, history, far)
    shift = np.empty((n, 2), np.float32)
    shift[idx] = prev_v - cur_v
    shift[miss] = prev_m - cur_m
    depth = np.zeros(n, np.float32)
    depth[idx] = depth_v
    return shift, depth


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


def previous_pixels(scene, gb, history, motion=None, still_scene=False, edges=None, film=None):
    """Footprint of last frame's history of every pixel of the part ``gb``.

    motion: temporal.ObjectMotion.between(scene, history) (None: nothing
    moved); still_scene: no triangle moved
    (with an unchanged camera, every pixel is then where it was).

    A moving view reads the history bilinearly at the reprojected centre:
    taking the nearest pixel instead rounds by up to half a pixel every
    frame, and those errors add up into streaks along the motion.

    edges ((N,) bool, geometric_edges of this frame): pixels that cover
    several surfaces read every tap, not only those that saw their own
    surface: their history is the mix they cover, as on a still view.

    film: film_shift's (shift, depth) of the part's pixels, if the caller
    has them (the frame finds them for the whole image); else found here."""
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
    shift, depth = film if film is not None else film_shift(scene, history, pix, gb.surf.p, gb.valid,
                                                            gb.object_id, motion)
    target = centre + shift
    idx = gb.index
    x = np.floor(target[:, 0]).astype(np.int64)
    y = np.floor(target[:, 1]).astype(np.int64)
    inside = (x >= 0) & (x < w) & (y >= 0) & (y < h)
    inside[idx] &= depth[idx] > 0
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
