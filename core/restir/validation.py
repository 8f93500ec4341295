"""Sample validation: re-trace stored samples with their stored seeds.

Each reservoir's sample point keeps the seed of the path that estimated its
radiance, so re-running that path in the current scene gives the radiance it
would have now. Where it changed by more than a threshold (a light moved or was
switched off), the reservoir's history is dropped (M = 0), so the next frames'
fresh samples take over within a frame or two. Sky samples are checked against
the current world (initial.world_sample_radiance: the world's radiance in
their direction, less the share the visible points' NEE takes).
"""

import numpy as np

from ..integrators.bounces import first_bounce_counts
from ..integrators.path import radiance_from_surface
from ..geometry.interaction import SurfaceHits
from ..workers.parallel import concat_rows
from ..util.vectors import luminance
from .initial import world_sample_radiance

CHANGE_THRESHOLD = 0.25     # relative change of luminance that invalidates a sample


def validate(ctx, res, max_bounces, threshold=CHANGE_THRESHOLD):
    """Re-trace every valid sample of ``res`` (Reservoirs, or a list of them);
    drop the changed ones in place. A sample kept by several reservoirs (the
    temporal and the spatial reservoirs share many) is traced once: its seed
    names it. Returns the number of reservoirs dropped."""
    sets = list(res) if isinstance(res, (list, tuple)) else [res]
    dropped = 0
    for r in sets:
        sky = np.nonzero((r.prim2 == r.WORLD_SAMPLE) & (r.M > 0))[0]
        if len(sky):
            old = luminance(r.field("lo", sky))
            new = luminance(world_sample_radiance(ctx.lights, -r.field("wo2", sky)))
            changed_sky = sky[_changed(old, new, threshold)]
            r.drop(changed_sky)
            dropped += len(changed_sky)
    rows = [np.nonzero((r.prim2 >= 0) & (r.M > 0))[0] for r in sets]
    if sum(len(x) for x in rows) == 0 or max_bounces < 1:
        return dropped
    # One row per distinct sample, over all sets.
    which = np.concatenate([np.full(len(x), i) for i, x in enumerate(rows)])
    row = np.concatenate(rows)
    seeds = np.concatenate([r.seed[x] for r, x in zip(sets, rows)])
    _, first, back = np.unique(seeds, return_index=True, return_inverse=True)

    def field(name, at):
        return np.concatenate([r.field(name, x) for r, x in zip(sets, rows)])[at]

    x2, ng2, n2, wo2 = (field(name, first) for name in ("x2", "ng2", "n2", "wo2"))
    prim2, seed, kind = field("prim2", first), seeds[first], field("kind", first)
    mat2 = np.take(ctx.scene.material_ids, prim2)

    def retrace(a, b):      # the paths of distinct samples a..b, on the context's workers
        k = slice(a, b)
        surf = SurfaceHits(p=x2[k], ng=ng2[k], ns=n2[k],
                           wo=wo2[k], prim=prim2[k], material=mat2[k], front=np.ones(b - a, bool))
        return radiance_from_surface(ctx, surf, seed[k], 1, max_bounces,
                                     counts=first_bounce_counts(b - a, max_bounces, kind[k]))

    lo_new = concat_rows(ctx.workers.map(retrace, len(first)))[back]
    changed = _changed(luminance(field("lo", slice(None))), luminance(lo_new), threshold)
    for i, r in enumerate(sets):
        drop = row[(which == i) & changed]
        r.drop(drop)
        dropped += len(drop)
    return int(dropped)


def _changed(old, new, threshold):
    return np.abs(new - old) > threshold * np.maximum(np.maximum(old, new), 1e-6)
