"""Path tracing through homogeneous media (core/integrators/media.py): the camera pass's
paths when the scene has volumes.

The same wavefront as path.py, with a second kind of vertex: along every
segment a free-flight distance is drawn (media.Intervals.sample); a path
that scatters in a medium gets a medium vertex there, with next-event
estimation through the Henyey-Greenstein phase function (MIS against
sampling the phase function) and a continuation drawn from it. Shadow rays
of both kinds of vertex carry the media's transmittance, and emission of the
media along each segment is added in closed form.

Bounces: a medium vertex is a bounce of the total, and counts as a volume
bounce; as in Cycles, the ray from a medium vertex whose volume bounces
exceed the limit (``max_bounces.volume``, Cycles' Light Paths > Volume, 0 by
default: light scattered once) is still traced for the emission it finds
(the world, lamps, emitters: MIS against the vertex's light sample), and
the path ends there; it is attenuated by the media on its way, and does not
scatter again.

Approximated: an analytic light a BSDF or phase ray crosses (a sphere or
area lamp hit by chance) is weighted by the ray's transmittance to the end
of its segment, not to the lamp; world volumes are not rendered.
"""

import numpy as np

from ..materials import shading as materials
from ..sampling import samplers
from ..geometry.accel import RayHits, offset_origins
from ..geometry.interaction import surface_hits
from .media import hg_pdf, hg_sample
from ..util.rows import gather, row_max, scale, scatter_add
from ..util.vectors import dot
from ..sampling.warps import power_heuristic
from .base import ShadingFrame, direct_light, sample_continuation, shadow_rays
from .bounces import count, per_kind

RR_START_BOUNCE = 3
D_MEDIUM = 1 << 14          # dimensions of the media's samples, past the bounces' blocks


def _dim(bounce, k):
    return D_MEDIUM + 8 * bounce + k


def volume_limit(max_bounces):
    v = getattr(max_bounces, "volume", None)
    return int(max_bounces) if v is None else int(v)


def _medium_light(ctx, media, p, d, g, seeds, bounce):
    """Next-event estimation at medium points p (N, 3) reached along d
    (N, 3), anisotropy g (N,): (N, 3) radiance scattered toward -d per unit
    of the scattering coefficient (the caller's weight holds sigma_s); one
    sample of each of the lights' nee_sets, summed."""
    out = np.zeros((len(p), 3), np.float32)
    for lights in ctx.lights.nee_sets():
        out += _medium_light_of(ctx, lights, media, p, d, g, seeds, bounce)
    return out


def _medium_light_of(ctx, lights, media, p, d, g, seeds, bounce):
    """_medium_light's sample of one light set."""
    n = len(p)
    out = np.zeros((n, 3), np.float32)
    if n == 0 or lights.count == 0:
        return out
    u_sel = samplers.uniform(seeds, samplers.bounce_dim(bounce, samplers.D_LIGHT_SELECT))
    u = samplers.uniform2(seeds, samplers.bounce_dim(bounce, samplers.D_LIGHT_UV))
    ls = lights.sample(p, u_sel, u, None)
    f = hg_pdf(dot(d, ls.wi), g)
    w = np.where(ls.delta, 1.0, power_heuristic(ls.pdf, f))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        contrib = scale(ls.radiance, f * w / np.where(ls.pdf > 0, ls.pdf, 1.0))
    rows = np.nonzero((ls.pdf > 0) & (row_max(contrib) > 0) & np.isfinite(contrib).all(axis=1))[0]
    if len(rows) == 0:
        return out
    o, dd, tmax = shadow_rays(ctx, gather(p, rows), gather(ls.wi, rows), gather(ls.wi, rows), ls.dist[rows])
    blocked = ctx.accel.occluded(o, dd, tmax)
    tr = media.along(o, dd, tmax).transmittance()
    keep = ~blocked
    scatter_add(out, rows[keep], gather(contrib, rows[keep]) * tr[keep])
    return out


def _by_origin(fn, prev_n, from_medium, rows):
    """fn(k, n) for the rows (indices into the batch) that left surfaces
    (n: their normals) and for those that left medium points (n None, as
    NEE sampled from them), joined in the order of rows; k: positions in
    rows. fn returns arrays of len(k) rows."""
    med = from_medium[rows]
    k = np.arange(len(rows))
    if not med.any():
        return fn(k, gather(prev_n, rows))
    if med.all():
        return fn(k, None)
    a, b = k[~med], k[med]
    ra, rb = fn(a, gather(prev_n, rows[a])), fn(b, None)
    out = np.zeros((len(rows),) + ra.shape[1:], ra.dtype)
    out[a], out[b] = ra, rb
    return out


def camera_radiance(ctx, media, o, d, tmax, hits, seeds, max_bounces):
    """(N, 3) radiance along camera rays (o, d, tmax) whose closest hits are
    ``hits``, through the scene's media."""
    # Suns apart (LightSet.nee_sets): NEE sums a sample of each set; what
    # rays find is weighed against the first.
    scene, nee = ctx.scene, ctx.lights.nee_sets()
    lights = nee[0]
    n = len(o)
    L = np.zeros((n, 3), np.float32)
    limits = np.asarray(per_kind(max_bounces), np.int16)
    vlimit = volume_limit(max_bounces)
    alive = np.nonzero(tmax > 0)[0]
    o, d, tmax = o[alive], d[alive], tmax[alive]
    hit_rows = hits.hit[alive]
    prim, hu, hv = hits.prim[alive], hits.u[alive], hits.v[alive]
    t_end = np.where(hit_rows, hits.t[alive], np.inf).astype(np.float64)
    beta = np.ones((len(alive), 3), np.float32)
    pdf = prev_p = prev_n = from_medium = None           # camera rays: no MIS
    counts = np.zeros((len(alive), 3), np.int16)
    vcount = np.zeros(len(alive), np.int32)
    final = np.zeros(len(alive), bool)
    for bounce in range(int(max_bounces) + 2):
        if len(alive) == 0:
            break
        s = seeds[alive]
        iv = media.along(o, d, t_end)
        scatter_add(L, alive, beta * iv.emission())
        scat, ts, w, ss, g = iv.sample(samplers.uniform(s, _dim(bounce, 0)), samplers.uniform(s, _dim(bounce, 1)))
        beta = beta * w
        seg_end = np.where(scat, ts, t_end)
        # What the segment's end gives: lamps crossed, the world, emitters hit.
        camera = pdf is None
        if lights.n_analytic and lights.analytic.crossable():
            if camera:
                scatter_add(L, alive, beta * lights.emitted_along(o, d, seg_end.astype(np.float32)))
            else:
                every = np.arange(len(alive))
                crossed = _by_origin(lambda k, nn: lights.emitted_along(
                    gather(o, k), gather(d, k), seg_end[k].astype(np.float32), pdf_bsdf=pdf[k],
                    p=gather(prev_p, k), n=nn), prev_n, from_medium, every)
                scatter_add(L, alive, beta * crossed)
        miss = np.nonzero(~scat & ~hit_rows)[0]
        if len(miss) and lights.environment is not None:
            if camera:
                if not scene.film_transparent:
                    scatter_add(L, alive[miss], gather(beta, miss) * lights.world_radiance(gather(d, miss),
                                                                                           camera=True))
            else:
                wgt = power_heuristic(pdf[miss], _by_origin(lambda k, nn: lights.pdf_world(gather(d, miss[k]), nn),
                                                            prev_n, from_medium, miss))
                scatter_add(L, alive[miss], scale(gather(beta, miss) * lights.world_radiance(gather(d, miss)), wgt))
        on_surface = ~scat & hit_rows
        sub = np.nonzero(on_surface)[0]
        surf = None
        if len(sub):
            sh = RayHits(t_end[sub].astype(np.float32), prim[sub], hu[sub], hv[sub])
            surf, _ = surface_hits(scene, gather(o, sub), gather(d, sub), sh)
            if camera:
                scatter_add(L, alive[sub], gather(beta, sub) * materials.camera_emission(scene, surf, lights))
            elif len(lights.tri_index) or materials.shading(scene).emitting:
                le = materials.surface_emission(scene, surf, lights)
                em = np.nonzero(row_max(le) > 0)[0]
                if len(em):
                    rows_em = sub[em]
                    pdf_l = _by_origin(lambda k, nn: lights.pdf_triangle(
                        surf.prim[em[k]], gather(prev_p, rows_em[k]), gather(surf.p, em[k]),
                        -gather(surf.wo, em[k]), nn), prev_n, from_medium, rows_em)
                    wgt = power_heuristic(pdf[sub[em]], pdf_l)
                    scatter_add(L, alive[sub[em]], scale(gather(beta, sub[em]) * gather(le, em), wgt))
        if bounce > int(max_bounces):
            break
        go_s = ~final[sub] if len(sub) else np.zeros(0, bool)
        sub, surf = sub[go_s], (surf.subset(go_s) if surf is not None else None)
        med = np.nonzero(scat & ~final)[0]
        # Surface vertices.
        parts = []
        if len(sub):
            frame = ShadingFrame.at(scene, surf, camera_ray=camera)
            b_s = gather(beta, sub)
            for sets in nee:
                scatter_add(L, alive[sub], b_s * direct_light(ctx, surf, frame, s[sub], bounce, media=media,
                                                              lights=sets))
            wi, weight, pdf_s, valid, kinds = sample_continuation(ctx, surf, frame, s[sub], bounce, kinds=True)
            b_s = b_s * weight
            c = counts[sub]
            over = count(c, kinds, limits)
            counts[sub] = c
            keep = np.nonzero(valid)[0]
            parts.append((sub[keep], offset_origins(gather(surf.p, keep), gather(surf.ng, keep), gather(wi, keep),
                                                   ctx.eps), gather(wi, keep), gather(b_s, keep), pdf_s[keep],
                          gather(surf.p, keep), gather(surf.ns, keep), over[keep]))
        # Medium vertices.
        if len(med):
            p = (gather(o, med) + gather(d, med) * ts[med, None]).astype(np.float32)
            dm, gm = gather(d, med), g[med]
            b_m = gather(beta, med)
            scatter_add(L, alive[med], b_m * _medium_light(ctx, media, p, dm, gm, s[med], bounce))
            vcount[med] += 1
            over = vcount[med] > vlimit         # traced for the emission it finds, then the path ends
            u = np.stack([samplers.uniform(s[med], _dim(bounce, 2)), samplers.uniform(s[med], _dim(bounce, 3))], 1)
            wi, pdf_m = hg_sample(dm, gm, u)
            keep = np.nonzero(pdf_m > 0)[0]
            parts.append((med[keep], gather(p, keep), gather(wi, keep), gather(b_m, keep), pdf_m[keep],
                          gather(p, keep), None, over[keep]))
        if not parts:
            break
        rows = np.concatenate([q[0] for q in parts])
        o = np.concatenate([q[1] for q in parts]).astype(np.float32)
        d = np.concatenate([q[2] for q in parts]).astype(np.float32)
        beta = np.concatenate([q[3] for q in parts]).astype(np.float32)
        pdf = np.concatenate([q[4] for q in parts]).astype(np.float32)
        prev_p = np.concatenate([q[5] for q in parts]).astype(np.float32)
        prev_n = np.concatenate([q[6] if q[6] is not None else np.zeros((len(q[0]), 3), np.float32)
                                 for q in parts]).astype(np.float32)
        from_medium = np.concatenate([np.full(len(q[0]), q[6] is None) for q in parts])
        final = np.concatenate([q[7] for q in parts])
        counts, vcount = counts[rows], vcount[rows]
        if bounce >= RR_START_BOUNCE:
            q = np.clip(1.0 - row_max(beta), 0.0, 0.95)
            u_rr = samplers.uniform(seeds[alive[rows]], samplers.bounce_dim(bounce, samplers.D_RR))
            live = u_rr >= q
            beta = scale(beta, 1.0 / np.maximum(1.0 - q, 1e-6))
        else:
            live = np.ones(len(rows), bool)
        live &= (row_max(beta) > 0) & np.isfinite(beta).all(axis=1)
        k = np.nonzero(live)[0]
        rows, o, d, beta, pdf, prev_p, final = rows[k], o[k], d[k], beta[k], pdf[k], prev_p[k], final[k]
        prev_n, from_medium = prev_n[k], from_medium[k]
        counts, vcount = counts[k], vcount[k]
        alive = alive[rows]
        h = ctx.accel.intersect_closest(o, d)
        hit_rows, prim, hu, hv = h.hit, h.prim, h.u, h.v
        t_end = np.where(hit_rows, h.t, np.inf).astype(np.float64)
    np.nan_to_num(L, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
    return L

