"""Which pixels' direct light a moving object can have changed since last
frame: those whose shadow rays toward a lamp pass through the box it swept,
and those close enough to it that it fills much of their sky.

The running means of the direct light (accumulation.LIGHT_GROUP) kept only
MOVING_CAP frames on every pixel while anything moved, so that a moving
shadow's edges do not trail. Four frames of one jittered camera ray each
are too few to smooth the pixel filter's edges and the sky rays' noise: the
whole image turned jagged and speckled while, say, one box slid across a
room. With this test only the pixels a moving object can shadow keep the
short history (a conservative test: boxes, the lamps' extents, and every
pixel within NEAR box radii).
"""

import numpy as np

from ..geometry.boxes import crosses_box
from ..scene import LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN

NEAR = 3.0              # pixels within this many swept-box radii: the object fills much of their sky
MARGIN = 0.25           # boxes grown by this share of their radius (pixel footprints, penumbrae)
MAX_TESTS = 256         # lamps x moved objects beyond which every pixel counts as reached
MAX_SWEEP = 16          # frames of steady motion a swept box reaches back at most


def swept_boxes(scene, motion, frames=1):
    """(K, 2, 3) float64: per object that moved, the box around its
    triangles now and where they were over the last ``frames`` frames, the
    motion since last frame (motion.to_previous) taken as steady."""
    ids = np.nonzero(motion.moved_now)[0]
    boxes = []
    for i in ids:
        tri = scene.triangles[scene.object_ids == i]
        if len(tri) == 0:
            continue
        v = scene.vertices[tri.ravel()].astype(np.float64)
        lo, hi = v.min(axis=0), v.max(axis=0)
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        m = motion.to_previous[i]
        before = corners
        for _ in range(int(np.clip(frames, 1, MAX_SWEEP))):
            before = before @ m[:3, :3].T + m[:3, 3]
            lo, hi = np.minimum(lo, before.min(axis=0)), np.maximum(hi, before.max(axis=0))
        boxes.append((lo, hi))
    return np.array(boxes, np.float64).reshape(-1, 2, 3)


def segment_hits_box(a, b, lo, hi):
    """(N,) bool: the segments a -> b (N, 3) may pass through the box [lo, hi]."""
    return crosses_box(a, b - a, np.ones(len(a)), lo, hi)


def reached(scene, lights, motion, p, valid, frames=1):
    """(P,) bool over the points p (P, 3) where ``valid``: a moved object may
    have changed their direct light over the last ``frames`` frames (the
    history a reached pixel keeps: a shadow that left it since must leave
    its mean too). None where the test cannot tell (the scene's emissive
    triangles light it, or too many lamps and objects): then every pixel
    counts as reached."""
    if lights is None or getattr(lights, "triangles", None) is not None and len(lights.tri_index):
        return None
    boxes = swept_boxes(scene, motion, frames)
    analytic = scene.lights
    n_lamps = 0 if analytic is None else len(analytic.kind)
    if len(boxes) == 0:
        return np.zeros(len(p), bool)
    if len(boxes) * max(n_lamps, 1) > MAX_TESTS:
        return None
    out = np.zeros(len(p), bool)
    rows = np.nonzero(valid)[0]
    x = p[rows].astype(np.float64)
    far = 4.0 * float(scene.extent())
    hit = np.zeros(len(rows), bool)
    for lo, hi in boxes:
        centre, radius = 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo))
        hit |= np.linalg.norm(x - centre, axis=1) < NEAR * radius
        for k in range(n_lamps):
            kind = int(analytic.kind[k])
            grow = MARGIN * radius
            if kind == LIGHT_SUN:
                to = x - far * analytic.direction[k].astype(np.float64)
                grow += far * np.tan(0.5 * float(analytic.angle[k]))
            elif kind in (LIGHT_POINT, LIGHT_SPOT):
                to = np.broadcast_to(analytic.position[k].astype(np.float64), x.shape)
                grow += float(analytic.radius[k])
            elif kind == LIGHT_AREA:
                to = np.broadcast_to(analytic.position[k].astype(np.float64), x.shape)
                grow += 0.5 * float(max(analytic.size_u[k], analytic.size_v[k]))
            else:
                continue
            open_rows = ~hit
            if open_rows.any():
                hit[open_rows] = segment_hits_box(x[open_rows], to[open_rows], lo - grow, hi + grow)
    out[rows] = hit
    return out
