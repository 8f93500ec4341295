"""Reprojected accumulation of the shaded frames: the static part of the image.

The reservoirs reuse indirect-light samples, but every frame still takes one
camera sample per pixel: primary visibility (anti-aliasing over the pixel
filter), the direct light of the visible point and the final shading are new
each frame. On a still or slowly moving view that noise averages away if
each pixel keeps a running mean of what it showed over the last frames.

Each pixel finds the pixel it was last frame: its visible point is carried to
the previous frame (the object's motion, then the previous camera), and the
motion of that point on the film is applied to the pixel's centre (not to its
jittered sample; a still view maps every pixel onto itself). The history
there is kept if the pixel's surface was seen in its 3x3 neighbourhood last
frame (a pixel on an edge sees both sides over its filter footprint, so the
pixel's own last sample need not match this one); disocclusions start over.
The mean is over at most ``cap`` frames (an exponential average once full),
so light that changes shows after about ``cap`` frames; a change of lighting
restarts every pixel.
"""

from dataclasses import dataclass

import numpy as np

from ..camera import generate_rays, project
from ..rows import gather

DEPTH_REL_MAX = 0.1
STILL = 1 << 30             # cap for a still image: the plain mean of every frame


@dataclass
class Accumulation:
    """Running means per pixel (full-image rows) and the frames each holds."""
    direct: np.ndarray      # (P, 3)
    indirect: np.ndarray    # (P, 3)
    albedo: np.ndarray      # (P, 3)
    normal: np.ndarray      # (P, 3) mean of the shading normals (not renormalised)
    count: np.ndarray       # (P,) float32 frames in the mean

    @property
    def nbytes(self):
        return sum(a.nbytes for a in (self.direct, self.indirect, self.albedo, self.normal, self.count))


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


def previous_pixels(scene, gb, history, motion=None, moved=None, still_scene=False):
    """Last frame's pixel of every pixel of the part ``gb`` (-1: start over).

    motion: 4x4 current -> previous matrices of gb's valid rows, or None;
    moved: temporal.moved_objects(), or None; still_scene: no triangle moved
    (with an unchanged camera, every pixel is then where it was)."""
    n = len(gb.valid)
    out = np.full(n, -1, np.int64)
    if history is None or (history.width, history.height) != (gb.width, gb.height):
        return out
    w, h = gb.width, gb.height
    pix = np.arange(gb.offset, gb.offset + n, dtype=np.int64)
    if still_scene and same_view(scene.camera, history.camera):
        return pix              # a still view: every pixel is where it was
    centre = np.stack([pix % w, pix // w], axis=1).astype(np.float32) + 0.5
    idx = gb.index
    miss = np.nonzero(~gb.valid)[0]
    # Visible points, and for pixels that see no surface a far point on the
    # ray through their centre (the world moves with the view direction).
    o, d, tmax = generate_rays(scene.camera, w, h, centre[miss])
    far = o + d * np.minimum(tmax, 1e4)[:, None]
    cur_v, prev_v, depth_v = film_motion(scene, history, gb.surf.p, motion)
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
    seen = np.zeros(n, bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            xs, ys = np.clip(x + dx, 0, w - 1), np.clip(y + dy, 0, h - 1)
            qn = ys * w + xs
            was_valid = history.valid[qn]
            same = np.where(gb.valid,
                            was_valid & (history.object_id[qn] == obj)
                            & (np.abs(history.depth[qn] - depth) <= DEPTH_REL_MAX * np.maximum(depth, 1e-6)),
                            ~was_valid)
            seen |= same
    ok = inside & seen
    q = np.where(inside, y * w + x, 0)
    if moved is not None:
        # Where a moving object passed, the pixel's history shows it: a pixel
        # that last showed another object, either of them moving, starts over
        # (no trail behind moving objects; the 3x3 test would keep one).
        now, before = moved
        obj_prev = history.object_id[q]
        ghost = (obj_prev != obj) & (np.where(obj >= 0, now[np.maximum(obj, 0)], False)
                                     | np.where(obj_prev >= 0, before[np.maximum(obj_prev, 0)], False))
        ok &= ~ghost
    out[ok] = q[ok]
    return out


def accumulate(prev, prev_pix, direct, indirect, albedo, normal, cap):
    """This frame's Accumulation: the history at prev_pix (rows of the part)
    blended with this frame's values, over at most ``cap`` frames. prev: last
    frame's Accumulation (whole image) or None."""
    n = len(prev_pix)
    if prev is None or cap <= 1:
        count = np.ones(n, np.float32)
        return Accumulation(direct.copy(), indirect.copy(), albedo.copy(), normal.copy(), count)
    found = prev_pix >= 0
    q = np.maximum(prev_pix, 0)
    count = np.where(found, np.minimum(np.take(prev.count, q), cap - 1), 0).astype(np.float32) + 1
    a = (1.0 / count)[:, None]

    def blend(old, new):
        out = gather(old, q)
        out -= new
        out *= 1.0 - a          # = old + (new - old) / count
        out += new
        return out

    return Accumulation(blend(prev.direct, direct), blend(prev.indirect, indirect),
                        blend(prev.albedo, albedo), blend(prev.normal, normal), count)


def restart(acc, cap=0):
    """Forget the history (cap 0) or keep at most ``cap`` frames of it, in place."""
    if acc is not None:
        np.minimum(acc.count, cap, out=acc.count)
