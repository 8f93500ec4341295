"""Heterogeneous media from voxel grids: Cycles' volume objects, an OpenVDB
density grid under the object's volume shader.

A GridMedium is plain data: the grid's voxel values as a dense array (voxel
(i, j, k) sits at index point (i, j, k), as in OpenVDB), the affine map from
world space to index space, a coefficient row (core/integrators/media.py's
layout) per unit of density and a row that holds everywhere inside the grid's
box whatever the density (a Principled Volume's emission, which Cycles does
not scale by the density). Between voxel centres the density is trilinear, as
Cycles samples grids, and it falls to zero one voxel past the grid's box.
The box is the voxels' cells grown by half a voxel each side, as Cycles'
mesh around a volume's voxels (matched on an emitting grid: without the
margin 3.4 % dark, with a whole voxel 2.9 % bright). Two Principled Volume
grids change what a step holds: a colour grid on the density's voxels
tints scattering and absorption, and a temperature grid (a GridMedium of
its own) emits the blackbody of its temperature (blackbody_emission).

Along a ray a grid is marched as Cycles marched volumes before its null
scattering: the span of the ray inside the grid's box is cut into steps of
about one voxel (at most MAX_STEPS), each step holds the density at its
midpoint, and these steps join the homogeneous media's piecewise-constant
intervals (media.Intervals). Transmittance, emission and free-flight
distances then come from the same closed forms, so a grid adds no noise of
its own; the midpoint rule's error is second order in the step. Rays are
marched in chunks of CHUNK to bound the memory of the merged intervals.
"""

from dataclasses import dataclass, field
import hashlib

import numpy as np

from ..materials.shader.nodes_spectrum import blackbody_rec709

MAX_STEPS = 128
CHUNK = 2048


@dataclass
class GridMedium:
    density: np.ndarray         # (nx, ny, nz) float32 voxel values
    to_index: np.ndarray        # (4, 4) world space -> index space of density
    scaled: np.ndarray          # (C,) coefficients per unit of density
    constant: np.ndarray        # (C,) coefficients inside the grid's box (emission)
    name: str = ""
    # A temperature grid instead of a density: (Temperature, Blackbody
    # Intensity, Blackbody Tint (3,)) of a Principled Volume. Its voxels,
    # times Temperature, are kelvins; the grid adds only blackbody emission.
    blackbody: tuple = None
    # A Principled Volume's colour grid on the density's voxels: (colour
    # voxels (nx, ny, nz, 3), Color (3,), Density, (1 - sqrt(Absorption
    # Color)) (3,), anisotropy). The scattering colour is Color times the
    # grid's, so absorption and scattering follow it voxel by voxel, and
    # ``scaled`` is not used.
    color: tuple = None
    _digest: bytes = field(default=None, repr=False, compare=False)

    def digest(self):
        """A change detector of the grid's data (computed once: grids are
        not changed in place)."""
        if self._digest is not None:
            return self._digest
        h = hashlib.sha1()
        h.update(repr(self.blackbody).encode())
        if self.color is not None:
            h.update(np.ascontiguousarray(self.color[0]).tobytes())
            h.update(repr(self.color[1:]).encode())
        for a in (self.density, self.to_index, self.scaled, self.constant):
            a = np.ascontiguousarray(a)
            h.update(repr((a.dtype.str, a.shape)).encode())
            h.update(a.tobytes())
        self._digest = h.digest()
        return self._digest


class PreparedGrid:
    """A GridMedium made ready for marching: the density padded with a layer
    of zeros (so trilinear lookups fall to zero past the box), the map to the
    padded array's index space, the box and the world length of a voxel."""

    def __init__(self, grid):
        dens = np.nan_to_num(np.asarray(grid.density, np.float32), nan=0.0, posinf=0.0, neginf=0.0)
        dens = np.maximum(dens, 0.0)
        if dens.ndim != 3 or dens.size == 0:
            dens = np.zeros((1, 1, 1), np.float32)
        self.shape = np.asarray(dens.shape)
        self.padded = np.pad(dens, 1)
        m = np.asarray(grid.to_index, np.float64).reshape(4, 4).copy()
        if not np.isfinite(m).all():
            m = np.zeros((4, 4))
        m[:3, 3] += 1.0                                 # index space of the padded array
        self.m = m
        # The box marched: the voxels' cells grown by half a voxel each side
        # ([-1, n] in the grid's own index space), where Cycles' volume mesh
        # encloses the grid (emission fills it).
        self.lo, self.hi = 0.0, self.shape + 1.0
        row = np.nan_to_num(np.asarray(grid.scaled, np.float32))
        self.scaled = row
        self.constant = np.nan_to_num(np.asarray(grid.constant, np.float32))
        with np.errstate(divide="ignore", invalid="ignore"):
            to_world = np.linalg.pinv(m[:3, :3])
        voxel = np.linalg.norm(to_world, axis=0)       # world length of one index step per axis
        self.voxel = float(voxel.min()) if np.isfinite(voxel).all() and voxel.min() > 0 else 0.0
        self.blackbody = None
        if grid.blackbody is not None:
            kelvin, intensity, tint = grid.blackbody
            self.blackbody = (float(kelvin), float(intensity), np.clip(np.nan_to_num(np.asarray(tint, np.float64)),
                                                                        0, None)[:3])
            row = np.zeros_like(row)
            self.scaled = row
        self.color = None
        if grid.color is not None:
            voxels, base, factor, absorb, g = grid.color
            voxels = np.maximum(np.nan_to_num(np.asarray(voxels, np.float32)), 0.0)
            if voxels.shape == dens.shape + (3,):
                self.color = ([np.pad(voxels[..., k], 1) for k in range(3)],
                              np.clip(np.asarray(base, np.float64), 0, None), max(float(factor), 0.0),
                              np.clip(np.asarray(absorb, np.float64), 0, None), float(np.clip(g, -0.999, 0.999)))
        scatters = dens.max(initial=0.0) > 0 and (np.abs(row).max() > 0 or self.blackbody is not None
                                                  or self.color is not None)
        self.empty = self.voxel <= 0 or not (scatters or np.abs(self.constant).max() > 0)

    def to_index_space(self, o, d):
        o = np.asarray(o, np.float64)
        d = np.asarray(d, np.float64)
        return o @ self.m[:3, :3].T + self.m[:3, 3], d @ self.m[:3, :3].T

    def span(self, o, d, t_end):
        """(t0, t1) of the rays o + t d, 0 <= t <= t_end, inside the box; t1 <= t0: none."""
        oi, di = self.to_index_space(o, d)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / di
            a = (self.lo - oi) * inv
            b = (self.hi - oi) * inv
        lo = np.where(np.isnan(a), -np.inf, np.minimum(a, b))
        hi = np.where(np.isnan(b), np.inf, np.maximum(a, b))
        # Axes the ray runs parallel to: inside the slab or never.
        par = di == 0
        inside = (oi >= self.lo) & (oi <= self.hi)
        lo = np.where(par, np.where(inside, -np.inf, np.inf), lo)
        hi = np.where(par, np.where(inside, np.inf, -np.inf), hi)
        t0 = np.maximum(lo.max(axis=1), 0.0)
        t1 = np.minimum(hi.min(axis=1), np.asarray(t_end, np.float64))
        return t0, t1

    def density(self, p, padded=None):
        """Trilinear density (or the values of ``padded``, an array of the
        same shape) at padded index points p (..., 3); zero outside."""
        shape = p.shape[:-1]
        p = p.reshape(-1, 3).astype(np.float32)
        n = self.padded.shape
        base = np.floor(p)
        f = p - base
        i = base.astype(np.int64)
        ok = ((i >= 0) & (i < np.asarray(n) - 1)).all(axis=1)
        sy, sz = n[1] * n[2], n[2]
        idx = np.where(ok, i[:, 0] * sy + i[:, 1] * sz + i[:, 2], 0)
        flat = (self.padded if padded is None else padded).reshape(-1)
        fx, fy, fz = f[:, 0], f[:, 1], f[:, 2]
        # Along z, then y, then x.
        c = []
        for off in (0, sz, sy, sy + sz):
            a = flat[idx + off]
            c.append(a + fz * (flat[idx + off + 1] - a))
        c00, c01, c10, c11 = c
        c0 = c00 + fy * (c01 - c00)
        c1 = c10 + fy * (c11 - c10)
        out = c0 + fx * (c1 - c0)
        return np.where(ok, out, 0.0).astype(np.float64).reshape(shape)

    def steps(self, o, d, t0, t1):
        """The march over [t0, t1] of each ray: bounds (M, S + 1) and the
        coefficient rows of the steps (M, S, C); rays of fewer steps end in
        steps of zero length."""
        length = np.maximum(t1 - t0, 0.0)
        count = np.clip(np.ceil(length / self.voxel), 1, MAX_STEPS).astype(np.int64)
        s = int(count.max(initial=1))
        delta = length / count
        j = np.arange(s + 1)
        bounds = t0[:, None] + np.minimum(j[None, :], count[:, None]) * delta[:, None]
        mid = 0.5 * (bounds[:, :-1] + bounds[:, 1:])
        oi, di = self.to_index_space(o, d)
        p = oi[:, None, :] + di[:, None, :] * mid[..., None]
        dens = self.density(p)
        vals = dens[..., None] * self.scaled + self.constant
        if self.color is not None:
            channels, base, factor, absorb, g = self.color
            scatter = np.stack([self.density(p, c) for c in channels], axis=-1) * base
            amount = dens[..., None] * factor
            vals = np.zeros(dens.shape + (len(self.constant),)) + self.constant
            vals[..., 3:6] += scatter * amount
            vals[..., :3] += (scatter + np.maximum(1.0 - scatter, 0.0) * absorb) * amount
            vals[..., 9] += (scatter * amount).mean(axis=-1) * g
        if self.blackbody is not None:
            kelvin, intensity, tint = self.blackbody
            vals = vals.copy()
            vals[..., 6:9] += blackbody_emission(kelvin * dens, intensity) * tint
        vals = np.where((j[None, :-1] < count[:, None])[..., None], vals, 0.0)
        return bounds, vals


STEFAN_BOLTZMANN = 5.670373e-8 * 1e-6 / np.pi     # Cycles' constant, per kelvin^4
_KELVIN = np.linspace(0.0, 20000.0, 4001)
_BLACKBODY = blackbody_rec709(np.maximum(_KELVIN, 800.0)).astype(np.float64)


def blackbody_emission(kelvin, intensity):
    """(..., 3) emission of a Principled Volume's blackbody at temperatures
    ``kelvin`` (...): the blackbody colour of luminance one (Cycles' below
    800 K is that of 800 K) times Stefan-Boltzmann's law, mixed toward
    constant by ``intensity`` as Cycles' Blackbody Intensity."""
    t = np.clip(np.nan_to_num(np.asarray(kelvin, np.float64)), 0.0, None)
    x = np.minimum(t, _KELVIN[-1]) / (_KELVIN[1] - _KELVIN[0])
    i = np.minimum(x.astype(np.int64), len(_KELVIN) - 2)
    f = (x - i)[..., None]
    colour = _BLACKBODY[i] * (1 - f) + _BLACKBODY[i + 1] * f
    power = STEFAN_BOLTZMANN * (1.0 + intensity * (t * t * t * t - 1.0))
    return colour * np.maximum(power, 0.0)[..., None]


def prepare(grids):
    out = [PreparedGrid(g) for g in grids or ()]
    return [g for g in out if not g.empty]


def merge(hom_bounds, hom_vals, parts):
    """Piecewise-constant coefficients along rays: the homogeneous media's
    intervals (bounds (M, K + 2), values (M, K + 1, C)) plus the grids'
    marches (a list of (bounds (M, S + 1), values (M, S, C)); a grid's
    bounds are evenly spaced, or equal past its last step). Returns the
    merged bounds and values."""
    m = len(hom_bounds)
    if hom_bounds.shape[1] == 2 and len(parts) == 1:
        # One interval of homogeneous media (none, or the world's) and one
        # grid: already in order, [0, t0], the steps, [t1, end].
        b, v = parts[0]
        bounds = np.concatenate([hom_bounds[:, :1], b, hom_bounds[:, 1:]], axis=1)
        vals = np.concatenate([hom_vals, hom_vals + v, hom_vals], axis=1)
        return bounds, vals
    all_bounds = np.sort(np.concatenate([hom_bounds] + [b for b, _ in parts], axis=1), axis=1)
    with np.errstate(invalid="ignore"):
        mid = 0.5 * (all_bounds[:, :-1] + all_bounds[:, 1:])
    mid = np.where(np.isnan(mid), all_bounds[:, :-1], mid)
    rows = np.arange(m)[:, None]
    k = hom_vals.shape[1]
    ih = np.clip((hom_bounds[:, None, :] <= mid[..., None]).sum(axis=-1) - 1, 0, k - 1)
    vals = hom_vals[rows, ih].astype(np.float64)
    for b, v in parts:
        s = v.shape[1]
        start, end = b[:, :1], b[:, -1:]
        with np.errstate(invalid="ignore", divide="ignore"):
            delta = (b[:, 1:2] - b[:, :1])
            j = np.floor((mid - start) / np.where(delta > 0, delta, 1.0))
        ok = (mid >= start) & (mid < end) & (delta > 0) & np.isfinite(j)
        j = np.clip(np.where(ok, j, 0), 0, s - 1).astype(np.int64)
        vals += np.where(ok[..., None], v[rows, j], 0.0)
    return all_bounds, vals
