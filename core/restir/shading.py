"""Final shading: emission + direct light + the spatial reservoir's indirect term.

indirect = f(x1, wo, wi) cos(wi) Lo(x2) W V(x1, x2), with wi toward the chosen
sample point and one visibility ray (unless the spatial pass already traced it).
"""

import numpy as np

from .. import bsdf
from ..rows import scale, scatter
from ..sampling import dot


def shade_indirect(ctx, gb, res, visible_own=None):
    """(P, 3) indirect radiance toward the camera from each pixel's reservoir."""
    from .spatial import visible
    n = len(gb.valid)
    out = np.zeros((n, 3), np.float32)
    idx = gb.index
    if len(idx) == 0:
        return out
    surf = gb.surf
    y = res.view(idx)
    to = y.x2 - surf.p
    dist = np.sqrt(np.maximum(dot(to, to), 1e-30))
    wi = scale(to, 1.0 / dist).astype(np.float32)
    frame = gb.frame
    wi_l = frame.local(surf, wi)
    f = bsdf.evaluate(frame.params, frame.wo_local, wi_l)
    cos = np.maximum(wi_l[:, 2], 0.0)
    vis = visible(ctx, surf.p, surf.ng, surf.ns, y) if visible_own is None else visible_own[idx]
    contrib = scale(f * y.lo, cos * y.W * vis)
    return scatter(out, idx, np.nan_to_num(contrib, nan=0.0, posinf=0.0, neginf=0.0))
