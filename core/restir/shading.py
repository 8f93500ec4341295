"""Final shading: emission + direct light + the spatial reservoir's indirect term.

indirect = f(x1, wo, wi) cos(wi) Lo(x2) W V(x1, x2), with wi toward the chosen
sample point and one visibility ray, unless the spatial pass already traced
it (unbiased mode) or it is known from a recent frame (carried_visibility).

Visibility states (int8 per pixel): 0 unknown; +a visible and -a hidden, as
traced a - 1 frames ago from (nearly) this visible point to this sample.
"""

import numpy as np

from ..util.rows import scale, scatter
from ..sampling.warps import INV_PI
from ..util.vectors import dot
from .shift import visible

VISIBILITY_MAX_AGE = 4      # frames a traced visibility is trusted for
VISIBILITY_MAX_MOVE = 0.01  # how far the visible point may have moved, relative to
                            # its distance to the sample


def carried_visibility(prev_state, from_prev, owner_p, p, x2):
    """This frame's known visibility states: last frame's, one frame older,
    where the pixel kept last frame's spatial sample (from_prev), its visible
    point moved by at most VISIBILITY_MAX_MOVE of the distance to the sample,
    and the state is younger than VISIBILITY_MAX_AGE. The caller makes sure
    that no geometry changed (a static scene sees what it saw before)."""
    state = prev_state.astype(np.int16)
    age = np.abs(state) + 1
    moved = p - owner_p
    to = x2 - p
    close = dot(moved, moved) <= VISIBILITY_MAX_MOVE ** 2 * dot(to, to)
    keep = from_prev & close & (state != 0) & (age <= VISIBILITY_MAX_AGE)
    return np.where(keep, np.sign(state) * age, 0).astype(np.int8)


def shade_indirect(ctx, gb, res, visible_own=None, known=None):
    """(P, 3) indirect radiance toward the camera from each pixel's reservoir
    through the diffuse lobe,
    and the (P,) int8 visibility states it used (traced rays are age 1).
    known: (P,) visibility states already known (0: trace a ray)."""
    n = len(gb.valid)
    out = np.zeros((n, 3), np.float32)
    state = np.zeros(n, np.int8)
    idx = gb.index
    if len(idx) == 0:
        return out, state
    surf = gb.surf
    y = res.view(idx)
    to = y.x2 - surf.p
    dist = np.sqrt(np.maximum(dot(to, to), 1e-30))
    wi = scale(to, 1.0 / dist).astype(np.float32)
    # The diffuse lobe only: the glossy lobe's indirect light comes from each
    # pixel's own new sample (initial.py). Its cosine is the local z of wi in
    # the shading frame, i.e. along the shading normal.
    cos_l = dot(wi, surf.ns)
    cos = np.maximum(cos_l, 0.0)
    f = scale(gb.frame.params.diffuse, (cos_l > 0) * INV_PI)
    if visible_own is not None:
        vis = visible_own[idx]
        s = np.where(vis, 1, -1)
    else:
        s = np.zeros(len(idx), np.int8) if known is None else known[idx]
        trace = s == 0
        vis = visible(ctx, surf.p, surf.ng, surf.ns, y, where=None if trace.all() else trace)
        vis = np.where(trace, vis, s > 0)
        s = np.where(trace, np.where(vis, 1, -1), s)
    state[idx] = np.where(y.has_sample, s, 0)
    contrib = scale(f * y.lo, cos * y.W * vis)
    return scatter(out, idx, np.nan_to_num(contrib, nan=0.0, posinf=0.0, neginf=0.0)), state
