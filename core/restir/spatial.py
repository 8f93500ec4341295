"""Spatial resampling: each pixel reuses the temporal reservoirs of k neighbours.

Neighbours are drawn in a disk of the given radius (pixels) and accepted only
if their visible point is geometrically similar (normal and depth tests, as
the temporal pass). Their samples are shifted by reconnection (Jacobian in
``shift``). The pixel's own reprojected spatial reservoir from last frame is
merged too, so reuse accumulates over frames up to the spatial M cap.

Biased: W = w_sum / (M p_hat). Unbiased: W = w_sum / (Z p_hat), Z summing M of
the reused reservoirs whose visible point sees the chosen sample (one
visibility ray each).
"""

import numpy as np

from .. import samplers
from ..reservoirs import Reservoirs, choose, finalize, target
from ..rows import gather, scatter
from ..sampling import dot
from .shift import J_MAX, J_MIN, jacobian, shift_weight, shift_weight_of, target_at, visible
from .temporal import DEPTH_REL_MAX, NORMAL_COS_MIN

D_SPATIAL = 1000            # first sampler dimension of the spatial pass


def reuse_weights(temporal):
    """luminance(Lo) W M of every temporal reservoir (0 without a sample): the
    part of a neighbour's resampling weight that does not depend on the receiver."""
    return np.where(temporal.has_sample, target(temporal.lo) * temporal.W * temporal.M,
                    0.0).astype(np.float32)


def spatial_resample(ctx, gb, temporal, prev_spatial, prev_owner_p, seeds, k, radius, biased,
                     rows=None, lum_wm=None):
    """Spatial reservoirs of this frame; (unbiased mode) the visibility of each
    pixel's chosen sample from its own visible point, for final shading; and
    where the chosen sample is last frame's spatial reservoir's.

    rows: the (start, stop) range of pixels to resample (all by default; a
    worker's share), whose own arrays are sliced from the whole-image inputs;
    neighbours come from the whole image. prev_spatial and prev_owner_p (last
    frame's spatial reservoirs reprojected, and their visible points) are
    given for those rows only. lum_wm: reuse_weights(temporal), if the caller
    has it (workers share one)."""
    a, b = rows if rows is not None else (0, len(gb.valid))
    w, h = gb.width, gb.height
    p_all, nrm_all, ng_all = gb.p, gb.n, gb.ng
    p, nrm, ng = p_all[a:b], nrm_all[a:b], ng_all[a:b]
    valid, depth = gb.valid[a:b], gb.depth[a:b]
    seeds = seeds[a:b]
    own = temporal.rows(a, b)
    pix = np.arange(a, b)
    # Candidates: this pixel's temporal reservoir, its reprojected spatial
    # reservoir of last frame, and k neighbours' temporal reservoirs. Each is
    # (source reservoirs, source row per pixel, weight, M, owner x1, ng, ns,
    # shifted from); one is chosen per pixel at the end (reservoirs.choose).
    candidates = []
    m_own = np.where(valid, own.M, 0.0).astype(np.float32)
    # p_hat W M of the own reservoir (finalised at this very point): its
    # w_sum, over M (biased, W = w_sum / (M p_hat)) or not (unbiased: the
    # temporal pass weighs by the balance heuristic, W = w_sum / p_hat).
    own_w = np.where(own.W > 0, own.w_sum * (1.0 if biased else m_own), 0.0).astype(np.float32)
    candidates.append((temporal, pix, own_w, m_own, p, ng, nrm, None))

    if prev_spatial is not None:
        pw = shift_weight(prev_spatial, prev_owner_p, p, ng, nrm, biased)
        pm = np.where(valid, prev_spatial.M, 0.0).astype(np.float32)
        candidates.append((prev_spatial, None, pw, pm, p, ng, nrm, prev_owner_p))

    px, py = (pix % w).astype(np.float32), (pix // w).astype(np.float32)
    # Neighbours' reservoirs enter through their sample point, its normal and
    # luminance(Lo) W M: gathered per neighbour, the rest only for the winners.
    if lum_wm is None:
        lum_wm = reuse_weights(temporal)
    for i in range(k):
        ctx.accel.poll()
        u = samplers.uniform2(seeds, D_SPATIAL + 2 + 3 * i)
        r = radius * np.sqrt(u[:, 0])
        phi = 2.0 * np.pi * u[:, 1]
        nx = np.clip(np.rint(px + r * np.cos(phi)), 0, w - 1).astype(np.int64)
        ny = np.clip(np.rint(py + r * np.sin(phi)), 0, h - 1).astype(np.int64)
        nb = ny * w + nx
        nrm_nb = gather(nrm_all, nb)
        ok = valid & np.take(gb.valid, nb) & (nb != pix)
        ok &= dot(nrm, nrm_nb) >= NORMAL_COS_MIN
        ok &= np.abs(np.take(gb.depth, nb) - depth) <= DEPTH_REL_MAX * depth
        p_nb = gather(p_all, nb)
        weight = shift_weight_of(gather(temporal.x2, nb), temporal.field("ng2", nb), np.take(lum_wm, nb),
                                 p_nb, p, ng, nrm, biased)
        weight *= ok
        m = np.where(ok, np.take(temporal.M, nb), 0.0).astype(np.float32)
        ng_nb = gather(ng_all, nb) if not biased else None
        candidates.append((temporal, nb, weight, m, p_nb, ng_nb, nrm_nb, p_nb))

    choice, w_sum = choose([c[2] for c in candidates], samplers.uniform(seeds, D_SPATIAL))
    # The winners' samples: one gather from the temporal reservoirs (own row or
    # a neighbour's), then the rows won by last frame's spatial reservoir.
    n = b - a
    src_row = pix.copy()
    from_prev = np.zeros(n, bool)
    for c, (src, src_rows, *_rest) in enumerate(candidates):
        won = choice == c
        if src is temporal:
            src_row = np.where(won, src_rows, src_row)
        else:
            from_prev |= won
    res = Reservoirs.empty(n)
    for name in Reservoirs.SAMPLE_FIELDS:
        setattr(res, name, temporal.field(name, src_row))
    prev_won = np.nonzero(from_prev)[0]
    if len(prev_won):
        for name in Reservoirs.SAMPLE_FIELDS:
            scatter(getattr(res, name), prev_won, gather(getattr(prev_spatial, name), prev_won))
    nothing = choice < 0
    res.prim2[nothing] = Reservoirs.NO_SAMPLE
    res.lo[nothing] = 0
    res.w_sum[:] = w_sum
    res.M[:] = sum(c[3] for c in candidates)

    own_visible = None
    p_hat = target_at(res, p, ng, nrm)
    if biased:
        finalize(res, p_hat)
    else:
        z = np.zeros(n, np.float32)
        for _src, _rows, _w, m_i, x1_i, ng_i, ns_i, x1_from in candidates:
            counts = m_i > 0
            if x1_from is not None:
                # A reservoir could have given the sample here only if its shift
                # is accepted: shift_weight rejects J outside [J_MIN, J_MAX].
                j = jacobian(x1_from, p, res.x2, res.ng2)
                counts &= (j >= J_MIN) & (j <= J_MAX)
            if x1_i is p:
                if own_visible is None:
                    own_visible = visible(ctx, p, ng, nrm, res)
                vis = own_visible & counts
            else:       # only reservoirs that count in Z need a ray
                vis = visible(ctx, x1_i, ng_i, ns_i, res, where=counts)
            z += np.where(vis, m_i, 0.0)
        finalize(res, p_hat, z)
        # res.M stays the sum of the candidates' M: a confidence that does not
        # depend on which sample was chosen. Setting it to Z (which does) makes
        # next frame's MIS weights correlate with the sample, a bias.
    return res, own_visible, from_prev
