"""What every integrator shares: the render context and the stages that trace
shadow rays for next-event estimation and continue paths by BSDF sampling."""

from dataclasses import dataclass

import numpy as np

from ..bsdfs import bsdf
from ..materials import shading as materials
from ..sampling import samplers
from . import terminator, transparency
from ..geometry.accel import Accel, offset_origins
from ..lights.light_set import INF_DIST, LightSet
from ..workers.parallel import SERIAL, Workers
from ..util.rows import gather, row_max, rows_finite, scale, scatter
from ..util.vectors import dot, orthonormal_basis, to_local, to_world
from ..sampling.warps import power_heuristic

RAY_EPS_RELATIVE = 1e-5     # origin offset relative to the scene's extent


@dataclass
class RenderContext:
    """A scene made ready for tracing: acceleration structure, lights, ray offset."""
    scene: object
    accel: Accel
    lights: LightSet
    eps: float
    workers: Workers = SERIAL   # threads for whole-image passes (core/workers/parallel.py)

    @staticmethod
    def build(scene, threads=None, processes=True):
        """processes: passes may run their second range in a forked child
        (core/workers/parallel.py); False keeps them on threads."""
        eps = RAY_EPS_RELATIVE * scene.extent()
        accel = transparency.wrap(Accel.from_scene(scene, threads), scene)
        return RenderContext(scene, accel, LightSet(scene), eps, Workers(threads, processes=processes))

    def close(self):
        self.accel.close()
        if self.workers is not SERIAL:
            self.workers.close()


@dataclass
class ShadingFrame:
    """BSDF parameters and the local frame at a batch of surface hits."""
    params: bsdf.BSDFParams
    t: np.ndarray
    b: np.ndarray
    wo_local: np.ndarray

    @staticmethod
    def at(scene, surf, camera_ray=False):
        """Materials evaluated at the hits (core/materials/shading.py; normal maps
        and bump replace ``surf.ns``) and the local frame of their normals."""
        params = materials.surface_params(scene, surf, camera_ray)
        t, b = orthonormal_basis(surf.ns)
        if params.smooth_n is not None:     # normals bent by maps: the smooth one, locally
            params.smooth_n = to_local(params.smooth_n, t, b, surf.ns).astype(np.float32)
        wo_local = to_local(surf.wo, t, b, surf.ns)
        if params.has_glass:    # the IOR as the ray meets it: inverted leaving the object
            params.eta = np.where(surf.front, params.ior, 1.0 / params.ior).astype(np.float32)
        bsdf.at_view(params, wo_local)
        return ShadingFrame(params, t, b, wo_local)

    def subset(self, index):
        return ShadingFrame(self.params.subset(index), gather(self.t, index), gather(self.b, index),
                            gather(self.wo_local, index))

    def local(self, surf, w):
        return to_local(w, self.t, self.b, surf.ns)

    def world(self, surf, w_local):
        return to_world(w_local, self.t, self.b, surf.ns).astype(np.float32, copy=False)


def direct_light(ctx, surf, frame, seeds, bounce, mis=True, strategy_pdf=None, u_light=None,
                 weigh=None, count=None, media=None, lights=None):
    """Next-event estimation at surface hits: one light sample and one shadow ray each.

    Returns the reflected radiance toward wo, (N, 3). With ``mis`` the sample is
    weighted against BSDF sampling by the power heuristic; without it (a path's
    last vertex, whose BSDF ray is never traced) it has weight one.
    strategy_pdf(wi_local) gives the pdf of the direction sampler it is weighted
    against, when that is not the BSDF's own (ReSTIR's uniform initial samples).
    u_light: (u_select, u) to use instead of the seeds' own light dimensions.
    weigh(ls, wi_local, f, w) -> (N, 3): f weighted, in place of f x w (ReSTIR
    splits the world's light between NEE and its reservoirs lobe by lobe).
    count: (N,) light samples each point takes, of which this is one: the
    MIS weights count them all (count x pdf) against the one BSDF sample.
    media: core.integrators.media.Media whose transmittance the shadow rays carry.
    lights: the light set to sample (default ctx.lights; one of its nee_sets).
    """
    n = len(surf)
    out = np.zeros((n, 3), np.float32)
    lights = ctx.lights if lights is None else lights
    if n == 0 or lights.count == 0:
        return out
    if u_light is None:
        u_sel = samplers.uniform(seeds, samplers.bounce_dim(bounce, samplers.D_LIGHT_SELECT))
        u = samplers.uniform2(seeds, samplers.bounce_dim(bounce, samplers.D_LIGHT_UV))
    else:
        u_sel, u = u_light
    ls = lights.sample(surf.p, u_sel, u, surf.ns)
    wi_local = frame.local(surf, ls.wi)
    delta = mis and ls.delta.all()      # lights of no extent only (a sun of zero angle): weight one
    if mis and strategy_pdf is None and not delta:
        f, pdf_b = bsdf.evaluate_pdf(frame.params, frame.wo_local, wi_local)
    else:
        f = bsdf.evaluate(frame.params, frame.wo_local, wi_local)
        pdf_b = strategy_pdf(wi_local) if mis and not delta else None
    hidden = getattr(lights, "hidden_kinds", None)
    if hidden is not None and ls.index is not None:
        f = _without_hidden_lobes(frame, wi_local, f, np.take(hidden, ls.index, axis=0))
    # The light must lie on the side of the surface the lobe sends it to:
    # geometric and shading normals agree (only glass lobes refract) ...
    cos = np.abs(wi_local[:, 2])
    ngl = dot(ls.wi, surf.ng)
    above = (ngl > 0) == (wi_local[:, 2] > 0)
    cutoff = float(getattr(ctx.scene, "shadow_terminator", 0.0))
    lifted = cutoff > 0 and surf.bary is not None
    if lifted:
        # ... or, on smooth-shaded triangles, a light the shading normal
        # faces below the triangle's plane: the shadow ray from the smooth
        # surface decides (terminator.py; the triangle itself may block it).
        above |= (ngl <= 0) & (wi_local[:, 2] > 0)
    if mis and not delta:
        w = np.where(ls.delta, 1.0, power_heuristic(ls.pdf if count is None else ls.pdf * count, pdf_b))
    else:
        w = np.ones(n, np.float32)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        if weigh is None:
            contrib = scale(f * ls.radiance, cos * w / np.where(ls.pdf > 0, ls.pdf, 1.0))
        else:
            contrib = scale(weigh(ls, wi_local, f, w) * ls.radiance, cos / np.where(ls.pdf > 0, ls.pdf, 1.0))
    live = above & (ls.pdf > 0) & (row_max(contrib) > 0) & rows_finite(contrib)
    rows = np.nonzero(live)[0]
    if len(rows) == 0:
        return out
    free = getattr(lights, "shadowless", None)
    if free is not None and ls.index is not None:   # lights with Cast Shadow off: no shadow rays
        test = ~np.take(free, np.take(ls.index, rows))
        lit = rows[~test]
        rows = rows[test]
    else:
        lit = rows[:0]
    if len(rows):
        blocked = _occluded(ctx, surf, ls, rows, cutoff if lifted else 0.0)
        lit = np.concatenate([lit, rows[~blocked]]) if len(lit) else rows[~blocked]
    if media is not None and len(lit):
        tr = media.along(*shadow_rays(ctx, gather(surf.p, lit), gather(surf.ng, lit), gather(ls.wi, lit),
                                      ls.dist[lit])).transmittance()
        return scatter(out, lit, gather(contrib, lit) * tr)
    return scatter(out, lit, gather(contrib, lit))


def _occluded(ctx, surf, ls, rows, cutoff):
    """(K,) bool: the light samples ``rows`` are blocked, seen from the hits
    or, near the terminator of smooth-shaded triangles (cutoff > 0:
    terminator.py), from the smooth surface. A light below a triangle's
    plane is tested from the lifted point, its own triangle included; where
    nothing lifts the point above the plane (a flat triangle whose normal
    map faces the light) it stays blocked, as the triangle blocks it there."""
    p, ng, wi = gather(surf.p, rows), gather(surf.ng, rows), gather(ls.wi, rows)
    dist = ls.dist[rows]
    under = dot(ng, wi) <= 0
    amount = terminator.amounts(gather(surf.ns, rows), ng, wi, cutoff) if cutoff > 0 else None
    some = np.zeros(0, np.int64) if amount is None else np.nonzero(amount > 0)[0]
    if len(some) == 0:
        if not under.any():
            return ctx.accel.occluded(*shadow_rays(ctx, p, ng, wi, dist))
        lift = np.zeros_like(p)
    else:
        lift = np.zeros_like(p)
        lift[some] = scale(terminator.smooth_lift(ctx.scene, gather(surf.prim, rows[some]),
                                                  gather(surf.bary, rows[some]), ng[some]), amount[some])
    blocked = under & ~(dot(lift, ng) > ctx.eps)
    trace = np.nonzero(~blocked)[0]
    if len(trace):
        blocked[trace] = ctx.accel.occluded(*shadow_rays(ctx, p[trace], ng[trace], wi[trace], dist[trace],
                                                         lift=lift[trace], up=under[trace]))
    return blocked


def _without_hidden_lobes(frame, wi_local, f, hidden):
    """f again, for the rows whose light is hidden from some kinds of bounce
    (hidden: (N, 3) diffuse, glossy, transmission), without those lobes."""
    rows = np.nonzero(hidden.any(axis=1))[0]
    if len(rows) == 0:
        return f
    params = bsdf.without_lobes(frame.params.subset(rows), hidden[rows])
    f = np.array(f, np.float32)
    scatter(f, rows, bsdf.evaluate(params, gather(frame.wo_local, rows), gather(wi_local, rows)))
    return f


def shadow_rays(ctx, p, ng, wi, dist, lift=None, up=None):
    """Shadow rays from surface points toward light points at ``dist`` along wi.

    The origin moves off the surface, so the direction is re-aimed from the moved
    origin at the light point: at grazing angles the unmoved direction would
    cross the light's plane early and hit the emitter itself. lift: (N, 3)
    added to the origins first (terminator.py); up: (N,) bool, rows whose
    origin moves off to the side of ng even where wi points below it (their
    own triangle may block them). Returns (origins, directions, tmax) for
    ``Accel.occluded``.
    """
    start = p if lift is None else (p + lift).astype(np.float32)
    o = offset_origins(start, ng, wi, ctx.eps)
    if up is not None and up.any():
        o[up] = start[up] + np.float32(ctx.eps) * ng[up]
    finite = dist < INF_DIST
    if not finite.any():    # lights at infinity only (suns, the world): along wi, unbounded
        return o, wi.astype(np.float32), np.full(len(o), INF_DIST, np.float32)
    target = p + wi * np.where(finite, dist, 0.0)[:, None]
    d = target - o
    length = np.sqrt(dot(d, d))
    d = np.where((finite & (length > 0))[:, None], scale(d, 1.0 / np.maximum(length, 1e-30)), wi)
    tmax = np.where(finite, np.maximum(length * (1.0 - 1e-4) - ctx.eps, 0.0), INF_DIST)
    return o, d.astype(np.float32), tmax.astype(np.float32)


def sample_continuation(ctx, surf, frame, seeds, bounce, kinds=False, u=None):
    """BSDF-sample one new direction per hit (u: (u_lobe, u) to use instead
    of the seeds' own).

    Returns (wi world (N, 3), weight f cos / pdf (N, 3), pdf (N,), valid (N,)
    bool), and with ``kinds`` also each ray's kind of bounce (N,) int8
    (bounces.py).
    """
    if u is None:
        u_lobe = samplers.uniform(seeds, samplers.bounce_dim(bounce, samplers.D_LOBE))
        u = samplers.uniform2(seeds, samplers.bounce_dim(bounce, samplers.D_BSDF_UV))
    else:
        u_lobe, u = u
    wi_local, f, pdf = bsdf.sample(frame.params, frame.wo_local, u_lobe, u)
    wi = frame.world(surf, wi_local)
    cos = np.abs(wi_local[:, 2])
    # Reflections stay above the surface, refractions (glass) go below it.
    valid = (pdf > 0) & ((dot(wi, surf.ng) > 0) == (wi_local[:, 2] > 0))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        weight = scale(f, cos / np.where(pdf > 0, pdf, 1.0))
    valid &= rows_finite(weight) & (row_max(weight) > 0)
    weight = scale(np.nan_to_num(weight, copy=False), valid.astype(np.float32)).astype(np.float32, copy=False)
    if kinds:
        return wi, weight, pdf, valid, bsdf.sampled_kinds(frame.params, frame.wo_local, wi_local, u_lobe)
    return wi, weight, pdf, valid
