"""The reference path tracer, written as wavefront stages over whole batches.

Per bounce: next-event estimation (light chosen in proportion to power, the
world among them; MIS with BSDF sampling), BSDF sampling of the continuation,
Russian roulette, trace, then emission found by the continuation rays
(analytic lights crossed, emissive triangles hit, the world on escape)
weighted by MIS against the light sampler's pdf of the same direction.

``radiance_from_surface`` is what ReSTIR GI calls to estimate the outgoing
radiance of its samples: it starts at given surface hits, excludes their own
emission, and is a pure function of the path seeds.
"""

from dataclasses import dataclass

import numpy as np

from ..materials import shading as materials
from ..sampling import samplers
from ..geometry.accel import offset_origins
from ..camera.projection import generate_rays, view_depth
from ..geometry.interaction import surface_hits
from .media import media_of
from .media_path import camera_radiance
from ..util.rows import gather, row_max, scale, scatter, scatter_add
from ..util.vectors import luminance
from ..sampling.warps import power_heuristic
from .base import ShadingFrame, direct_light, sample_continuation
from .bounces import binding, count, per_kind

RR_START_BOUNCE = 3


def radiance_from_surface(ctx, surf, seeds, bounce0, max_bounces, frame=None, counts=None, first=None):
    """Radiance reflected at ``surf`` toward ``surf.wo`` (its own emission excluded).

    bounce0 is the bounce index of ``surf`` (0 for camera hits). Every vertex up
    to bounce ``max_bounces`` gets NEE and a BSDF ray, both weighted by MIS; the
    BSDF ray of the last vertex only collects emission. ``max_bounces`` may be
    a bounces.Bounces with limits per kind of bounce: a ray that takes its
    kind's count past its limit only collects emission, and its path ends
    there; ``counts`` (N, 3): the bounces of each kind the paths made before
    ``surf`` (zero if None; a path already past a limit gives nothing). ``frame``: the
    ShadingFrame of ``surf`` if the caller has it. ``first``: the uniforms
    of the first vertex, ((u_lobe, u), (u_select, u)) per row of ``surf``,
    instead of the seeds' own (samplers.first_bounce_uniforms). Returns
    (N, 3) float32.
    """
    scene = ctx.scene
    n = len(surf)
    L = np.zeros((n, 3), np.float32)
    alive = np.arange(n)
    beta = np.ones((n, 3), np.float32)
    limits = np.asarray(per_kind(max_bounces), np.int16)
    track = binding(max_bounces)
    by_kind = getattr(ctx.accel, "per_kind_visibility", False)
    want_kinds = track or by_kind or getattr(ctx.lights, "hidden_kinds", None) is not None
    # Suns apart (LightSet.nee_sets): a light sample of each sun besides one
    # of the other emitters; BSDF rays weigh what they find against the latter.
    nee = ctx.lights.nee_sets()
    lights = nee[0]
    if track:
        counts = np.zeros((n, 3), np.int16) if counts is None else np.array(counts, np.int16)
        over = (counts > limits).any(axis=1)        # reached by a ray past a limit: emission only
        if over.any():
            alive = np.nonzero(~over)[0]
            surf, beta, frame = surf.subset(alive), beta[alive], None
    for bounce in range(bounce0, max_bounces + 1):
        if len(alive) == 0:
            break
        s = seeds[alive]
        if frame is None:
            frame = ShadingFrame.at(scene, surf)
        u_dir = u_light = None
        if first is not None and bounce == bounce0:
            (u_lobe, u), (u_sel, u_uv) = first
            u_dir, u_light = (u_lobe[alive], gather(u, alive)), (u_sel[alive], gather(u_uv, alive))
        for sets in nee:
            scatter_add(L, alive, beta * direct_light(ctx, surf, frame, s, bounce, u_light=u_light, lights=sets))
        kinds = None
        if want_kinds:
            wi, weight, pdf, valid, kinds = sample_continuation(ctx, surf, frame, s, bounce, kinds=True, u=u_dir)
        else:
            wi, weight, pdf, valid = sample_continuation(ctx, surf, frame, s, bounce, u=u_dir)
        beta = beta * weight
        if bounce >= RR_START_BOUNCE:
            q = np.clip(1.0 - row_max(beta), 0.0, 0.95)
            u_rr = samplers.uniform(s, samplers.bounce_dim(bounce, samplers.D_RR))
            valid &= u_rr >= q
            beta = scale(beta, 1.0 / np.maximum(1.0 - q, 1e-6))
        # Rows of the surviving rays are taken from the rows of this vertex
        # once, at the composed index, when the next vertex is known (each
        # row gather costs a pass over the batch).
        keep = np.nonzero(valid)[0]
        alive, wi, pdf = alive[keep], gather(wi, keep), pdf[keep]
        kinds = kinds[keep] if kinds is not None else None
        if track:
            c = counts[alive]
            final = count(c, kinds, limits)     # these rays end their paths at their hits
            counts[alive] = c
        o = offset_origins(gather(surf.p, keep), gather(surf.ng, keep), wi, ctx.eps)
        hits = ctx.accel.intersect_closest(o, wi, kinds=kinds) if by_kind \
            else ctx.accel.intersect_closest(o, wi)
        # Emission found by the BSDF rays, each weighted against NEE.
        if lights.n_analytic and lights.analytic.crossable():
            scatter_add(L, alive, gather(beta, keep) * lights.emitted_along(
                o, wi, hits.t, pdf_bsdf=pdf, kinds=kinds, p=gather(surf.p, keep), n=gather(surf.ns, keep)))
        miss = np.nonzero(~hits.hit)[0]
        if len(miss) and lights.environment is not None:
            # n: the normal NEE sampled a constant world about.
            rows = keep[miss]
            scatter_add(L, alive[miss], escaped_radiance(lights, gather(wi, miss), pdf[miss],
                                                         gather(surf.ns, rows), gather(beta, rows)))
        prev = surf
        surf, idx = surface_hits(scene, o, wi, hits)
        frame = None
        rows = keep[idx]
        alive, beta, pdf = alive[idx], gather(beta, rows), pdf[idx]
        if len(lights.tri_index) or materials.shading(scene).emitting:
            le = materials.surface_emission(scene, surf, lights)
            emissive = np.nonzero(row_max(le) > 0)[0]
            if len(emissive):
                pdf_l = lights.pdf_triangle(surf.prim[emissive], gather(prev.p, rows[emissive]),
                                                gather(surf.p, emissive), -gather(surf.wo, emissive),
                                                gather(prev.ns, rows[emissive]))
                w = power_heuristic(pdf[emissive], pdf_l)
                scatter_add(L, alive[emissive], scale(gather(beta, emissive) * gather(le, emissive), w))
        if track and len(alive):
            go = np.nonzero(~final[idx])[0]
            if len(go) < len(alive):
                alive, beta, pdf = alive[go], gather(beta, go), pdf[go]
                surf = surf.subset(go)
    np.nan_to_num(L, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
    return L


def escaped_radiance(lights, wi, pdf_bsdf, n, beta):
    """beta x the world's radiance seen by BSDF rays that escaped along wi,
    weighted against NEE (which samples the world with lights.pdf_world from
    points of normal n) by the power heuristic."""
    w = power_heuristic(pdf_bsdf, lights.pdf_world(wi, n))
    return scale(beta * lights.world_radiance(wi), w)


CAMERA_JITTER = 0x7E7       # key of each pixel's scramble of its pixel filter's dimensions
FIRST_BOUNCE = 0xF1B        # key of its scrambles of the first bounce's dimensions


@dataclass
class PassResult:
    """One sample per pixel of a whole image; rows of pixel index y * width + x."""
    color: np.ndarray       # (P, 3)
    depth: np.ndarray       # (P,) view-axis depth, 1e10 where nothing was hit
    normal: np.ndarray      # (P, 3) world shading normal facing the camera (0 on misses)
    albedo: np.ndarray      # (P, 3) diffuse + specular albedo (denoising albedo)
    alpha: np.ndarray = None  # (P,) coverage (Film > Transparent) less holdouts


def camera_pass(ctx, width, height, seed, frame, sample, max_bounces, pixel_filter, pixels=None):
    """Path-trace one sample for every pixel (or for the pixel indices ``pixels``)."""
    scene = ctx.scene
    pix = np.arange(width * height, dtype=np.int64) if pixels is None else np.asarray(pixels, np.int64)
    n = len(pix)
    seeds = samplers.path_seeds(seed, frame, pix, sample)
    xy = np.stack([pix % width, pix // width], axis=1).astype(np.float32) + 0.5
    # The pixel filter's positions over a render's samples, and the first
    # bounce's light samples and BSDF directions, follow the pixel's Sobol
    # points, scrambled per pixel and frame: each uniform, together evenly
    # spread (as Cycles' pattern), so edges and direct light converge faster.
    xy += pixel_filter.offsets(samplers.sobol_jitter(samplers.hash_keys(seed, frame, pix, CAMERA_JITTER), sample))
    o, d, tmax = generate_rays(scene.camera, width, height, xy, samplers.lens_uniforms(scene.camera, seeds),
                               samplers.time_uniforms(scene.camera, seeds))
    hits = ctx.accel.intersect_closest(o, d, tmax, camera=True)
    media = media_of(scene, ctx.eps)
    if media is not None:
        color = camera_radiance(ctx, media, o, d, tmax, hits, seeds, max_bounces)
        return _with_aovs(ctx, color, o, d, hits, n, tmax, media)
    color = ctx.lights.emitted_along(o, d, np.minimum(hits.t, tmax))
    miss = np.nonzero(~hits.hit & (tmax > 0))[0]     # tmax 0: outside a fisheye's lens
    if len(miss) and ctx.lights.environment is not None and not scene.film_transparent:
        scatter_add(color, miss, ctx.lights.world_radiance(gather(d, miss), camera=True))
    depth = np.full(n, 1e10, np.float32)
    normal = np.zeros((n, 3), np.float32)
    albedo = np.zeros((n, 3), np.float32)
    surf, idx = surface_hits(scene, o, d, hits)
    if len(idx):
        shading = ShadingFrame.at(scene, surf, camera_ray=True)
        keys = samplers.hash_keys(seed, frame, pix[idx], FIRST_BOUNCE)
        first = samplers.first_bounce_uniforms(keys, sample if np.ndim(sample) == 0 else np.take(sample, idx))
        light = radiance_from_surface(ctx, surf, seeds[idx], 0, max_bounces, shading, first=first)
        light += materials.camera_emission(scene, surf, ctx.lights)
        scatter_add(color, idx, light)
        _first_surface_passes(scene, surf, idx, shading, depth, normal, albedo)
    return _finished(scene, color, depth, normal, albedo, n, idx, surf)


def _first_surface_passes(scene, surf, idx, shading, depth, normal, albedo):
    """Depth, Normal and Denoising Albedo of the camera rays' first surfaces, in place."""
    depth[idx] = view_depth(scene.camera, surf.p)
    scatter(normal, idx, surf.ns)
    scatter(albedo, idx, np.clip(shading.params.diffuse + shading.params.f0, 0.0, 1.0))


def _finished(scene, color, depth, normal, albedo, n, idx, surf):
    """The PassResult: colours made finite, holdouts cut out, alpha."""
    np.nan_to_num(color, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
    alpha, keep = materials.camera_alpha(scene, n, idx, surf)
    if (keep < 1).any():
        color = scale(color, keep)
    return PassResult(color, depth, normal, albedo, alpha)


def _with_aovs(ctx, color, o, d, hits, n, tmax, media):
    """PassResult of colours found another way (through media) with the
    passes of the camera rays' first surfaces. With a transparent film, a
    camera ray that meets no surface is as opaque as the media it crosses
    (alpha one minus their mean transmittance, as Cycles)."""
    scene = ctx.scene
    depth = np.full(n, 1e10, np.float32)
    normal = np.zeros((n, 3), np.float32)
    albedo = np.zeros((n, 3), np.float32)
    surf, idx = surface_hits(scene, o, d, hits, hits.hit & (tmax > 0))
    if len(idx):
        shading = ShadingFrame.at(scene, surf, camera_ray=True)
        _first_surface_passes(scene, surf, idx, shading, depth, normal, albedo)
    result = _finished(scene, color, depth, normal, albedo, n, idx, surf)
    miss = np.nonzero(~hits.hit & (tmax > 0))[0]
    if scene.film_transparent and len(miss) and result.alpha is not None:
        tr = media.along(gather(o, miss), gather(d, miss), np.full(len(miss), np.inf)).transmittance()
        result.alpha[miss] = np.maximum(result.alpha[miss], 1.0 - tr.mean(axis=1))
    return result


def mean_luminance(color):
    return float(luminance(color).mean())
