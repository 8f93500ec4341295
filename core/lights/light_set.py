"""Emitters: analytic lights, emissive triangles and the world, chosen in
proportion to power and, among lamps and emissive triangles, by where the
shading point is (core/lights/light_grid.py).

``LightSet.sample`` picks one emitter per shading point and returns a direction,
its distance (INF_DIST for the sun and the world), the incident radiance and
the solid-angle pdf (selection included); ``emitted_along`` adds what
BSDF-sampled rays see of the analytic lights, and ``pdf_triangle`` and
``pdf_world`` give the NEE pdf of an emissive triangle a ray hit or of the
world a ray escaped to, so both strategies combine by multiple importance
sampling. The analytic lights themselves live in core/lights/analytic.py, the
emissive triangles in core/lights/emissive_triangles.py, the world in
core/lights/environment.py.

Selection weights approximate emitted power: the luminance of a light's power;
a sun's irradiance times the scene's cross-section pi R^2 (R: half the
diagonal of the scene's bounds); an emissive triangle's radiance x area x pi
(x 2 if two-sided); and the world, as Cycles' light tree weighs the
background, its spherical mean radiance x pi (the irradiance a cosine-weighted
hemisphere of it gives) times the same pi R^2 as a sun. Like Cycles it
ignores visibility: a closed room under a bright sky spends samples on it.
Emission colour x strength and world colour x strength are radiances.

Suns apart (``nee_sets``): a sun is weighed by its irradiance over the whole
scene, so in a room lit through a window by a sun and by lamps nearly every
shadow ray goes to the sun, which most of the room does not see (the corpus
glossy interior: 94 % of the choices, its walls' direct light the frame's
noise). So the NEE of the visible points (core/restir/initial.py) and of
paths (core/integrators/path.py, and media_path.py at surface and medium
points) gives each sun (at most SUNS_APART of them)
a light sample of its own, and chooses the other emitters among
themselves; the estimate is the sum over these sets, so it stays
unbiased. Suns are NEE's alone (no ray crosses one: ``crossable``), so
what BSDF rays find is weighed against the first set, which chooses every
other emitter.
"""

import copy
from dataclasses import dataclass

import numpy as np

from .analytic import INF_DIST, AnalyticLights, by_code, empty_sample
from .environment import scene_environment
from .light_grid import LightGrid
from .emissive_triangles import EmissiveTriangles
from ..util.rows import gather, rows_finite, scatter
from ..sampling.warps import Distribution1D
from ..util.vectors import luminance
from ..scene import LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN

__all__ = ["INF_DIST", "LightSample", "LightSet"]


def _radius(scene):
    """Half the diagonal of the scene's bounds (at least 1e-3)."""
    lo, hi = scene.bounds()
    return max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)


SUNS_APART = 2          # scenes with more suns than this keep choosing them by power

# Which routine samples an emitter (LightSet._group).
_SPHERE, _SUN, _AREA, _TRI, _ENV, _NONE = range(6)


@dataclass
class LightSample:
    wi: np.ndarray          # (N, 3) unit direction from the shading point to the light
    dist: np.ndarray        # (N,) distance to the sampled point (INF_DIST for the sun and the world)
    radiance: np.ndarray    # (N, 3) incident radiance (or irradiance-like for delta lights)
    pdf: np.ndarray         # (N,) solid-angle pdf including selection; 1 x pmf for delta lights
    delta: np.ndarray       # (N,) bool: no BSDF ray can hit this light (no MIS)
    world: np.ndarray = None    # (N,) bool: rows that sampled the world (None: no world to sample)
    index: np.ndarray = None    # (N,) the light each row sampled (LightSet order)


class LightSet:
    """All emitters of a scene with a power-proportional selection distribution.

    ``environment`` is the scene's world (core/lights/environment.py; None when black),
    whose radiance every ray that escapes reads; ``world_pmf`` its selection
    probability (0 for a constant world, which only BSDF rays find)."""

    def __init__(self, scene, emission_two_sided=True):
        self.analytic = AnalyticLights(scene.lights)
        self.n_analytic = len(scene.lights)
        self.two_sided = emission_two_sided

        self.triangles = EmissiveTriangles(scene, emission_two_sided)
        self.emitting_objects = self.triangles.emitting_objects
        self.tri_index = self.triangles.index
        self.tri_slot = self.triangles.slot
        # Per light, the kinds of bounce (diffuse, glossy, transmission) whose
        # rays its object is hidden from: light sampling leaves it out of
        # those lobes, as Cycles does (None: hidden from none).
        self.hidden_kinds = None
        hidden = np.zeros((self.n_analytic + len(self.tri_index) + 1, 3), bool)
        lamps = getattr(scene.lights, "hidden_kinds", None)
        if lamps is not None and len(lamps):
            hidden[:self.n_analytic] = lamps
        vis = getattr(scene, "ray_visibility", None)
        if vis is not None and np.asarray(vis).shape[1] == 5 and len(self.tri_index):
            hidden[self.n_analytic:-1] = ~np.asarray(vis, bool)[scene.object_ids[self.tri_index]][:, 2:5]
        if hidden.any():
            self.hidden_kinds = hidden
        # Per light, no shadow rays (a lamp with Cast Shadow off): its samples
        # light what they reach whatever lies between, as in Cycles, whose
        # shadow ray setup skips such lights (None: every light casts shadows).
        self.shadowless = None
        free = getattr(scene.lights, "shadowless", None)
        if free is not None and np.any(free):
            self.shadowless = np.zeros(self.n_analytic + len(self.tri_index) + 1, bool)
            self.shadowless[:self.n_analytic] = free

        self.scene_radius = _radius(scene)
        self.environment = scene_environment(scene)

        # Selection weights ~ emitted power, in the order: analytic lights,
        # emissive triangles, the world.
        kind = scene.lights.kind
        group = np.select([(kind == LIGHT_POINT) | (kind == LIGHT_SPOT), kind == LIGHT_SUN,
                           kind == LIGHT_AREA], [_SPHERE, _SUN, _AREA], _NONE)
        weights = [self.analytic.selection_weights(self.scene_radius), self.triangles.power]
        groups = [group, np.full(len(self.tri_index), _TRI)]
        # A constant world is no light for NEE, as in Cycles (which disables
        # the background light when the world shader does not vary with
        # direction): sampling it about the normal is the diffuse lobe's own
        # cosine sampling again, and each pick of it takes a shadow ray from
        # the lamps (a sun beside a sky-blue world was picked 40 % of the
        # time, doubling the noise of sunlit surfaces). BSDF rays that escape
        # take its whole radiance.
        if self.environment is not None and self.environment.constant is None:
            weights.append([self.world_weight(self.environment, self.scene_radius)])
            groups.append([_ENV])
        self._weights = np.concatenate(weights).astype(np.float64)
        self._groups = np.concatenate(groups).astype(np.int8)
        self._boxes = self._emitter_boxes()
        self._bounds = scene.bounds()
        self._set_distribution(self._weights, self._groups)

    def follow(self, scene):
        """This set, in place, for ``scene``: the next frame of its scene,
        in which no object of ``emitting_objects`` changed and the lights,
        materials, world and ray visibility are the same (a frame of an
        animation where other objects moved). Only the scene's bounds, by
        whose radius suns and the world are weighed, are taken anew.
        Returns self."""
        self.lights = scene.lights
        self.triangles.follow(scene)
        bounds = scene.bounds()
        if not all(np.array_equal(a, b) for a, b in zip(bounds, self._bounds)):
            self._bounds = bounds
            self.scene_radius = _radius(scene)
            weights = self._weights.copy()
            weights[:self.n_analytic] = self.analytic.selection_weights(self.scene_radius)
            if self.world_index >= 0:
                weights[self.world_index] = self.world_weight(self.environment, self.scene_radius)
            self._weights = weights
            self._set_distribution(weights, self._groups)
        return self

    def _emitter_cones(self):
        """(E, 3) directions the emitters shine along and (E,) the
        half-angles they reach from them: a spot's half cone, pi/2 for area
        lights and one-sided emissive triangles, pi for the others."""
        count = len(self._weights)
        axis, spread = np.zeros((count, 3)), np.full(count, np.pi)
        lt = self.lights
        if self.n_analytic:
            kind = np.asarray(lt.kind)
            axis[:self.n_analytic] = lt.direction
            spread[:self.n_analytic] = np.select(
                [kind == LIGHT_SPOT, kind == LIGHT_AREA],
                [np.minimum(0.5 * np.asarray(lt.spot_size, np.float64), np.pi), 0.5 * np.pi], np.pi)
        if len(self.tri_index) and not self.two_sided:
            t = slice(self.n_analytic, self.n_analytic + len(self.tri_index))
            axis[t], spread[t] = self.triangles.normal, 0.5 * np.pi
        return axis, spread

    def _emitter_boxes(self):
        """(E, 2, 3) bounds of each emitter (a point for suns and the world)."""
        boxes = np.zeros((len(self._weights), 2, 3), np.float32)
        lt = self.lights
        if self.n_analytic:
            pos = np.asarray(lt.position, np.float32)
            half = np.asarray(lt.radius, np.float32)[:, None] * np.ones(3, np.float32)
            area = lt.kind == LIGHT_AREA
            if area.any():
                span = 0.5 * (np.abs(lt.axis_u) * np.asarray(lt.size_u)[:, None]
                              + np.abs(lt.axis_v) * np.asarray(lt.size_v)[:, None])
                half = np.where(area[:, None], span, half)
            boxes[:self.n_analytic] = np.stack([pos - half, pos + half], 1)
        if len(self.tri_index):
            boxes[self.n_analytic:self.n_analytic + len(self.tri_index)] = self.triangles.boxes()
        return boxes

    @staticmethod
    def world_weight(env, scene_radius):
        """Selection weight of the world: mean radiance x pi (irradiance) x pi R^2."""
        return float(luminance(env.mean_radiance)) * np.pi * np.pi * scene_radius ** 2

    def nee_sets(self):
        """The light sets whose NEE samples, one of each, sum to the direct
        light: [self], or with suns apart (module docstring) the other
        emitters first, chosen among themselves, then one set per sun. The
        first set's emitted_along and pdf_* are what BSDF rays weigh against."""
        if self._nee_sets is None:
            sets = [self]
            suns = np.nonzero((self._groups == _SUN) & (self._weights > 0))[0]
            rest = self._weights.copy()
            rest[suns] = 0.0
            if 0 < len(suns) <= SUNS_APART and rest.sum() > 0:
                sets = [self._view(rest, keep_grid=True)]
                for i in suns:
                    alone = np.zeros_like(self._weights)
                    alone[i] = self._weights[i]
                    sets.append(self._view(alone))
            self._nee_sets = sets
        return self._nee_sets

    def _view(self, weights, keep_grid=False):
        """A shallow copy choosing by ``weights`` (the same emitters, scene
        and tables); keep_grid: its lamps keep this set's LightGrid (their
        weights are the same)."""
        view = copy.copy(self)
        view._set_distribution(weights, self._groups, keep_grid)
        view._nee_sets = [view]
        return view

    def _set_distribution(self, weights, groups, keep_grid=False):
        self._nee_sets = None
        self.distribution = Distribution1D(weights)
        self.count = self.distribution.count if self.distribution.total > 0 else 0
        # Sampling routine of each emitter, and those that rows can select
        # (zero-weight emitters never are, except at the clipped ends of the cdf).
        self._group = groups
        live = self.distribution.pmf > 0
        if len(live):
            live[[0, -1]] = True
        self._live_groups = tuple(int(g) for g in np.unique(groups[live]))
        world = np.nonzero(groups == _ENV)[0]
        self.world_index = int(world[0]) if len(world) else -1
        self.world_pmf = float(self.distribution.pmf[self.world_index]) if len(world) and self.count else 0.0
        self._set_grid(weights, groups, keep_grid)

    def _set_grid(self, weights, groups, keep_grid=False):
        """Emitters with a place (lamps, emissive triangles) are chosen by
        where the shading point is (core/lights/light_grid.py), together with the
        probability power gives them all; suns and the world by power.
        keep_grid: the lamps' weights are those of the grid the set has."""
        kept = self.grid if keep_grid else None
        self.grid = None
        local = np.isin(groups, (_SPHERE, _AREA, _TRI)) & (weights > 0)
        if local.sum() < 2 or self.count == 0:
            return
        self._local_ids = np.nonzero(local)[0]
        self._local_slot = np.full(len(weights), -1, np.int64)
        self._local_slot[self._local_ids] = np.arange(len(self._local_ids))
        self._p_local = float(self.distribution.pmf[self._local_ids].sum())
        self._far_ids = np.nonzero(~local)[0]
        far = weights[self._far_ids]
        self._far = Distribution1D(far) if len(far) and far.sum() > 0 else None
        if self._far is None:
            self._p_local = 1.0
        if keep_grid:
            self.grid = kept
            return
        box = self._boxes[self._local_ids]
        axis, spread = self._emitter_cones()
        grid = LightGrid(*self._bounds, weights[self._local_ids], box[:, 0], box[:, 1],
                         axis[self._local_ids], spread[self._local_ids])
        self.grid = grid if grid.useful else None

    @property
    def lights(self):
        """The analytic lights (scene.Lights); assignable, as the viewport does
        with an unchanged light table."""
        return self.analytic.lights

    @lights.setter
    def lights(self, value):
        self.analytic.lights = value

    # --- light sampling (next-event estimation) --------------------------------
    #
    # Rows are grouped by the routine that samples them (core/lights/analytic.py).

    def _select(self, u_select, p, n=None):
        """(index of the emitter each row at points p samples, its selection
        probability) (Distribution1D.sample_discrete without the re-stretched
        u, which sampling does not use)."""
        if self.distribution.count == 1:
            return np.zeros(len(u_select), np.intp), np.ones(len(u_select))
        if self.grid is None:
            idx = np.clip(self.distribution.locate(u_select) - 1, 0, self.distribution.count - 1)
            return idx, np.take(self.distribution.pmf, idx)
        idx = np.empty(len(u_select), np.intp)
        pmf = np.empty(len(u_select))
        near = u_select < self._p_local
        rows = np.nonzero(near)[0]
        if len(rows):
            light, q = self.grid.sample(gather(p, rows), u_select[rows].astype(np.float64) / self._p_local,
                                        None if n is None else gather(n, rows))
            idx[rows] = self._local_ids[light]
            pmf[rows] = self._p_local * q
        rows = np.nonzero(~near)[0]
        if len(rows):
            u = (u_select[rows].astype(np.float64) - self._p_local) / (1.0 - self._p_local)
            far = np.clip(self._far.locate(u) - 1, 0, self._far.count - 1)
            idx[rows] = self._far_ids[far]
            pmf[rows] = np.take(self.distribution.pmf, idx[rows])
        return idx, pmf

    def selection_pmf(self, idx, p, n=None):
        """Probability (N,) of NEE choosing emitters idx (N,) at points p (N, 3)
        of unit normals n (N, 3), as sample() was given them."""
        pmf = np.take(self.distribution.pmf, idx)
        if self.grid is None:
            return pmf
        slot = np.take(self._local_slot, idx)
        rows = np.nonzero(slot >= 0)[0]
        if len(rows):
            pmf[rows] = self._p_local * self.grid.pmf(np.take(slot, rows), gather(p, rows),
                                                      n=None if n is None else gather(n, rows))
        return pmf

    def sample(self, p, u_select, u, n=None):
        """One light sample for each shading point p (N, 3); n: the points'
        unit shading normals (N, 3), which a constant world samples about
        (uniform over the sphere without them)."""
        count = len(p)
        if self.count == 0 or count == 0:
            return LightSample(*empty_sample(count))
        idx, pmf = self._select(u_select, p, n)
        a = self.analytic
        routines = {_SPHERE: a.sample_sphere, _SUN: a.sample_sun, _AREA: a.sample_area,
                    _TRI: self._sample_triangle, _ENV: self._sample_world}
        world = None
        if len(self._live_groups) == 1:     # one kind of emitter: no regrouping
            fn = routines.get(self._live_groups[0])
            wi, dist, rad, pdf, delta = fn(idx, p, u, n) if fn else empty_sample(count)
            if self.world_index >= 0:
                world = np.full(count, self._live_groups[0] == _ENV)
        else:
            codes = np.take(self._group, idx)
            wi, dist, rad, pdf, delta = by_code(codes, self._live_groups, routines, idx, p, u, n)
            if self.world_index >= 0:
                world = codes == _ENV
        if self.distribution.count > 1:
            pdf = pdf * pmf
        ok = (pdf > 0) & np.isfinite(pdf) & rows_finite(rad)
        if not ok.all():
            bad = np.nonzero(~ok)[0]
            rad = scatter(np.array(rad, np.float32), bad, 0.0)
            pdf = np.array(pdf, np.float32)
            pdf[bad] = 0.0
        return LightSample(wi, dist, rad.astype(np.float32, copy=False),
                           pdf.astype(np.float32, copy=False), delta, world, idx)

    def _sample_triangle(self, li, p, u, n=None):
        return self.triangles.sample(li - self.n_analytic, p, u)

    def _sample_world(self, li, p, u, n=None):
        wi, pdf, rad = self.environment.sample(u, n)
        count = len(li)
        return wi, np.full(count, INF_DIST, np.float32), rad, pdf, np.zeros(count, bool)

    # --- what BSDF-sampled rays see ---------------------------------------------

    def triangle_emission(self, prim, front):
        """Radiance leaving emissive triangles toward the ray that hit them."""
        return self.triangles.emitted(prim, front)

    def pdf_triangle(self, prim, p_ref, p_hit, wi, n_ref=None):
        """NEE solid-angle pdf of having sampled the hit point on an emissive
        triangle from points p_ref of normals n_ref (as sample() had them)."""
        if not len(self.tri_index):
            return np.zeros(len(prim), np.float32)
        slot = np.take(self.tri_slot, prim)
        ok = slot >= 0
        s = np.maximum(slot, 0)
        pdf = self.selection_pmf(self.n_analytic + s, p_ref, n_ref) * self.triangles.pdf(s, p_ref, p_hit, wi)
        return np.where(ok, pdf, 0.0).astype(np.float32)

    def pdf_world(self, d, n=None):
        """NEE solid-angle pdf (selection included) of having sampled the world
        in directions d (N, 3) from points of unit normals n (N, 3)."""
        if self.world_pmf <= 0:
            return np.zeros(len(d), np.float32)
        pdf = self.environment.pdf(d, n)
        if self.distribution.count > 1:
            pdf = (pdf * np.float32(self.world_pmf)).astype(np.float32)
        return pdf

    def world_radiance(self, d, camera=False):
        """(N, 3) radiance of the world arriving from directions d (zero
        without one); camera: as camera rays see it (a world reading Light Path)."""
        if self.environment is None:
            return np.zeros((len(d), 3), np.float32)
        if camera and getattr(self.environment, "camera_radiance", None) is not None:
            return self.environment.camera_radiance(d)
        return self.environment.radiance(d)

    def emitted_along(self, o, d, tmax, pdf_bsdf=None, kinds=None, p=None, n=None):
        """Radiance of the analytic lights crossed by rays o + t d, 0 < t < tmax,
        weighted against NEE by the power heuristic. pdf_bsdf None means camera
        rays: weight one, and only lights marked camera_visible. kinds: each
        ray's kind of bounce (diffuse where None), which lights hidden from
        it do not give. p, n: the surface points the rays left and their
        normals, as NEE sampled lights from them (p defaults to o)."""
        hidden = None
        if self.hidden_kinds is not None and pdf_bsdf is not None:
            lamps = self.hidden_kinds[:self.n_analytic]
            if lamps.any():
                hidden = lamps[:, 0:1] if kinds is None else lamps[:, kinds]     # (L, N)
        pmf = self.distribution.pmf
        if self.grid is not None and (self._local_slot[:self.n_analytic] >= 0).any():
            at = o if p is None else p
            table = pmf

            def pmf(li, rows):      # at the rays that cross lamp li
                slot = self._local_slot[li]
                if slot < 0:
                    return table[li]
                return self._p_local * self.grid.pmf(np.full(len(rows), slot), gather(at, rows),
                                                      n=None if n is None else gather(n, rows))
        return self.analytic.emitted_along(o, d, tmax, pmf, pdf_bsdf, hidden)
