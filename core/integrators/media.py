"""Homogeneous participating media inside closed meshes (Cycles' volume
shading of a material: Volume Absorption, Volume Scatter, Principled Volume,
Emission, with constant inputs).

A material's medium is the ``volume`` of its shader graph (core/shader/
graph.py): absorption and scattering coefficients, emission and the
Henyey-Greenstein anisotropy g, all per unit length. The triangles of such
materials bound the media; they get their own Embree scene here. Along a
ray, every crossing of a boundary is found (up to MAX_CROSSINGS), and its
side says whether the ray enters or leaves that object's medium (Cycles'
volume stack, made per ray: a medium is inside an object, so the ray's
origin is inside it if the first crossing of that object is a way out).
Overlapping media add up, as in Cycles; anisotropy is averaged by the
scattering coefficient. The world's medium (Scene.world_volume, Cycles'
world volume) fills all space and adds to every interval: a ray that leaves
the scene crosses an infinite length of it, so with any density the world
and the sun, as in Cycles, are not seen through it.

Along the ray the coefficients are then constant between crossings, so
transmittance is exact (ratio tracking and delta tracking reduce to it in a
homogeneous medium) and distances are sampled exactly: one colour channel
picked at random, its free-flight distance drawn, and the sample weighted
by the mean over channels of their pdfs (spectral MIS), so chromatic media
stay unbiased. Emission along the ray is integrated in closed form.
"""

import threading
from dataclasses import dataclass

import numpy as np

from ..geometry.accel import Accel
from .field_media import field_grids, graph_fields
from .grid_media import CHUNK, merge, prepare
from ..util.vectors import orthonormal_basis

MAX_CROSSINGS = 16
C = 10          # coefficients carried per interval: sigma_t (3), sigma_s (3), emission (3), mean sigma_s x g


def graph_media(shaders):
    """{material id: volume dict} of the graphs with a medium."""
    out = {}
    for i, g in enumerate(shaders or ()):
        v = getattr(g, "volume", None)
        if v is not None:
            out[i] = v
    return out


def coefficients(volume):
    """(C,) float32 row of a volume dict (sigma_a, sigma_s, emission, g)."""
    sa = np.clip(np.asarray(volume.get("sigma_a", (0, 0, 0)), np.float64), 0, None)
    ss = np.clip(np.asarray(volume.get("sigma_s", (0, 0, 0)), np.float64), 0, None)
    em = np.clip(np.asarray(volume.get("emission", (0, 0, 0)), np.float64), 0, None)
    g = float(np.clip(volume.get("g", 0.0), -0.999, 0.999))
    row = np.concatenate([sa + ss, ss, em, [ss.mean() * g]])
    return np.where(np.isfinite(row), row, 0.0).astype(np.float32)


class Media:
    """The media of a scene and their boundaries (see the module notes)."""

    def __init__(self, scene, volumes, eps, world=None, grids=None, fields=None):
        """fields: {material id: density graph} of the volumes whose density
        a texture drives (field_media.py): their faces bound a grid of the
        texture instead of a constant medium (which keeps their emission)."""
        fields = {i: f for i, f in (fields or {}).items() if i in volumes}
        self.world = coefficients(world) if world is not None else None
        if self.world is not None and not np.abs(self.world).max() > 0:
            self.world = None
        mids = np.asarray(scene.material_ids)
        table = np.zeros((max(len(scene.shaders or ()), int(mids.max(initial=0)) + 1), C), np.float32)
        per_density = {}
        for i, v in volumes.items():
            table[i] = coefficients(v)
            if i in fields:
                per_density[i] = coefficients(dict(v, emission=(0.0, 0.0, 0.0)))
                table[i] = coefficients({"emission": v.get("emission", (0.0, 0.0, 0.0))})
        boundary = np.isin(mids, list(volumes)) & ((np.abs(table[mids]).max(axis=1) > 0) | np.isin(mids, list(fields)))
        self.tri = np.nonzero(boundary)[0]
        self.obj = np.asarray(scene.object_ids)[self.tri] if getattr(scene, "object_ids", None) is not None \
            else np.zeros(len(self.tri), np.int64)
        self.coeff = table[mids[self.tri]]
        self.normals = np.asarray(scene.face_normals, np.float32)[self.tri] if len(self.tri) \
            else np.zeros((0, 3), np.float32)
        self.eps = float(eps)
        self.accel = Accel(scene.vertices, np.asarray(scene.triangles)[self.tri], threads=1) \
            if len(self.tri) else None
        self.grids = prepare(list(grids or ()) + field_grids(scene, self, fields, per_density))

    @property
    def empty(self):
        return len(self.tri) == 0 and self.world is None and not self.grids

    def close(self):
        if self.accel is not None:
            self.accel.close()

    def crossings(self, o, d):
        """(t (N, K), boundary triangle (N, K), -1 where none) of every
        crossing along the rays o + t d, t > 0, nearest first."""
        o = np.asarray(o, np.float32)
        d = np.asarray(d, np.float32)
        n = len(o)
        ts, bs = [], []
        start = np.zeros(n, np.float32)
        rows = np.arange(n) if self.accel is not None else np.arange(0)
        for _ in range(MAX_CROSSINGS):
            if len(rows) == 0:
                break
            h = self.accel.intersect_closest(o[rows] + d[rows] * start[rows, None], d[rows])
            t = np.full(n, np.inf, np.float32)
            b = np.full(n, -1, np.int64)
            hit = h.hit
            t[rows[hit]] = start[rows[hit]] + h.t[hit]
            b[rows[hit]] = h.prim[hit]
            ts.append(t)
            bs.append(b)
            rows = rows[hit]
            start[rows] = t[rows] + self.eps
        if not ts:
            return np.zeros((n, 0), np.float32), np.zeros((n, 0), np.int64)
        return np.stack(ts, axis=1), np.stack(bs, axis=1)

    def along(self, o, d, t_end):
        """Intervals of the segments o + t d, 0 < t < t_end (inf: the ray
        leaves the scene). Only rays that cross a boundary are worked on:
        the others meet no medium (but the world's, if there is one)."""
        t_all, b_all = self.crossings(o, d)
        end_all = np.asarray(t_end, np.float64).reshape(-1)
        if self.world is not None:
            rows = np.arange(len(end_all))
        else:
            rows = np.nonzero((b_all >= 0).any(axis=1))[0]
        k = int((b_all[rows] >= 0).sum(axis=1).max(initial=0))
        t, b = t_all[rows, :k], b_all[rows, :k]
        m = len(rows)
        valid = b >= 0
        bb = np.maximum(b, 0)
        enter = (np.einsum("nkj,nj->nk", self.normals[bb], np.asarray(d, np.float32)[rows]) < 0) & valid
        c = np.where(valid[..., None], self.coeff[bb], np.float32(0))
        obj = np.where(valid, self.obj[bb], -1)
        # Inside at the origin: the first crossing of an object leaves it.
        first = valid.copy()
        for j in range(1, k):
            first[:, j] &= ~((obj[:, :j] == obj[:, j:j + 1]) & valid[:, :j]).any(axis=1)
        start = (c * (first & ~enter & valid)[..., None]).sum(axis=1)
        sign = np.where(enter, np.float32(1), np.float32(-1))[..., None] * valid[..., None]
        vals = np.concatenate([start[:, None, :], start[:, None, :] + np.cumsum(sign * c, axis=1)], axis=1)
        # Past the last crossing the ray is outside every object.
        vals[np.arange(m), valid.sum(axis=1)] = 0.0
        if self.world is not None:
            vals += self.world
        vals[..., :9] = np.maximum(vals[..., :9], 0.0)     # (the last column, sigma_s x g, has a sign)
        end = end_all[rows]
        bounds = np.concatenate([np.zeros((m, 1)), np.minimum(t, end[:, None]), end[:, None]], axis=1)
        iv = Intervals(bounds, vals.astype(np.float64), rows, end_all)
        return Segments(iv, self.grids, o, d, end_all) if self.grids else iv


@dataclass
class Intervals:
    """Piecewise constant coefficients along the rays ``rows`` of a batch
    that cross media boundaries: bounds (M, K + 2) and values (M, K + 1, C)
    between them; ``end`` (N,): every ray's segment end. The other rays meet
    no medium."""
    bounds: np.ndarray
    vals: np.ndarray
    rows: np.ndarray = None
    end: np.ndarray = None

    @property
    def n(self):
        return len(self.bounds) if self.rows is None else len(self.end)

    def _expand(self, sub, fill):
        if self.rows is None:
            return sub
        out = np.full((self.n,) + sub.shape[1:], fill, sub.dtype)
        out[self.rows] = sub
        return out

    def _lengths(self):
        with np.errstate(invalid="ignore"):
            length = np.diff(self.bounds, axis=1)
        return np.where(np.isfinite(length) & (length > 0), length, np.where(np.isinf(length), np.inf, 0.0))

    def _depths(self):
        """(N, K + 2, 3) optical depth from the origin to each bound."""
        length = self._lengths()
        with np.errstate(invalid="ignore"):
            tau = self.vals[..., :3] * length[..., None]
        tau = np.where(self.vals[..., :3] > 0, tau, 0.0)
        return np.concatenate([np.zeros((len(length), 1, 3)), np.cumsum(tau, axis=1)], axis=1)

    def transmittance(self):
        """(N, 3) float32 transmittance over each whole segment."""
        return self._expand(np.exp(-self._depths()[:, -1]).astype(np.float32), 1.0)

    def emission(self):
        """(N, 3) float32 emitted radiance arriving at the origins: the
        integral of transmittance x emission over each segment."""
        length = self._lengths()
        st, em = self.vals[..., :3], self.vals[..., 6:9]
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            x = st * length[..., None]
            share = np.where(x > 1e-6, -np.expm1(-x) / np.where(st > 0, st, 1.0), length[..., None])
            share = np.where(np.isfinite(share), share, np.where(st > 0, 1.0 / np.where(st > 0, st, 1.0), 0.0))
            out = (np.exp(-self._depths()[:, :-1]) * em * share).sum(axis=1)
        return self._expand(np.nan_to_num(out, nan=0.0, posinf=0.0).astype(np.float32), 0.0)

    def sample(self, u_channel, u_distance):
        """Free-flight distances: (scattered (N,) bool, t (N,), weight (N, 3),
        sigma_s (N, 3) and g (N,) at the scattering point). weight is
        transmittance x sigma_s over the mean pdf where scattered, else the
        transmittance to the segment's end over its mean."""
        if self.rows is not None:
            sub = Intervals(self.bounds, self.vals)
            r = self.rows
            scat, t, w, ss, g = sub.sample(np.asarray(u_channel)[r], np.asarray(u_distance)[r])
            out_t = self.end.astype(np.float32)
            out_t[r] = t
            return (self._expand(scat, False), out_t, self._expand(w, 1.0), self._expand(ss, 0.0),
                    self._expand(np.asarray(g, np.float64), 0.0))
        n = len(self.bounds)
        tau = self._depths()                                     # (N, K + 2, 3)
        ch = np.minimum((np.asarray(u_channel) * 3).astype(np.int64), 2)
        target = -np.log1p(-np.minimum(np.asarray(u_distance, np.float64), 1.0 - 1e-7))
        tc = tau[np.arange(n), :, ch]                            # (N, K + 2) of the chosen channel
        i = (tc <= target[:, None]).sum(axis=1) - 1              # interval holding the target
        scattered = i < tc.shape[1] - 1
        ii = np.clip(i, 0, self.vals.shape[1] - 1)
        rows = np.arange(n)
        v = self.vals[rows, ii]                                  # (N, C)
        st_c = v[rows, ch]
        with np.errstate(invalid="ignore", divide="ignore"):
            t = self.bounds[rows, ii] + (target - tc[rows, ii]) / np.where(st_c > 0, st_c, 1.0)
        scattered &= st_c > 0
        t = np.where(scattered, t, self.bounds[:, -1])
        with np.errstate(invalid="ignore"):
            inside = np.where(scattered, t - self.bounds[rows, ii], 0.0)
        depth = np.where(scattered[:, None], tau[rows, ii] + v[:, :3] * inside[:, None], tau[:, -1])
        tr = np.exp(-depth)
        with np.errstate(invalid="ignore", divide="ignore"):
            pdf_scatter = (v[:, :3] * tr).mean(axis=1)
            p_pass = tr.mean(axis=1)
            weight = np.where(scattered[:, None], tr * v[:, 3:6] / np.where(pdf_scatter > 0, pdf_scatter, 1.0)[:, None],
                              tr / np.where(p_pass > 0, p_pass, 1.0)[:, None])
        ss = v[:, 3:6]
        with np.errstate(invalid="ignore", divide="ignore"):
            g = np.where(ss.mean(axis=1) > 0, v[:, 9] / np.maximum(ss.mean(axis=1), 1e-30), 0.0)
        weight = np.nan_to_num(weight, nan=0.0, posinf=0.0, neginf=0.0).astype(np.float32)
        return scattered, t.astype(np.float32), weight, ss.astype(np.float32), np.clip(g, -0.999, 0.999)


class Segments:
    """Intervals of the homogeneous media joined with the marches of the
    voxel grids (core/integrators/grid_media.py) along the rays that cross a
    grid's box, in chunks of CHUNK rays: the same three estimates as
    Intervals."""

    def __init__(self, hom, grids, o, d, end):
        self.hom, self.grids, self.end = hom, grids, np.asarray(end, np.float64)
        self.o, self.d = np.asarray(o, np.float64), np.asarray(d, np.float64)
        self.spans = [g.span(self.o, self.d, self.end) for g in grids]
        cross = np.zeros(len(self.end), bool)
        for t0, t1 in self.spans:
            cross |= t1 > t0
        self.rows = np.nonzero(cross)[0]

    def _hom_rows(self, rows):
        h = self.hom
        if h.rows is None:
            pos = rows
        else:
            lookup = np.full(len(self.end), -1, np.int64)
            lookup[h.rows] = np.arange(len(h.rows))
            pos = lookup[rows]
        have = pos >= 0
        width = h.bounds.shape[1]
        bounds = np.repeat(self.end[rows, None], width, axis=1)
        bounds[:, 0] = 0.0
        vals = np.zeros((len(rows), width - 1, C))
        bounds[have] = h.bounds[pos[have]]
        vals[have] = h.vals[pos[have]]
        return bounds, vals

    def _chunks(self):
        for start in range(0, len(self.rows), CHUNK):
            r = self.rows[start:start + CHUNK]
            parts = []
            for g, (t0, t1) in zip(self.grids, self.spans):
                a, b = t0[r], t1[r]
                cross = b > a
                parts.append(g.steps(self.o[r], self.d[r], np.where(cross, a, 0.0), np.where(cross, b, 0.0)))
            yield r, Intervals(*merge(*self._hom_rows(r), parts))

    def transmittance(self):
        out = self.hom.transmittance()
        for r, iv in self._chunks():
            out[r] = iv.transmittance()
        return out

    def emission(self):
        out = self.hom.emission()
        if not any(np.abs(g.constant[6:9]).max() > 0 or g.blackbody is not None for g in self.grids) and \
                not np.abs(self.hom.vals[..., 6:9]).max(initial=0.0) > 0:
            return out          # nothing emits: the grids change nothing
        for r, iv in self._chunks():
            out[r] = iv.emission()
        return out

    def sample(self, u_channel, u_distance):
        u_channel, u_distance = np.asarray(u_channel), np.asarray(u_distance)
        out = [np.array(a) for a in self.hom.sample(u_channel, u_distance)]
        for r, iv in self._chunks():
            for a, b in zip(out, iv.sample(u_channel[r], u_distance[r])):
                a[r] = b
        return tuple(out)


def hg_pdf(cos_theta, g):
    """Henyey-Greenstein phase function of the angle between the ray's
    direction and the new one (1 / sr)."""
    g = np.asarray(g, np.float64)
    denom = np.maximum(1.0 + g * g - 2.0 * g * np.asarray(cos_theta, np.float64), 1e-12)
    return ((1.0 - g * g) / (4.0 * np.pi * denom * np.sqrt(denom))).astype(np.float32)


def hg_sample(d, g, u):
    """New directions (N, 3) around ray directions d (N, 3), drawn from HG
    of anisotropy g (N,) with uniforms u (N, 2); and their pdf."""
    g = np.asarray(g, np.float64)
    u0, u1 = u[:, 0].astype(np.float64), u[:, 1].astype(np.float64)
    small = np.abs(g) < 1e-3
    gs = np.where(small, 0.5, g)
    sq = (1.0 - gs * gs) / (1.0 - gs + 2.0 * gs * u0)
    cos = np.where(small, 1.0 - 2.0 * u0, (1.0 + gs * gs - sq * sq) / (2.0 * gs))
    cos = np.clip(cos, -1.0, 1.0)
    sin = np.sqrt(np.maximum(1.0 - cos * cos, 0.0))
    phi = 2.0 * np.pi * u1
    d = np.asarray(d, np.float32)
    t, b = orthonormal_basis(d)
    w = (t * (sin * np.cos(phi))[:, None] + b * (sin * np.sin(phi))[:, None] + d * cos[:, None])
    w /= np.maximum(np.linalg.norm(w, axis=1, keepdims=True), 1e-30)
    return w.astype(np.float32), hg_pdf(cos, g)


_CACHE = {}
_LOCK = threading.Lock()


def media_of(scene, eps):
    """The scene's Media (cached per scene geometry and graphs: the passes
    of a frame, on either worker thread, share one), None without media."""
    volumes = graph_media(getattr(scene, "shaders", None))
    fields = graph_fields(getattr(scene, "shaders", None))
    world = getattr(scene, "world_volume", None)
    grids = list(getattr(scene, "volume_grids", None) or ())
    if not volumes and world is None and not grids:
        return None
    if volumes and getattr(scene, "face_normals", None) is None:
        volumes = {}
        if world is None and not grids:
            return None
    # (versions: the geometry's change counter, which moves when an object
    # moves in place in the same arrays: the viewport, animation frames)
    key = (id(scene.vertices), id(scene.triangles), id(scene.material_ids), len(scene.triangles),
           getattr(scene, "versions", None),
           tuple(sorted((i, tuple(coefficients(v))) for i, v in volumes.items())),
           None if world is None else tuple(coefficients(world)),
           tuple((id(g.density), g.density.shape, g.to_index.tobytes(), g.scaled.tobytes(), g.constant.tobytes(),
                  repr(g.blackbody), None if g.color is None else (id(g.color[0]), repr(g.color[1:])))
                 for g in grids),
           repr(sorted(fields.items())))
    with _LOCK:
        cached = _CACHE.get(id(scene))
        if cached is not None and cached[0] == key:
            return cached[1]
        media = Media(scene, volumes, eps, world, grids, fields)
        if media.empty:
            media.close()
            media = None
        # One scene at a time: the previous scene's boundaries are let go
        # (not closed: a pass of it may still be tracing them).
        _CACHE.clear()
        _CACHE[id(scene)] = (key, media)
        return media
