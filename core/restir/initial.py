"""Initial samples: one secondary surface point per pixel, with its radiance.

From each visible point x1 one direction is drawn (cosine-weighted or uniform
over the hemisphere of the shading normal; glossy materials sample their BSDF),
traced to the sample point x2, whose outgoing radiance toward x1 is estimated
by the path tracer (NEE + MIS, up to max_bounces). The same ray also completes
the direct lighting of x1: emitters it finds are weighted against NEE by MIS.
A ray that escapes becomes a sky sample: a far point in its direction whose
radiance is the world's, resampled like indirect light.

The world's light at x1 is counted once, split between x1's NEE and the sky
samples. The sky samples' radiance is reused at other pixels, whose NEE
weighs the same directions differently, so the diffuse lobe's split can't be
an MIS weight of x1's own densities: it is a function of the direction alone,
``world_share`` = power heuristic of the world's NEE density against
NEE_REFERENCE_PDF (a cosine-weighted ray's density along the normal). Bright,
small regions (a sun in an HDRI) go to NEE, the broad sky to the reservoirs,
and any such partition of unity keeps both estimates unbiased. The glossy
lobe is not reused, so its share is plain MIS between NEE and the sample ray.
A constant world is no NEE light at all (core/lights/light_set.py, as in Cycles): it has
no bright directions to find, and its light reaches the reservoirs whole.

Reservoirs carry light for the diffuse lobe only (their target is
luminance(Lo) x cos, the shape of a Lambert lobe): a neighbour's sample reused
on a glossy lobe lands where the lobe is peaked or empty, which showed as
sparkle on metals that no number of frames averaged away. The glossy lobe's
indirect light is this sample's own path-traced estimate, returned apart.
"""

from dataclasses import dataclass

import numpy as np

from ..bsdfs import bsdf
from ..materials import shading as materials
from ..sampling import samplers
from ..geometry.accel import offset_origins
from ..integrators.base import direct_light
from ..integrators.bounces import DIFFUSE, binding, first_bounce_counts
from ..integrators.path import radiance_from_surface
from ..geometry.interaction import surface_hits
from .reservoirs import Reservoirs, target
from ..util.rows import gather, row_max, scale, scatter, scatter_add
from ..sampling.warps import (
    INV_PI, cosine_hemisphere_pdf, power_heuristic, square_to_cosine_hemisphere,
    square_to_uniform_hemisphere, uniform_hemisphere_pdf)
from ..util.vectors import dot

COSINE = "COSINE"
UNIFORM = "UNIFORM"
NEE_REFERENCE_PDF = INV_PI  # world_share: directions NEE samples more densely than this go to NEE


def world_share(lights, d):
    """(N,) share of the world's light from directions d that the visible
    points' NEE carries for the diffuse lobe;
    the sky samples carry the rest. Depends on the direction only."""
    if lights.world_pmf <= 0:
        return np.zeros(len(d), np.float32)
    q = lights.pdf_world(d)         # a map's density: no normal needed
    return power_heuristic(q, np.full(len(d), NEE_REFERENCE_PDF, np.float32))


def world_sample_radiance(lights, d):
    """(N, 3) radiance of sky samples in directions d: the world's, less the
    share the visible points' NEE takes."""
    return scale(lights.world_radiance(d), 1.0 - world_share(lights, d)).astype(np.float32)


def _world_split(lights, params):
    """direct_light's ``weigh`` at visible points of BSDF parameters params:
    world samples weigh their diffuse lobe by world_share and their glossy
    lobe by MIS; other emitters keep their MIS weight. None without a world."""
    if lights.world_pmf <= 0:
        return None

    def weigh(ls, wi_local, f, w):
        fw = scale(f, w)
        rows = np.nonzero(ls.world)[0] if ls.world is not None else ()
        if len(rows):
            fr = gather(f, rows)
            fd = scale(gather(params.diffuse, rows), (np.take(wi_local[:, 2], rows) > 0) * INV_PI)
            split = scale(fd, world_share(lights, gather(ls.wi, rows)))
            split += scale(np.maximum(fr - fd, 0.0), np.take(w, rows))
            scatter(fw, rows, split.astype(fw.dtype))
        return fw

    return weigh


def _direct(ctx, surf, frame, seeds, u_light, params, wo_local, sampling, count, nee, lights):
    """(N, 3) direct light of visible points: one NEE sample of each light set
    of ``nee``, each weighed against the initial direction sampler; the
    world's light split by ``lights`` (ctx.lights: world_share is the same
    function wherever it is read)."""
    d = None
    for sets in nee:
        one = direct_light(ctx, surf, frame, seeds, 0, mis=True, u_light=u_light,
                           strategy_pdf=lambda w_l: _source_pdf(params, wo_local, w_l, sampling),
                           weigh=_world_split(lights, params), count=count, lights=sets)
        d = one if d is None else d + one
    return d


def _source_pdf(params, wo_local, wi_local, sampling):
    """Density of the initial direction sampler: the BSDF's own for glossy
    materials, else the chosen hemisphere warp."""
    glossy = _bsdf_sampled(params)
    if sampling == UNIFORM:
        base = uniform_hemisphere_pdf(wi_local[:, 2])
    else:
        base = cosine_hemisphere_pdf(wi_local[:, 2])
    if glossy.any():
        base = np.where(glossy, bsdf.pdf(params, wo_local, wi_local), base)
    return base.astype(np.float32)


def _bsdf_sampled(params):
    """Visible points whose sample direction comes from their BSDF: glossy
    lobes, and glass, whose light comes through it (below the surface)."""
    glossy = params.p_spec > 0
    if params.has_glass:
        glossy = glossy | (params.p_glass > 0)
    if params.has_sheen:
        glossy = glossy | (params.p_sheen > 0)
    return glossy


def path_reused(params):
    """Visible points whose glossy lobe's light path reuse may estimate
    (glossy_reuse.py): no glass or sheen lobe, whose samplers it does not model."""
    takes = np.ones(len(params.alpha), bool)
    if params.has_glass:
        takes &= params.p_glass <= 0
    if params.has_sheen:
        takes &= params.p_sheen <= 0
    return takes


def world_distance(scene):
    """Distance at which sky samples are placed: far beyond the scene."""
    return np.float32(1e4 * scene.extent())


STREAM_SAMPLE = 0x57EA        # key of each pixel's scrambles of its stream sequences


@dataclass
class InitialSampling:
    """How initial_samples draws and estimates each pixel's sample."""
    max_bounces: object             # bounces of the sample's path (int or integrators.bounces.Bounces)
    sampling: str = COSINE          # the diffuse lobe's directions: COSINE or UNIFORM
    light_samples: object = 1       # NEE samples of the direct light: one count for all,
                                    # or one per visible point (gb.index order)
    # False: the glossy light leaves out the samples on surfaces that the
    # specular lobes of the points path reuse takes drew (glossy_reuse.py
    # estimates those; sky samples stay, and so do those the diffuse lobe drew).
    own_surface_glossy: bool = True
    # True: the world's light on the diffuse lobe comes from sky rays (sky.py),
    # so rays that escape are no samples of the reservoirs (they keep their
    # glossy lobe's share).
    sky_rays: bool = False


def first_uniforms(seed, ids, seeds, stream_index):
    """(u_lobe (N,), u (N, 2), u_light) of the first bounce of visible points
    of pixel ids (N,) and path seeds (N,): with a stream_index (the sample's
    place in its image stream) from each pixel's sequences
    (samplers.first_bounce_uniforms; u_light their light uniforms), else the
    seeds' own (u_light None: the light sampler draws from the seeds)."""
    if stream_index is None:
        u_lobe = samplers.uniform(seeds, samplers.bounce_dim(0, samplers.D_LOBE))
        u = samplers.uniform2(seeds, samplers.bounce_dim(0, samplers.D_BSDF_UV))
        return u_lobe, u, None
    (u_lobe, u), u_light = samplers.first_bounce_uniforms(samplers.hash_keys(seed, ids, STREAM_SAMPLE), stream_index)
    return u_lobe, u, u_light


def nee_direct(ctx, surf, frame_sh, seeds, u_light, sampling, light_samples):
    """The next-event part of the direct light of visible points (surf,
    frame_sh: their SurfaceHits and ShadingFrame; seeds (N,) and u_light
    their uniforms, first_uniforms): (N, 3), and the light samples of each
    point (N,) float32. light_samples: one count for all or (N,) counts;
    each NEE sample is weighed against the initial direction sampler
    (``sampling``) as that many samples of the light strategy, so the
    emitters the sample ray finds complete it (initial_samples)."""
    params, wo_l = frame_sh.params, frame_sh.wo_local
    lights = ctx.lights
    # light_samples per point spread evenly over light choice and light
    # surfaces (stratified), all in one batch.
    counts = np.broadcast_to(np.maximum(np.asarray(light_samples, np.int64), 1), (len(seeds),))
    # With k light samples a point weighs each against its one BSDF-sampled
    # ray as k samples of the light strategy (Veach's n_i p_i): near a bright
    # emitter the BSDF ray kept the weight of a single light sample, and more
    # light samples left its noise as it was (the room of small emitters:
    # 16 light samples a point, direct light's variance 0.12 -> 0.108).
    countf = counts.astype(np.float32)
    # Suns apart (LightSet.nee_sets): a sample of each sun besides one of the
    # other emitters; BSDF rays weigh what they find against the first set.
    nee = lights.nee_sets()
    d = _direct(ctx, surf, frame_sh, seeds, u_light, params, wo_l, sampling, countf, nee, lights)
    extra = counts - 1
    if extra.any():
        # Samples k = 1 .. count - 1 of the points that take more; sample 0 is
        # the one above (the stratified pattern starts at the origin, so its
        # first point is exactly sample 0's uniforms).
        rep = np.repeat(np.arange(len(seeds)), extra)
        k = np.arange(len(rep)) - np.repeat(np.cumsum(extra) - extra, extra) + 1
        if u_light is None:
            s_sel = samplers.uniform(seeds[rep], samplers.bounce_dim(0, samplers.D_LIGHT_SELECT))
            s_uv = samplers.uniform2(seeds[rep], samplers.bounce_dim(0, samplers.D_LIGHT_UV))
        else:
            s_sel, s_uv = u_light[0][rep], gather(u_light[1], rep)
        u_light = samplers.stratified_light_uniforms(k, counts[rep], s_sel, s_uv)
        surf_k, frame_k = surf.subset(rep), frame_sh.subset(rep)
        params_k, wo_k = frame_k.params, frame_k.wo_local
        more = _direct(ctx, surf_k, frame_k, seeds[rep], u_light, params_k, wo_k, sampling, countf[rep],
                       nee, lights)
        for c in range(3):
            d[:, c] += np.bincount(rep, weights=more[:, c], minlength=len(seeds)).astype(np.float32)
        d = scale(d, 1.0 / countf)
    return d, countf


def initial_samples(ctx, gb, seed, frame, sample, how, stream_index=None):
    """Reservoirs (one per pixel, empty where nothing was hit) holding each
    pixel's new sample; the direct light of each pixel (P, 3), estimated
    with ``how.light_samples`` NEE samples averaged (each keeps its one-sample MIS
    weight, so with the sample ray's own weight they still sum to one); and the
    indirect light of each pixel's glossy lobe (P, 3) from the sample's path.
    how: InitialSampling. stream_index: the sample's place in its image
    stream, whose first bounce's uniforms then follow each pixel's sequences
    over the stream (samplers.first_bounce_uniforms; else the seeds' own): a
    still's mean of frames converges faster."""
    max_bounces, sampling, light_samples = how.max_bounces, how.sampling, how.light_samples
    own_surface_glossy, sky_rays = how.own_surface_glossy, how.sky_rays
    scene = ctx.scene
    n_pix = len(gb.valid)
    res = Reservoirs.empty(n_pix)
    direct = np.zeros((n_pix, 3), np.float32)
    glossy_light = np.zeros((n_pix, 3), np.float32)
    surf, index = gb.surf, gb.index
    if len(index) == 0:
        return res, direct, glossy_light
    seeds = samplers.path_seeds(seed, frame, gb.ids(index), sample)
    frame_sh = gb.frame
    params, wo_l = frame_sh.params, frame_sh.wo_local

    # Direction: hemisphere warp, or the BSDF for glossy materials.
    u_lobe, u, u_light = first_uniforms(seed, gb.ids(index), seeds, stream_index)
    wi_l = square_to_uniform_hemisphere(u) if sampling == UNIFORM else square_to_cosine_hemisphere(u)
    glossy = _bsdf_sampled(params)
    by_kind = getattr(ctx.accel, "per_kind_visibility", False)
    # Path reuse (own_surface_glossy False) reads which lobe drew each sample.
    want = by_kind or binding(max_bounces) or getattr(ctx.lights, "hidden_kinds", None) is not None \
        or not own_surface_glossy
    kinds = np.full(len(index), DIFFUSE, np.int8) if want else None
    if glossy.any():
        wi_b, _, _ = bsdf.sample(params.subset(glossy), wo_l[glossy], u_lobe[glossy], u[glossy])
        wi_l[glossy] = wi_b
        if kinds is not None:
            kinds[glossy] = bsdf.sampled_kinds(params.subset(glossy), wo_l[glossy], wi_b, u_lobe[glossy])
    pdf = _source_pdf(params, wo_l, wi_l, sampling)
    wi = frame_sh.world(surf, wi_l)
    f = bsdf.evaluate(params, wo_l, wi_l)
    # Reservoirs resample for the diffuse lobe (cosine above the surface);
    # the sample's own weight also carries light refracted by glass.
    cos = np.maximum(wi_l[:, 2], 0.0)
    ok = (pdf > 0) & ((dot(wi, surf.ng) > 0) == (wi_l[:, 2] > 0))
    with np.errstate(invalid="ignore", divide="ignore"):
        weight = scale(f, np.abs(wi_l[:, 2]) / np.where(pdf > 0, pdf, 1.0))
    weight = np.nan_to_num(weight, nan=0.0, posinf=0.0, neginf=0.0)
    weight = scale(weight, ok.astype(np.float32)).astype(np.float32)

    # Direct light: NEE weighted against this very sampler (nee_direct) ...
    lights = ctx.lights
    nee = lights.nee_sets()
    d, countf = nee_direct(ctx, surf, frame_sh, seeds, u_light, sampling, light_samples)

    rows = np.nonzero(ok)[0]
    wi_r, weight_r = gather(wi, rows), gather(weight, rows)
    o = offset_origins(gather(surf.p, rows), gather(surf.ng, rows), wi_r, ctx.eps)
    hits = ctx.accel.intersect_closest(o, wi_r, kinds=kinds[rows]) if by_kind \
        else ctx.accel.intersect_closest(o, wi_r)
    # ... plus the emitters the sample ray finds (analytic lights, emissive
    # triangles), weighted against the same NEE (lights' selection).
    if lights.n_analytic:
        scatter_add(d, rows, weight_r * nee[0].emitted_along(o, wi_r, hits.t, pdf_bsdf=pdf[rows] / countf[rows],
                                                             kinds=None if kinds is None else kinds[rows],
                                                             p=gather(surf.p, rows), n=gather(surf.ns, rows)))
    surf2, hit_idx = surface_hits(scene, o, wi_r, hits)
    rows2 = rows[hit_idx]
    if len(lights.tri_index) or materials.shading(scene).emitting:
        le = materials.surface_emission(scene, surf2, lights)
        if (row_max(le) > 0).any():
            pdf_l = nee[0].pdf_triangle(surf2.prim, gather(surf.p, rows2), surf2.p, -surf2.wo,
                                        gather(surf.ns, rows2))
            scatter_add(d, rows2, scale(gather(weight, rows2) * le,
                                        power_heuristic(pdf[rows2], pdf_l * countf[rows2])))
    scatter(direct, index, d)

    # The sample: x2 and its outgoing radiance toward x1 (its own emission is
    # direct light of x1, counted above).
    # Its path counts the sample ray as one bounce of the kind of the lobe that
    # drew it, as the path tracer does (validation re-traces it the same way):
    # counted as diffuse, the glossy lobe's own light on metals lost a diffuse
    # bounce further on (glossy corpus scene: metals 4-5 % dark, the image
    # 1.3 %). The diffuse lobe's share of BSDF-sampled rays keeps the same
    # estimate as the path tracer's.
    kind2 = kinds[rows2] if kinds is not None else np.full(len(rows2), DIFFUSE, np.int8)
    lo = radiance_from_surface(ctx, surf2, seeds[rows2], 1, max_bounces,
                               counts=first_bounce_counts(len(rows2), max_bounces, kind2)) \
        if max_bounces >= 1 else np.zeros((len(rows2), 3), np.float32)
    pix = index[rows2]
    for name, value in (("x2", surf2.p), ("ng2", surf2.ng), ("n2", surf2.ns), ("wo2", surf2.wo),
                        ("lo", lo)):
        scatter(getattr(res, name), pix, value)
    res.prim2[pix], res.seed[pix], res.kind[pix] = surf2.prim, seeds[rows2], kind2
    lo_glossy = lo
    if not own_surface_glossy:
        reused = np.take(path_reused(params), rows2) & (kind2 == bsdf.KIND_GLOSSY)
        lo_glossy = scale(lo, (~reused).astype(np.float32))
    # Rays that escaped sample the world. The glossy lobe takes the world's
    # radiance by MIS. For the diffuse lobe, sky rays (sky.py) carry it, or
    # else the ray becomes a sky sample: a far point in its direction whose
    # radiance is the world's (less NEE's share), resampled like any other.
    miss = rows[~hits.hit]
    if len(miss) and ctx.lights.environment is not None:
        pm = index[miss]
        wi_m = gather(wi, miss)
        le = lights.world_radiance(wi_m)
        w_b = power_heuristic(pdf[miss], nee[0].pdf_world(wi_m, gather(surf.ns, miss)) * countf[miss])
        lo_glossy = np.concatenate([lo_glossy, scale(le, w_b).astype(np.float32)])
        rows2, pix = np.concatenate([rows2, miss]), np.concatenate([pix, pm])
    if len(miss) and ctx.lights.environment is not None and not sky_rays:
        far = world_distance(scene)
        scatter(res.x2, pm, gather(surf.p, miss) + wi_m * far)
        for name in ("ng2", "n2", "wo2"):
            scatter(getattr(res, name), pm, -wi_m)
        res.prim2[pm] = res.WORLD_SAMPLE
        scatter(res.lo, pm, scale(le, 1.0 - world_share(lights, wi_m)).astype(np.float32))
        res.seed[pm] = seeds[miss]
        if kinds is not None:
            res.kind[pm] = kinds[miss]
    lo_all = gather(res.lo, pix)
    p_hat = target(lo_all) * cos[rows2]
    w = np.where(p_hat > 0, p_hat / pdf[rows2], 0.0).astype(np.float32)
    res.w_sum[pix] = w
    res.M[index] = 1.0          # every pixel with a visible point drew one candidate
    if glossy.any():
        # (f - f_diffuse) cos / pdf: the glossy lobe's share of the sample's weight.
        g = gather(weight, rows2) - scale(gather(params.diffuse, rows2),
                                          (cos[rows2] * INV_PI / np.where(pdf[rows2] > 0, pdf[rows2], 1.0))
                                          .astype(np.float32))
        scatter(glossy_light, pix, np.nan_to_num(np.maximum(g, 0.0) * lo_glossy, nan=0.0, posinf=0.0))
    return res, direct, glossy_light
