"""Spatial resampling: each pixel reuses the temporal reservoirs of k neighbours.

Neighbours are drawn in a disk of the given radius (pixels) and accepted only
if their visible point is geometrically similar (normal and depth tests, as
the temporal pass). Their samples are shifted by reconnection (Jacobian in
``shift``). The pixel's own reprojected spatial reservoir from last frame is
merged too, so reuse accumulates over frames up to the spatial M cap.

Biased: W = w_sum / (Z p_hat), Z the confidence of the candidates whose
visible point the chosen sample could have come from, visibility aside
(``domain_confidence``). Unbiased: the candidates' weights carry
pairwise MIS weights (``_pairwise_weights``) with visibility in the targets,
and W = w_sum / p_hat.
"""

from typing import NamedTuple

import numpy as np

from ..sampling import samplers
from .reservoirs import Reservoirs, choose, finalize, target
from ..integrators.base import shadow_rays
from ..util.rows import gather, scale, scatter
from ..util.vectors import dot
from .shift import shift_target, shift_weight, shift_weight_of, target_at
from .similarity import DEPTH_REL_MAX, NORMAL_COS_MIN

D_SPATIAL = 1000            # first sampler dimension of the spatial pass


class Candidate(NamedTuple):
    """One reservoir a pixel may take its sample from, for every pixel of a range."""
    source: object          # the Reservoirs it comes from (temporal, or last frame's spatial)
    rows: np.ndarray        # (n,) its row in source per pixel (None: the range's own rows)
    weight: np.ndarray      # (n,) resampling weight (None until pairwise MIS sets it)
    M: np.ndarray           # (n,) confidence it brings (0 where not reused)
    owner_p: np.ndarray     # (n, 3) the visible point that found it
    ng: np.ndarray          # (n, 3) that point's geometric normal (None where not needed)
    ns: np.ndarray          # (n, 3) that point's shading normal
    shifted_from: np.ndarray  # (n, 3) the point its sample is shifted from (None: this pixel's own)


def sample_luminance(temporal):
    """luminance(Lo) of every temporal reservoir's sample (0 without one)."""
    return np.where(temporal.has_sample, target(temporal.lo), 0.0).astype(np.float32)


def reuse_weights(temporal):
    """luminance(Lo) W M of every temporal reservoir (0 without a sample): the
    part of a neighbour's resampling weight that does not depend on the receiver."""
    w = sample_luminance(temporal) * temporal.W
    w *= temporal.M
    return w


def shared_terms(temporal, biased):
    """The per-image values spatial_resample reads at neighbours, computed once
    for all workers: reuse_weights (biased) or sample_luminance (unbiased)."""
    return reuse_weights(temporal) if biased else sample_luminance(temporal)


class SpatialReuse(NamedTuple):
    """How spatial_resample reuses neighbours."""
    neighbors: int          # k neighbours per pixel
    radius: float           # of the disk they are drawn in, pixels
    biased: bool            # biased (W = w_sum / (Z p_hat), domain_confidence) or unbiased (pairwise MIS)
    more: int = 0           # neighbours more for the pixels spatial_resample's ``more`` flags (biased)


class CarriedSpatial(NamedTuple):
    """Last frame's spatial reservoirs reprojected to a range of pixels."""
    reservoirs: Reservoirs  # one per pixel of the range
    owner_p: np.ndarray     # (n, 3) the visible points that held them


def spatial_resample(ctx, gb, temporal, seeds, reuse, carried=None, rows=None, shared=None, more=None):
    """Spatial reservoirs of this frame; (unbiased mode) the visibility of each
    pixel's chosen sample from its own visible point, for final shading; and
    where the chosen sample is last frame's spatial reservoir's.

    reuse: SpatialReuse. rows: the (start, stop) range of pixels to resample
    (all by default; a worker's share), whose own arrays are sliced from the
    whole-image inputs; neighbours come from the whole image. carried:
    CarriedSpatial of those rows, or None. shared: shared_terms(temporal,
    biased), if the caller has it (workers share one). more: (n,) bool of
    the range's pixels, those that draw reuse.more neighbours more (biased
    mode), or None."""
    k, radius, biased = reuse.neighbors, reuse.radius, reuse.biased
    prev_spatial, prev_owner_p = carried if carried is not None else (None, None)
    a, b = rows if rows is not None else (0, len(gb.valid))
    w, h = gb.width, gb.height
    p_all, nrm_all, ng_all = gb.p, gb.n, gb.ng
    p, nrm, ng = p_all[a:b], nrm_all[a:b], ng_all[a:b]
    valid, depth = gb.valid[a:b], gb.depth[a:b]
    seeds = seeds[a:b]
    own = temporal.rows(a, b)
    pix = np.arange(a, b)
    # Candidates: this pixel's temporal reservoir, its reprojected spatial
    # reservoir of last frame, and k neighbours' temporal reservoirs; one is
    # chosen per pixel at the end (reservoirs.choose).
    candidates = []
    m_own = np.where(valid, own.M, 0.0).astype(np.float32)
    # p_hat W M of the own reservoir (finalised at this very point): its
    # w_sum, over M (biased, W = w_sum / (M p_hat)) or not (unbiased: the
    # temporal pass weighs by the balance heuristic, W = w_sum / p_hat).
    own_w = np.where(own.W > 0, own.w_sum * (1.0 if biased else m_own), 0.0).astype(np.float32)
    candidates.append(Candidate(temporal, pix, own_w, m_own, p, ng, nrm, None))

    if prev_spatial is not None:
        pw = shift_weight(prev_spatial, prev_owner_p, p, ng, nrm, biased)
        pm = np.where(valid, prev_spatial.M, 0.0).astype(np.float32)
        candidates.append(Candidate(prev_spatial, None, pw, pm, p, ng, nrm, prev_owner_p))

    px, py = (pix % w).astype(np.float32), (pix // w).astype(np.float32)
    # Neighbours' reservoirs enter through their sample point, its normal and
    # luminance(Lo) W M (biased) or luminance(Lo) and W (unbiased): gathered
    # per neighbour, the rest only for the winners.
    if shared is None:
        shared = shared_terms(temporal, biased)
    def neighbour(i, sel):
        """Candidate of draw i for the rows sel (None: all; elsewhere M 0)."""
        at = (lambda x: x) if sel is None else (lambda x: x[sel])
        u = samplers.uniform2(at(seeds), D_SPATIAL + 2 + 3 * i)
        r = radius * np.sqrt(u[:, 0])
        phi = 2.0 * np.pi * u[:, 1]
        nx = np.clip(np.rint(at(px) + r * np.cos(phi)), 0, w - 1).astype(np.int64)
        ny = np.clip(np.rint(at(py) + r * np.sin(phi)), 0, h - 1).astype(np.int64)
        nb = ny * w + nx
        nrm_nb = gather(nrm_all, nb)
        ok = at(valid) & np.take(gb.valid, nb) & (nb != at(pix))
        ok &= dot(at(nrm), nrm_nb) >= NORMAL_COS_MIN
        ok &= np.abs(np.take(gb.depth, nb) - at(depth)) <= DEPTH_REL_MAX * at(depth)
        p_nb = gather(p_all, nb)
        m = np.where(ok, np.take(temporal.M, nb), 0.0).astype(np.float32)
        weight = None       # (unbiased: pairwise MIS weights, below, once every neighbour is known)
        if biased:
            weight = shift_weight_of(gather(temporal.x2, nb), temporal.field("ng2", nb), np.take(shared, nb),
                                     p_nb, at(p), at(ng), at(nrm), biased)
            weight *= ok
        if sel is None:
            return Candidate(temporal, nb, weight, m, p_nb, gather(ng_all, nb), nrm_nb, p_nb)
        full_nb = pix.copy()
        full_nb[sel] = nb
        full_m = np.zeros(len(pix), np.float32)
        full_m[sel] = m
        full_w = np.zeros(len(pix), np.float32)
        full_w[sel] = weight
        p_full = gather(p_all, full_nb)
        return Candidate(temporal, full_nb, full_w, full_m, p_full, gather(ng_all, full_nb),
                         gather(nrm_all, full_nb), p_full)

    for i in range(k):
        ctx.accel.poll()
        candidates.append(neighbour(i, None))
    busy = np.flatnonzero(more) if (more is not None and biased and reuse.more > 0) else ()
    for i in range(k, k + reuse.more if len(busy) else k):
        ctx.accel.poll()
        candidates.append(neighbour(i, busy))
    if not biased:
        targets = _pairwise_weights(ctx, temporal, shared, own, candidates, p, ng, nrm)

    choice, w_sum = choose([c.weight for c in candidates], samplers.uniform(seeds, D_SPATIAL))
    # The winners' samples: one gather from the temporal reservoirs (own row or
    # a neighbour's), then the rows won by last frame's spatial reservoir.
    n = b - a
    src_row = pix.copy()
    from_prev = np.zeros(n, bool)
    for c, cand in enumerate(candidates):
        won = choice == c
        if cand.source is temporal:
            src_row = np.where(won, cand.rows, src_row)
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
    res.M[:] = sum(c.M for c in candidates)

    own_visible = None
    if biased:
        finalize(res, target_at(res, p, ng, nrm), domain_confidence(res, candidates))
    else:
        # The weights are MIS weights already: W = w_sum / p_hat, with p_hat
        # the chosen candidate's target here (found above, visibility
        # included). A sample chosen has a non-zero weight, so its pixel sees it.
        p_hat = np.zeros(n, np.float32)
        for c, t in enumerate(targets):
            np.copyto(p_hat, t, where=choice == c)
        finalize(res, p_hat, np.ones(n, np.float32))
        own_visible = choice >= 0
        # res.M stays the sum of the candidates' M: a confidence that does not
        # depend on which sample was chosen.
    return res, own_visible, from_prev


def domain_confidence(res, candidates):
    """Z of the biased mode's W = w_sum / (Z p_hat): the M of the candidates
    that could have produced each row's chosen sample, by geometry alone (the
    sample and the candidate's visible point face each other and the shift
    between the pixel's and the candidate's visible points is accepted); the
    pixel's own reservoirs always count. A neighbour whose point could not
    hold the sample (near a concave corner, a sample close to the pixel
    shifts beyond J_MAX) adds nothing to Z, where 1/M counted it and
    darkened the pixel (corpus courtyard, moving camera: mean 0.995 of the
    reference with 1/M, 0.997 with Z). Visibility stays out: rays from
    every neighbour cost more than they gave (docs/validation.md)."""
    z = np.zeros(len(res.M), np.float32)
    receiver = candidates[0].owner_p
    one = np.ones(len(z), np.float32)
    for cand in candidates:
        if cand.owner_p is receiver:    # found here: the pixel's own reservoirs, temporal and carried
            z += cand.M
            continue
        live = np.flatnonzero((cand.M > 0) & res.has_sample)     # (the rest adds nothing)
        if len(live) == len(z):
            p_r, _j = shift_target(res.x2, res.ng2, one, receiver, cand.owner_p, cand.ng, cand.ns)
            z += np.where(p_r > 0, cand.M, 0.0).astype(np.float32)
        elif len(live):
            p_r, _j = shift_target(gather(res.x2, live), gather(res.ng2, live), one[live], gather(receiver, live),
                                   gather(cand.owner_p, live), gather(cand.ng, live), gather(cand.ns, live))
            z[live] += np.where(p_r > 0, cand.M[live], 0.0).astype(np.float32)
    return z


def _pairwise_weights(ctx, temporal, lum, own, candidates, p, ng, nrm):
    """Unbiased resampling weights of the own (canonical) reservoir and the
    k neighbours' (candidates[0] and candidates[1:], Candidates replaced in
    the list with their weights set) by
    pairwise MIS (Bitterli 2022, ch. 9.1.3, with confidence weights M); lum:
    sample_luminance(temporal). Returns each candidate's target at the
    receiver, visibility included.

    Each pair of the canonical reservoir c and a neighbour i is a balance
    heuristic of two techniques, the canonical one standing for M_c / k
    samples, in the receiver's solid angle (the Jacobian J of the shift
    between the two visible points), targets with visibility:

        m_i(y) = s_i M_i p_i(y) / (M_i p_i(y) + M_c/k p_c(y))
        m_c(y) = sum_i s_i (M_c/k) p_c(y) / (M_i p_i(y) + M_c/k p_c(y))
        s_i = (M_i + M_c/k) / (M_c + sum_j M_j)

    so the weights of every y sum to one over the reservoirs that can hold it
    (a neighbour that is not reused has M_i = 0), and with equal targets
    each reservoir weighs M_i / sum M. 1/Z instead gave every candidate the
    same weight however poorly its visible point sees the sample, and its
    variance outgrew what the neighbours add (courtyard: one frame's indirect
    variance with 4 neighbours 0.0073, none 0.0093). Visibility: 2k + 1 rays,
    of the canonical sample from the neighbours and every sample from the
    receiver (whose visibility of the chosen sample shading then knows)."""
    k = len(candidates) - 1
    m_c = candidates[0].M
    m_tot = m_c + sum(c.M for c in candidates[1:])
    share = m_c / np.float32(max(k, 1))
    lum_c = np.where(own.has_sample, target(own.lo), 0.0).astype(np.float32)
    pc_c = target_at(own, p, ng, nrm)
    # Every target first, then all their visibility rays in one batch.
    rays = _RayBatch(ctx)
    rays.add(p, ng, own.x2, pc_c > 0)
    terms = []
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for cand in candidates[1:]:
            nb, m_i, p_nb, ng_nb, ns_nb = cand.rows, cand.M, cand.owner_p, cand.ng, cand.ns
            x2_i, lum_i = temporal.field("x2", nb), np.take(lum, nb)
            # The neighbour's sample here (J: its shift from there to here) ...
            pc_i, j_ic = shift_target(x2_i, temporal.field("ng2", nb), lum_i, p_nb, p, ng, nrm)
            pc_i = np.where(m_i > 0, pc_i, 0.0)
            # ... at its own visible point (found from there: seen) ...
            to = x2_i - p_nb
            cos_i = np.maximum(dot(to, ns_nb), 0.0) / np.sqrt(np.maximum(dot(to, to), 1e-30))
            n_i = m_i * lum_i * cos_i / np.where(j_ic > 0, j_ic, 1.0)
            # ... and the canonical sample at the neighbour's visible point.
            pi_c, j_ci = shift_target(own.x2, own.ng2, lum_c, p, p_nb, ng_nb, ns_nb)
            pi_c = np.where((m_i > 0) & (pc_c > 0), pi_c, 0.0)
            rays.add(p, ng, x2_i, pc_i > 0)
            rays.add(p_nb, ng_nb, own.x2, pi_c > 0)
            terms.append((m_i, temporal.field("W", nb), pc_i, j_ic, n_i, pi_c * j_ci))
        seen = rays.trace()
        pc_c = np.where(seen[0], pc_c, 0.0).astype(np.float32)
        c_c = share * pc_c
        own_mis = np.zeros(len(p), np.float32)
        targets = [pc_c]
        for i, (m_i, w_i, pc_i, j_ic, n_i, pi_c) in enumerate(terms, 1):
            s_i = (m_i + share) / np.maximum(m_tot, 1e-30)
            pc_i = np.where(seen[2 * i - 1], pc_i, 0.0)
            targets.append(pc_i)
            c_i = share * pc_i
            m_mis = np.where(c_i > 0, s_i * n_i / (n_i + c_i), 0.0)
            candidates[i] = candidates[i]._replace(weight=(m_mis * pc_i * w_i * j_ic).astype(np.float32))
            pi_c = np.where(seen[2 * i], pi_c, 0.0)
            own_mis += np.where(c_c > 0, s_i * c_c / (c_c + m_i * pi_c), 0.0).astype(np.float32)
        own_w = np.where(own.W > 0, own_mis * pc_c * own.W, 0.0)
    candidates[0] = candidates[0]._replace(weight=own_w.astype(np.float32))
    return targets


class _RayBatch:
    """Visibility between points x1 and sample points x2 for the rows of
    several sets, traced in one query."""

    def __init__(self, ctx):
        self.ctx, self.sets = ctx, []

    def add(self, x1, ng1, x2, where):
        rows = np.nonzero(where)[0]
        to = gather(x2, rows) - gather(x1, rows)
        dist = np.sqrt(np.maximum(dot(to, to), 1e-30))
        self.sets.append((len(where), rows, gather(x1, rows), gather(ng1, rows),
                          scale(to, 1.0 / dist).astype(np.float32), dist))

    def trace(self):
        """One (n,) bool array per set: True where x1 sees x2 (False where not asked)."""
        cat = [np.concatenate([s[i] for s in self.sets]) for i in range(2, 6)]
        seen = ~self.ctx.accel.occluded(*shadow_rays(self.ctx, *cat)) if len(cat[0]) else np.zeros(0, bool)
        out, start = [], 0
        for n, rows, *_rest in self.sets:
            v = np.zeros(n, bool)
            v[rows] = seen[start:start + len(rows)]
            start += len(rows)
            out.append(v)
        return out
