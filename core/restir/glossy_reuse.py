"""The glossy lobe's indirect light, reused over neighbouring pixels (path reuse).

Reservoirs carry the diffuse lobe only (initial.py): a neighbour's sample
resampled for a glossy lobe lands where the lobe is peaked or empty. Without
reuse, a glossy pixel's indirect light is its own one-path estimate, about
three quarters of a glossy interior's frame variance (bench/glossy_lobe.py).

A pixel's glossy light from samples its specular lobe drew is the integral
over sample points y of

    h_i(y) = f_g(x1_i, y) |cos_i| G(x1_i, y) Lo(y) V(x1_i, y) q_i(y)

with f_g the specular lobe, G the reconnection's geometry term |cos at y| /
d^2, Lo the path-traced radiance of y and q_i the share of the pixel's
direction sampler that its specular lobe has toward y (the path tracer
counts such a path's bounces as glossy; the share drawn by the diffuse lobe
stays the pixel's own estimate, initial.py). Each receiver i estimates it
from its own such sample and those of K neighbours j at fixed offsets (the
four adjacent pixels), as
sampling techniques of one integral, each of area density p_j(y) (the
neighbour's specular lobe's density through the reconnection Jacobian,
times the visibility of y from x1_j: a sampler reaches only what it sees,
and only from the side its sample was found from). Pairwise MIS (Bitterli's
thesis, 9.1.3), each neighbour paired with the pixel's own technique c:

    own sample:        h_i(y_c) / K sum_j 1 / (K p_j(y_c) + p_c(y_c))
    neighbour j's:     h_i(y_j) / (K p_j(y_j) + p_c(y_j))

(K = 0: h_i / p_c, the pixel's own estimate). Two shadow rays per pair, not
the K (K + 1) of the balance heuristic over all techniques, whose variance
was 13 % lower for 2.7 times the cost (glossy interior, 3 px). Unbiased
where y's radiance does not depend on the direction it leaves in, as for
the reservoirs' reconnection shift; sky samples stay each pixel's own.

Pixels whose sampler has a glass or sheen lobe (initial.path_reused) take
no part: they neither give samples nor count as techniques, and keep their
own estimate. Everything is a function of this frame's whole-image samples,
so images do not depend on how rows are split between workers.
"""

from dataclasses import dataclass

import numpy as np

from ..bsdfs import bsdf
from ..integrators.base import shadow_rays
from ..util.rows import gather, row_max, scale, scatter, scatter_add
from ..sampling.warps import INV_PI
from ..util.vectors import dot, orthonormal_basis, to_local
from .initial import path_reused

# The 4 adjacent pixels. One frame's indirect variance on the glossy interior
# (bench/glossy_lobe.py's split, one worker), none 0.333; 4 at 1 px 0.111,
# 4 diagonal 0.115, 4 at 2 px 0.118, 4 at 3 px 0.130, for the same time;
# 8 at 1 px 0.086 and 8 at 3 px 0.111 for twice that: no better for the time.
OFFSETS = ((-1, 0), (1, 0), (0, -1), (0, 1))


@dataclass
class GlossySamples:
    """Whole-image rows: what path reuse reads of each pixel's sampler and of
    its first initial sample (written by the frame's first pass)."""
    wo: np.ndarray          # (P, 3) toward the camera from the visible point
    alpha: np.ndarray       # (P,) GGX alpha of its specular lobe
    p_spec: np.ndarray      # (P,) probability that its sampler draws from that lobe toward wo
                            # (0 below the shading normal); -1: the pixel takes no part
    f0: np.ndarray          # (P, 3)
    f90: np.ndarray         # (P, 3)
    f_exact: np.ndarray     # (P, 3) the share rising by the exact dielectric curve ...
    spec_ior: np.ndarray    # (P,) ... of this IOR (BSDFParams)
    x2: np.ndarray          # (P, 3) sample point
    ng2: np.ndarray         # (P, 3) its geometric normal (facing the pixel's visible point)
    lo: np.ndarray          # (P, 3) its radiance toward the visible point
    has: np.ndarray         # (P,) bool: a sample on a surface, drawn by the specular lobe

    @staticmethod
    def allocate(n):
        vec = lambda: np.empty((n, 3), np.float32)  # noqa: E731
        return GlossySamples(vec(), np.empty(n, np.float32), np.empty(n, np.float32), vec(), vec(), vec(),
                             np.empty(n, np.float32), vec(), vec(), vec(), np.empty(n, bool))

    @staticmethod
    def of_range(gb, res):
        """The rows of a G-buffer part and its first initial samples ``res``
        (read before anything merges into them; their kinds must be set)."""
        n = len(gb.valid)
        out = GlossySamples(np.zeros((n, 3), np.float32), np.zeros(n, np.float32), np.full(n, -1.0, np.float32),
                            np.zeros((n, 3), np.float32), np.ones((n, 3), np.float32),
                            np.zeros((n, 3), np.float32), np.ones(n, np.float32), res.x2.copy(),
                            res.ng2.copy(), res.lo.copy(), np.zeros(n, bool))
        idx = gb.index
        if len(idx) == 0:
            return out
        params = gb.frame.params
        rows = np.nonzero(path_reused(params))[0]
        pix = idx[rows]
        scatter(out.wo, pix, gather(gb.surf.wo, rows))
        out.alpha[pix] = np.take(params.alpha, rows)
        out.p_spec[pix] = np.take(params.p_spec, rows) * (np.take(gb.frame.wo_local[:, 2], rows) > 0)
        scatter(out.f0, pix, gather(params.f0, rows))
        if params.f90 is not None:
            scatter(out.f90, pix, gather(params.f90, rows))
        if params.f_exact is not None:
            scatter(out.f_exact, pix, gather(params.f_exact, rows))
            out.spec_ior[pix] = np.take(params.spec_ior, rows)
        out.has = res.has_sample & (res.prim2 >= 0) & (res.kind == bsdf.KIND_GLOSSY) & (out.p_spec > 0)
        return out


def _shift(pix, dx, dy, width, height):
    """Pixel indices moved by (dx, dy); -1 outside the image."""
    x, y = pix % width + dx, pix // width + dy
    inside = (x >= 0) & (x < width) & (y >= 0) & (y < height)
    return np.where(inside, y * width + x, -1)


def _lobe_terms(img, gs, pix, samples, with_f):
    """Pixels pix toward the sample points of pixels ``samples``: (h, p).
    h (with_f; else None) is the integrand without visibility: f of the
    specular lobe, cosine, geometry term, the sample's radiance and the
    share of the pixel's sampler that the lobe has in that direction. p is
    the density of that lobe's samples per area at those points, zero where
    the pixels cannot reach them (below their surface as their shading
    frame sees it, or on the far side of the sample's surface)."""
    n = img.n[pix]
    t, b = orthonormal_basis(n)     # the first pass's shading frames (ShadingFrame.at)
    q = np.take(gs.p_spec, pix)
    params = bsdf.BSDFParams(np.zeros((len(pix), 3), np.float32), gather(gs.f0, pix), np.take(gs.alpha, pix),
                             (q > 0).astype(np.float32), gather(gs.f90, pix),
                             f_exact=gather(gs.f_exact, pix), spec_ior=np.take(gs.spec_ior, pix))
    wo_l = to_local(gather(gs.wo, pix), t, b, n).astype(np.float32)
    to = gs.x2[samples] - img.p[pix]
    d2 = np.maximum(dot(to, to), np.float32(1e-30))
    wi = scale(to, 1.0 / np.sqrt(d2)).astype(np.float32)
    wi_l = to_local(wi, t, b, n).astype(np.float32)
    ng2 = gs.ng2[samples]
    ok = ((dot(wi, img.ng[pix]) > 0) == (wi_l[:, 2] > 0)) & (dot(wi, ng2) < 0)
    geometry = np.where(ok, np.abs(dot(wi, ng2)) / d2, 0.0).astype(np.float32)
    # The lobe alone (its p_spec set to 1), times q.
    f, p_lobe = bsdf.evaluate_pdf(params, wo_l, wi_l) if with_f else (None, bsdf.pdf(params, wo_l, wi_l))
    p_spec = q * p_lobe
    if with_f:
        p_all = (1.0 - q) * np.maximum(wi_l[:, 2], 0.0) * INV_PI + p_spec
        share = np.where(p_all > 0, p_spec / np.where(p_all > 0, p_all, 1.0), 0.0)
        f = scale(f * gs.lo[samples], (np.abs(wi_l[:, 2]) * geometry * share).astype(np.float32))
    return f, (p_spec * geometry).astype(np.float32)


def _visible(ctx, img, gs, pix, samples):
    """True where pixel pix's visible point sees the sample point of ``samples``."""
    x1 = img.p[pix]
    to = gs.x2[samples] - x1
    dist = np.sqrt(np.maximum(dot(to, to), np.float32(1e-30)))
    wi = scale(to, 1.0 / dist).astype(np.float32)
    return ~ctx.accel.occluded(*shadow_rays(ctx, x1, img.ng[pix], wi, dist.astype(np.float32)))


def _with_visibility(ctx, img, gs, pix, samples, values):
    """values where the pixels pix see the samples' points, zero elsewhere
    (rays only where values are not zero)."""
    live = np.nonzero(row_max(values) > 0 if values.ndim == 2 else values > 0)[0]
    if len(live):
        blocked = ~_visible(ctx, img, gs, pix[live], samples[live])
        values[live[blocked]] = 0
    return values


def _pair_density(k, p_j, p_c):
    """The density a pair of techniques (neighbour j and the pixel's own c,
    one of k pairs) weighs a sample by: K p_j + p_c, so that the weights of
    all techniques sum to one at every point."""
    return k * p_j + p_c


def reuse_glossy(ctx, img, gs, start, stop, offsets=OFFSETS):
    """(stop - start, 3) the glossy lobe's light at the pixels [start, stop)
    from the samples their specular lobes and those of their neighbours at
    ``offsets`` drew. img: the frame's whole-image visible points
    (FrameImage); gs: its GlossySamples."""
    out = np.zeros((stop - start, 3), np.float32)
    recv = start + np.nonzero(gs.p_spec[start:stop] > 0)[0]
    if len(recv) == 0:
        return out
    # Samples without radiance add nothing whatever their weights: only the
    # others are read (about 60 % of the glossy interior's are dark).
    has = gs.has & (row_max(gs.lo) > 0)
    # Each receiver's neighbour techniques: pixels that take part and whose
    # specular lobe can draw (-1: none, or outside the image).
    tech = []
    for dx, dy in offsets:
        q = _shift(recv, dx, dy, img.width, img.height)
        tech.append(np.where((q >= 0) & (np.take(gs.p_spec, np.maximum(q, 0)) > 0), q, -1))
    k = sum(((t >= 0).astype(np.float32) for t in tech), np.zeros(len(recv), np.float32))
    # Each sample's density under its own technique, computed once.
    reads = np.unique(np.concatenate([recv] + tech))
    reads = reads[(reads >= 0) & np.take(has, np.maximum(reads, 0))]
    own_density = _lobe_terms(img, gs, reads, reads, False)[1]

    def p_own(j):
        return np.take(own_density, np.searchsorted(reads, j))

    tiny = np.float32(1e-30)
    mine = np.nonzero(np.take(has, recv))[0]
    if len(mine):       # the pixel's own sample: h / K sum_j 1 / (K p_j V_j + p_c)
        i, kk = recv[mine], k[mine]
        p_c = p_own(i)
        acc = np.zeros(len(mine), np.float32)
        for t in tech:
            r = np.nonzero(t[mine] >= 0)[0]
            lobe = t[mine][r]
            p_j = _with_visibility(ctx, img, gs, lobe, i[r], _lobe_terms(img, gs, lobe, i[r], False)[1])
            acc[r] += 1.0 / np.maximum(_pair_density(kk[r], p_j, p_c[r]), tiny)
        weight = np.where(kk > 0, acc / np.maximum(kk, 1.0), 1.0 / np.maximum(p_c, tiny))
        h = _lobe_terms(img, gs, i, i, True)[0]
        scatter_add(out, i - start, scale(h, np.where(p_c > 0, weight, 0.0).astype(np.float32)))
    for t in tech:      # each neighbour's sample: h V_c / (K p_j + p_c V_c)
        r = np.nonzero((t >= 0) & np.take(has, np.maximum(t, 0)))[0]
        if len(r) == 0:
            continue
        i, j = recv[r], t[r]
        h, p_c = _lobe_terms(img, gs, i, j, True)
        h = _with_visibility(ctx, img, gs, i, j, h)
        den = _pair_density(k[r], p_own(j), np.where(row_max(h) > 0, p_c, 0.0))
        scatter_add(out, i - start, scale(h, (1.0 / np.maximum(den, tiny)).astype(np.float32)))
    return np.nan_to_num(out, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
