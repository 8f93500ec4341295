"""Sample validation: re-trace stored samples with their stored seeds.

Each reservoir's sample point keeps the seed of the path that estimated its
radiance, so re-running that path in the current scene gives the radiance it
would have now. Where it changed by more than a threshold (a light moved or was
switched off), the reservoir's history is dropped (M = 0), so the next frames'
fresh samples take over within a frame or two. Sky samples are checked against
the current world colour.
"""

import numpy as np

from ..integrators.path import radiance_from_surface
from ..interaction import SurfaceHits
from ..parallel import concat_rows
from ..rows import gather
from ..sampling import luminance

CHANGE_THRESHOLD = 0.25     # relative change of luminance that invalidates a sample


def validate(ctx, res, max_bounces, threshold=CHANGE_THRESHOLD):
    """Re-trace every valid sample of ``res``; drop the changed ones in place.
    Returns the number of reservoirs dropped."""
    sky = np.nonzero((res.prim2 == res.WORLD_SAMPLE) & (res.M > 0))[0]
    changed_sky = np.zeros(0, np.int64)
    if len(sky):
        old = luminance(res.lo[sky])
        new = luminance(np.broadcast_to(ctx.scene.world_color, (len(sky), 3)))
        changed_sky = sky[np.abs(new - old) > threshold * np.maximum(np.maximum(old, new), 1e-6)]
        res.M[changed_sky] = res.W[changed_sky] = res.w_sum[changed_sky] = 0
    rows = np.nonzero((res.prim2 >= 0) & (res.M > 0))[0]
    if len(rows) == 0 or max_bounces < 1:
        return int(len(changed_sky))
    def retrace(a, b):      # the paths of rows[a:b], on the context's workers
        r = rows[a:b]
        surf = SurfaceHits(p=gather(res.x2, r), ng=gather(res.ng2, r), ns=gather(res.n2, r),
                           uv=np.zeros((len(r), 2), np.float32), wo=gather(res.wo2, r),
                           prim=res.prim2[r], material=res.mat2[r], front=np.ones(len(r), bool))
        return radiance_from_surface(ctx, surf, res.seed[r], 1, max_bounces)

    lo_new = concat_rows(ctx.workers.map(retrace, len(rows)))
    old = luminance(res.lo[rows])
    new = luminance(lo_new)
    changed = np.abs(new - old) > threshold * np.maximum(np.maximum(old, new), 1e-6)
    drop = rows[changed]
    res.M[drop] = 0
    res.W[drop] = 0
    res.w_sum[drop] = 0
    return int(len(drop) + len(changed_sky))
