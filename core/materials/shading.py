"""Material id + shader graph -> BSDF parameters at hits.

Each material is either a row of the constant table (``scene.materials``) or
a shader graph (``scene.shaders[id]``, core/shader/). A graph whose nodes do
not depend on the hit (no textures, coordinates or attributes) is run once
and becomes a row of the lobe table like a constant material; the others run
per batch, on the hits that carry them, grouped by material. Normal maps and
bump write the hits' shading normal.

The graphs are compiled and the lobe table built once per scene object
(``shading(scene)``), not per batch.
"""

import numpy as np

from ..bsdfs import bsdf
from ..bsdfs.principled import material_lobes
from ..geometry.interaction import SurfaceHits
from ..util.rows import gather, scatter
from .lobe_rows import add_lobes
from .shader import CompiledShader, SurfaceGeometry, WorldGeometry

DEFAULT_ROUGHNESS = 0.5


class SceneShading:
    """Compiled shaders and the per-material lobe table of one scene."""

    def __init__(self, scene, warn=None):
        self.warnings = []
        warn = warn or self.warnings.append
        m = len(scene.materials)
        shaders = list(scene.shaders or [])
        self.compiled = [None] * m
        table = material_lobes(scene.materials)
        one = WorldGeometry(np.array([[0.0, 0.0, 1.0]], np.float32))
        self.emission = np.array(scene.materials.emission, np.float32, copy=True)
        self.transparent_ids = set()
        self.transparent_row = np.zeros(m, np.float32)     # uniform materials' pass probability
        self.holdout_ids = set()
        self.holdout_row = np.zeros(m, np.float32)         # uniform materials' holdout share
        for i, graph in enumerate(shaders[:m]):
            if graph is None:
                continue
            shader = CompiledShader(graph, scene.images, _named(warn, graph.name))
            closure = shader.closure(one) if shader.uniform else None
            if closure is not None and not _needs_hits(closure):
                row = params_of(closure, 1)
                for name in ("diffuse", "f0", "alpha", "p_spec", "f90", "layered", "layer_f0"):
                    getattr(table, name)[i] = getattr(row, name)[0]
                add_lobes(table, [i], row)
                self.emission[i] = closure.get("emission", 1)[0]
                self.transparent_row[i] = _pass_probability(closure, 1)[0]
                self.holdout_row[i] = np.clip(closure.get("holdout", 1)[0], 0, 1)
                if self.transparent_row[i] > 0:
                    self.transparent_ids.add(i)
                if self.holdout_row[i] > 0:
                    self.holdout_ids.add(i)
            else:
                self.compiled[i] = shader
                if _may_be_transparent(graph):
                    self.transparent_ids.add(i)
                if any(node.kind == "HOLDOUT" for node in graph.nodes):
                    self.holdout_ids.add(i)
        negative = np.nonzero((self.emission < 0).any(axis=1))[0] if len(self.emission) else []
        for i in negative:
            # Cycles subtracts such light; here an emitter's negative channels emit nothing.
            name = scene.materials.names[i] if i < len(scene.materials.names) else str(i)
            warn(f"Material '{name}': negative emission is not supported; it emits no light")
        np.maximum(self.emission, 0.0, out=self.emission)
        # A ray that stops at a partly transparent surface stands for the ones
        # that pass it too (core/integrators/transparency.py): it sees the surface's
        # emission divided by the share that stops, as it sees its other
        # lobes (params_of). Light samples on the surface see it undivided.
        see_through = self.transparent_row > 0
        self.stopped_emission = np.where(see_through, 1.0 / np.maximum(1.0 - self.transparent_row, 1e-3),
                                         1.0).astype(np.float32)
        self.divide_emission = bool((see_through & (self.emission > 0).any(axis=1)).any())
        self.table = table
        self.varying = [i for i, s in enumerate(self.compiled) if s is not None]
        # Graphs that vary over the surface and may emit: every ray sees their
        # emission at its own hit (a screen's image), not the triangle's centre.
        self.emitting = [i for i in self.varying if _may_emit(shaders[i])]
        # Graphs reading Light Path: camera rays see them evaluated as camera rays.
        self.camera_ids = [i for i in self.varying
                           if any(node.kind == "LIGHT_PATH" for node in shaders[i].nodes)]


def _named(warn, name):
    """warn, with the material's name in front of the text."""
    return (lambda text: warn(f"Material '{name}': {text}")) if name else warn


def params_of(closure, n):
    """BSDFParams of a closure spread over n hits. Where the closure is partly
    transparent, the lobes are those of a ray that stopped there: divided by
    the share that does not pass (core/integrators/transparency.py)."""
    t = _pass_probability(closure, n)
    if (t > 0).any():
        closure = closure.scaled(1.0 / np.maximum(1.0 - t, 1e-3))
    layered = closure.get("layered", n)
    glass = None
    if "transmission" in closure.fields or "trans_refl" in closure.fields:
        glass = (closure.get("trans_refl", n), closure.get("transmission", n),
                 closure.averaged("ior", n, 1.5), closure.averaged("trans_rough", n, 0.0))
    velvet = None
    if "velvet" in closure.fields:
        velvet = (closure.get("velvet", n), closure.averaged("velvet_sigma", n, 0.5))
    exact = None
    if "spec_exact" in closure.fields:
        exact = (closure.get("spec_exact", n), closure.averaged("spec_ior", n, 1.5))
    p = bsdf.lobe_params(closure.get("diffuse", n) + layered, closure.get("specular", n),
                         closure.averaged("spec_rough", n, DEFAULT_ROUGHNESS),
                         closure.get("spec_edge", n), glass, velvet, exact)
    p.layered = layered
    p.layer_f0 = closure.averaged("layer_f0", n, 0.0)
    if "spec_ss" in closure.fields:
        p.spec_ss = closure.averaged("spec_ss", n, 0.0)
    if "sheen" in closure.fields:
        p.sheen = closure.get("sheen", n)
        p.sheen_rough = closure.averaged("sheen_rough", n, 0.5)
        if "sheen_free" in closure.fields:
            p.sheen_free = closure.averaged("sheen_free", n, 0.0)
    return p


def shading(scene):
    """The scene's SceneShading, built on first use."""
    s = getattr(scene, "_shading", None)
    if s is None or s.source[0] is not scene.shaders or s.source[1] is not scene.materials:
        s = SceneShading(scene)
        s.source = (scene.shaders, scene.materials)
        scene._shading = s
        for text in s.warnings:
            if text not in scene.warnings:
                scene.warnings.append(text)
    return s


def surface_params(scene, surf, camera_ray=False):
    """BSDFParams at the hits ``surf``; where a graph bends the normal,
    ``surf.ns`` is replaced by the bent one (kept on the side of ng)."""
    sh = shading(scene)
    ids = surf.material
    params = sh.table.subset(ids)
    if not sh.varying or len(ids) == 0:
        return params
    order = np.argsort(ids, kind="stable")
    sorted_ids = ids[order]
    for m in sh.varying:
        a, b = np.searchsorted(sorted_ids, [m, m + 1])
        if a == b:
            continue
        rows = order[a:b]
        hits = surf.subset(rows)
        geom = SurfaceGeometry(scene, hits, camera_ray)
        closure = sh.compiled[m].closure(geom)
        p = params_of(closure, len(rows))
        scatter(params.diffuse, rows, p.diffuse)
        scatter(params.f0, rows, p.f0)
        scatter(params.f90, rows, p.f90)
        scatter(params.layered, rows, p.layered)
        params.layer_f0[rows] = p.layer_f0
        add_lobes(params, rows, p)
        params.alpha[rows] = p.alpha
        params.p_spec[rows] = p.p_spec
        if closure.normal_sum is not None:
            ns = closure.normal(len(rows), hits.ns)
            # Cycles raises bent normals of glossy closures only (its diffuse
            # closures keep the mapped normal and fade by bump_shadowing);
            # one normal serves all lobes here, so the larger lobe decides.
            glossy = p.p_spec > 0.5
            if glossy.any():
                ns = np.where(glossy[:, None], valid_reflection_normal(hits.ng, hits.wo, ns), ns)
            if params.smooth_n is None:       # world space here; ShadingFrame makes it local
                params.smooth_n = surf.ns.copy()
            scatter(surf.ns, rows, ns)
    return params


def emission_per_hit(scene, camera=False):
    """Whether surface_emission evaluates some material's graph at each hit
    (graphs that vary over the surface and may emit; for camera rays, graphs
    reading Light Path too): then it needs SurfaceHits, else HitSides do."""
    sh = shading(scene)
    return bool(sh.emitting) or (camera and bool(sh.camera_ids))


def camera_emission(scene, surf, lights):
    """(N, 3) emission camera rays see at the hits ``surf`` (surface_emission
    as camera rays: graphs reading Light Path see Is Camera Ray)."""
    return surface_emission(scene, surf, lights, camera=True)


def surface_emission(scene, surf, lights, camera=False):
    """(N, 3) emission leaving the hits ``surf`` toward their rays: the
    emissive triangles' for uniform materials, and each hit's own for graphs
    that vary over the surface and may emit (an image on a screen), as
    Cycles evaluates emission where a ray lands. camera: camera rays (graphs
    reading Light Path are evaluated at each hit as such). surf: SurfaceHits,
    or interaction.HitSides where emission_per_hit(scene, camera) is False."""
    n = len(surf.prim)
    em = np.zeros((n, 3), np.float32)
    if len(lights.tri_index):
        em += lights.triangle_emission(surf.prim, surf.front)
    sh = shading(scene)
    ids = set(sh.emitting) | (set(sh.camera_ids) if camera else set())
    if ids and n and not isinstance(surf, SurfaceHits):
        raise TypeError(f"surface_emission: the graphs of materials {sorted(ids)} are evaluated "
                        f"at each hit and need SurfaceHits, not {type(surf).__name__}")
    if sh.divide_emission and n:      # partly transparent emitters (SceneShading)
        em *= np.take(sh.stopped_emission, np.take(scene.material_ids, surf.prim))[:, None]
    for m in sorted(ids):
        rows = np.nonzero(surf.material == m)[0]
        if len(rows):
            closure = sh.compiled[m].closure(SurfaceGeometry(scene, surf.subset(rows), camera))
            e = np.maximum(closure.get("emission", len(rows)), 0.0)
            t = _pass_probability(closure, len(rows))
            if (t > 0).any():
                e = e / np.maximum(1.0 - t, 1e-3)[:, None]
            if not lights.two_sided:
                e = e * surf.front[rows, None]
            scatter(em, rows, e.astype(np.float32))
    return em


def _may_emit(graph):
    """Whether a graph can have emission (an Emission or Background node, or
    a Principled BSDF whose Emission Strength is linked or above zero)."""
    for node in graph.nodes:
        if node.kind in ("EMISSION", "BACKGROUND"):
            return True
        if node.kind == "BSDF_PRINCIPLED":
            strength = node.inputs.get("Emission Strength", 0.0)
            if not isinstance(strength, (int, float)) or strength > 0:
                return True
    return False


def emission_at_points(scene, prim, p, normal, wo, bary):
    """(N, 3) emission of the graphs that vary over the surface at points p
    (N, 3) on triangles prim (N,) (barycentrics bary (N, 2), unit face
    normals (N, 3), wo (N, 3) toward the receiver); zero for other
    materials. Light samples on textured emitters read it (lights.py)."""
    sh = shading(scene)
    em = np.zeros((len(prim), 3), np.float32)
    mats = np.take(scene.material_ids, prim)
    facing = (normal * wo).sum(axis=1) >= 0
    ng = np.where(facing[:, None], normal, -normal).astype(np.float32)
    for m in sh.emitting:
        rows = np.nonzero(mats == m)[0]
        if len(rows):
            hits = SurfaceHits(p=p[rows], ng=ng[rows], ns=ng[rows].copy(), wo=wo[rows],
                               prim=prim[rows].astype(np.int32), material=np.full(len(rows), m, np.int32),
                               front=facing[rows], bary=bary[rows].astype(np.float32))
            closure = sh.compiled[m].closure(SurfaceGeometry(scene, hits))
            scatter(em, rows, np.maximum(closure.get("emission", len(rows)), 0.0).astype(np.float32))
    return em


def _pass_probability(closure, n):
    """(n,) share of light passing straight through: the transparent colour's mean."""
    if "transparent" not in closure.fields:
        return np.zeros(n, np.float32)
    return np.clip(closure.get("transparent", n).mean(axis=1), 0.0, 1.0).astype(np.float32)


def _may_be_transparent(graph):
    """Whether a graph evaluated per hit can leave a transparent share."""
    for node in graph.nodes:
        if node.kind == "BSDF_TRANSPARENT":
            return True
        if node.kind == "BSDF_PRINCIPLED":
            alpha = node.inputs.get("Alpha", 1.0)
            if not isinstance(alpha, (int, float)) or alpha < 1.0:
                return True
    return False


def transparency(scene, surf, shadow=False):
    """(N,) probability that a ray passes the surface at hits ``surf``;
    shadow: the rays are shadow rays (Light Path > Is Shadow Ray is 1)."""
    sh = shading(scene)
    return _per_hit(scene, surf, sh.transparent_row, sh.transparent_ids, False,
                    _pass_probability, shadow)


def holdout(scene, surf):
    """(N,) share of the pixel a Holdout closure, or a holdout object, cuts
    out at camera hits ``surf``."""
    sh = shading(scene)
    out = _per_hit(scene, surf, sh.holdout_row, sh.holdout_ids, True,
                   lambda c, n: np.clip(c.get("holdout", n), 0.0, 1.0))
    objects = getattr(scene, "object_holdout", None)
    if objects is not None and len(objects):
        oid = np.take(scene.object_ids, surf.prim)
        out = np.where(np.take(objects, np.clip(oid, 0, len(objects) - 1)), np.float32(1), out)
    return out


def _per_hit(scene, surf, row, ids_with, camera_ray, of_closure, shadow_ray=False):
    """A scalar of the closures at hits: ``row`` (per material) where the
    material is constant, ``of_closure(closure, n)`` of the per-hit graphs of
    the materials in ``ids_with``."""
    sh = shading(scene)
    ids = surf.material
    out = np.take(row, ids)
    for m in sh.varying:
        if m not in ids_with:
            continue
        rows = np.nonzero(ids == m)[0]
        if len(rows):
            closure = sh.compiled[m].closure(SurfaceGeometry(scene, surf.subset(rows), camera_ray, shadow_ray))
            out[rows] = of_closure(closure, len(rows))
    return out


def camera_alpha(scene, n, index, surf):
    """(n,) alpha of camera samples: coverage by geometry with Film >
    Transparent (else 1), less what Holdout closures cut out, and the colour
    factor (n,) the holdout leaves (index: rows of the hits ``surf``)."""
    hit = np.zeros(n, np.float32)
    hit[index] = 1.0
    keep = np.ones(n, np.float32)
    if (shading(scene).holdout_ids or getattr(scene, "object_holdout", None) is not None) and len(index):
        keep[index] = 1.0 - holdout(scene, surf)
    alpha = hit * keep if scene.film_transparent else 1.0 - hit * (1.0 - keep)
    return alpha.astype(np.float32), keep


def _needs_hits(closure):
    """Glass lobes (their IOR turns on back faces) stay per hit, like textures."""
    return any(k in closure.fields and bool((closure.fields[k] > 0).any())
               for k in ("transmission", "trans_refl"))


def valid_reflection_normal(ng, wo, n):
    """A bent shading normal raised toward ng just enough that wo mirrored about
    it stays above the surface, as Cycles does for normal and bump maps
    (``ensure_valid_specular_reflection``): without it a map tilted away from a
    grazing view would shade the surface from below."""
    def dot_(a, b):
        return (a * b).sum(axis=1)
    iz = np.maximum(dot_(wo, ng), 0.0)
    r = 2 * dot_(n, wo)[:, None] * n - wo
    threshold = np.minimum(0.9 * iz, 0.01)
    bad = dot_(ng, r) < threshold
    if not bad.any():
        return n
    x = n - dot_(n, ng)[:, None] * ng
    lx = np.sqrt(dot_(x, x))
    x = np.where((lx > 1e-8)[:, None], x / np.where(lx > 1e-8, lx, 1)[:, None], n)
    ix = dot_(wo, x)
    a = ix * ix + iz * iz
    b = 2 * (a + iz * threshold)
    c = (threshold + iz) ** 2
    root = np.sqrt(np.maximum(b * b - 4 * a * c, 0))
    a_safe = np.where(a > 0, a, 1)
    nz2 = np.where(ix < 0, 0.25 * (b + root) / a_safe, 0.25 * (b - root) / a_safe)
    nz2 = np.clip(nz2, 0, 1)
    fixed = np.sqrt(1 - nz2)[:, None] * x + np.sqrt(nz2)[:, None] * ng
    return np.where(bad[:, None], fixed, n).astype(np.float32)


def emissive_triangles(scene):
    """(indices, (N, 3) emitted radiance) of the triangles that may emit:
    those of materials with emission or a graph that varies over the surface
    and may emit (_may_emit; the others are skipped without a per-triangle
    pass over them)."""
    sh = shading(scene)
    maybe = (np.abs(sh.emission).max(axis=1) > 0) if len(sh.emission) else np.zeros(0, bool)
    maybe[sh.emitting] = True
    if not maybe.any() or scene.triangle_count == 0:
        return np.zeros(0, np.int64), np.zeros((0, 3), np.float32)
    ids = np.clip(scene.material_ids, 0, len(maybe) - 1)
    tris = np.nonzero(maybe[ids])[0]
    return tris, triangle_emission(scene, tris)


def triangle_emission(scene, subset=None):
    """(T, 3) emitted radiance per triangle (or per triangle of ``subset``):
    the material's, and for graphs that vary over the surface and may emit,
    the graph at the triangle's centre."""
    sh = shading(scene)
    all_ids = scene.material_ids if subset is None else scene.material_ids[subset]
    em = gather(sh.emission, all_ids) if len(all_ids) else np.zeros((0, 3), np.float32)
    local = np.nonzero(np.isin(all_ids, sh.emitting))[0] if sh.emitting else []
    if len(local):
        tris = local if subset is None else subset[local]
        centre = scene.vertices[scene.triangles[tris]].mean(axis=1).astype(np.float32)
        n = scene.face_normals[tris] if scene.face_normals is not None else np.zeros_like(centre)
        bary = np.full((len(tris), 2), 1 / 3, np.float32)
        scatter(em, local, emission_at_points(scene, tris, centre, n, n, bary))
    return em
