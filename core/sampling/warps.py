"""Warps from the unit square to directions and points, each with its density.

Every sampler here has a matching pdf function (ReSTIR needs the source pdf of
any candidate, so it must always be recomputable). All functions work on whole
arrays: ``u`` is ``(N, 2)`` float32 in [0, 1), directions are ``(N, 3)``.
"""

import numpy as np


INV_PI = np.float32(1.0 / np.pi)
INV_2PI = np.float32(0.5 / np.pi)
INV_4PI = np.float32(0.25 / np.pi)


# --- disks, hemispheres, spheres, cones -----------------------------------

def _pick(mask, a, b):
    """np.where(mask, a, b) for finite a and b, as a sum of products: np.where
    with an unpredictable mask is several times slower (core/util/rows.py)."""
    return a * mask + b * ~mask


def _concentric(u):
    """Columns (x, y) of the Shirley-Chiu concentric map (float32)."""
    a = 2.0 * u[:, 0] - 1.0
    b = 2.0 * u[:, 1] - 1.0
    use_a = np.abs(a) > np.abs(b)
    r = _pick(use_a, a, b)              # the larger of |a|, |b|, signed; 0 only at the centre
    centre = r == 0
    q = _pick(use_a, b, a) / (np.where(centre, 1, r) if centre.any() else r)
    phi = (np.pi / 4) * q               # b / a, or a / b on the other wedges
    phi = _pick(use_a, phi, (np.pi / 2) - phi)
    if centre.any():
        phi[centre] = 0.0
    return (r * np.cos(phi)).astype(np.float32, copy=False), (r * np.sin(phi)).astype(np.float32, copy=False)


def square_to_concentric_disk(u):
    """Shirley-Chiu concentric map: uniform on the unit disk, low distortion."""
    return np.stack(_concentric(u), axis=1)


def square_to_cosine_hemisphere(u):
    x, y = _concentric(u)
    z = np.sqrt(np.maximum(0.0, 1.0 - x ** 2 - y ** 2))
    return np.stack([x, y, z.astype(np.float32, copy=False)], axis=1)


def cosine_hemisphere_pdf(cos_theta):
    # max(cos, 0) / pi; fmax also maps NaN to 0, as np.where(cos > 0, ...) did, but faster.
    return (np.fmax(cos_theta, 0.0) * INV_PI).astype(np.float32, copy=False)


def square_to_uniform_hemisphere(u):
    z = u[:, 0]
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1).astype(np.float32, copy=False)


def uniform_hemisphere_pdf(cos_theta):
    return ((cos_theta > 0) * INV_2PI).astype(np.float32, copy=False)


def square_to_uniform_sphere(u):
    z = 1.0 - 2.0 * u[:, 0]
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1).astype(np.float32, copy=False)


def uniform_sphere_pdf(n):
    return np.full(n, INV_4PI, dtype=np.float32)


def square_to_uniform_cone(u, cos_max):
    """Uniform directions within angle acos(cos_max) of +z; cos_max may be an array."""
    cos_theta = (1.0 - u[:, 0]) + u[:, 0] * cos_max
    sin_theta = np.sqrt(np.maximum(0.0, 1.0 - cos_theta * cos_theta))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), cos_theta], axis=1).astype(np.float32, copy=False)


def uniform_cone_pdf(cos_max):
    return (1.0 / (2.0 * np.pi * (1.0 - cos_max))).astype(np.float32)


def square_to_uniform_triangle(u):
    """Barycentrics (b1, b2) uniform over a triangle (Heitz 2019 low-distortion map)."""
    u0, u1 = u[:, 0], u[:, 1]
    low = u0 < u1
    b0 = _pick(low, u0 / 2, u0 - u1 / 2)
    b1 = _pick(low, u1 - u0 / 2, u1 / 2)
    return b0.astype(np.float32), b1.astype(np.float32)


# --- multiple importance sampling and measure conversion ------------------

def power_heuristic(pdf_a, pdf_b):
    """Weight of strategy a against b (beta = 2); zero where pdf_a vanishes.
    Written as 1 / (1 + (b / a)^2) so huge pdfs (sharp lobes) cannot overflow."""
    pdf_a = np.asarray(pdf_a, np.float64)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        r = np.asarray(pdf_b, np.float64) / pdf_a
        w = 1.0 / (1.0 + r * r)
    return np.where((pdf_a > 0) & np.isfinite(w), w, 0.0).astype(np.float32)


def area_to_solid_angle(pdf_area, dist2, cos_at_light):
    """Convert an area-measure pdf at a light point to solid angle at the receiver."""
    with np.errstate(invalid="ignore", divide="ignore"):
        pdf = pdf_area * dist2 / np.abs(cos_at_light)
    return np.where(np.isfinite(pdf), pdf, 0.0).astype(np.float32)


# --- tabulated 1D distributions (filters, light selection) ----------------

_CELLS = 1 << 16        # Distribution1D.locate's cells over [0, 1)


class Distribution1D:
    """Piecewise-constant distribution over n bins of [0, 1) or n discrete items."""

    def __init__(self, weights):
        w = np.asarray(weights, dtype=np.float64)
        w = np.where(np.isfinite(w) & (w > 0), w, 0.0)
        total = w.sum()
        self.count = len(w)
        self.total = float(total)
        self.pmf = (w / total if total > 0 else np.full(len(w), 1.0 / max(len(w), 1))).astype(np.float32)
        cdf = np.concatenate([[0.0], np.cumsum(self.pmf, dtype=np.float64)])
        cdf[-1] = 1.0
        self.cdf = cdf
        self._cells = None      # locate's table, built on first use

    def locate(self, u):
        """np.searchsorted(self.cdf, u, side="right"), the same integers.

        A binary search per row mispredicts its branches on random keys; a
        table over 2^16 cells of [0, 1) answers every row whose cell holds
        no cdf value (all but a few in a thousand), and the binary search
        takes only the rest (and any u outside [0, 1) or NaN)."""
        u = np.asarray(u)
        if u.ndim != 1 or u.dtype not in (np.float32, np.float64):
            return np.searchsorted(self.cdf, u, side="right")
        if self._cells is None:
            edges = np.arange(_CELLS + 1, dtype=np.float64) / _CELLS
            lo = np.searchsorted(self.cdf, edges[:-1], side="right")
            sure = lo == np.searchsorted(self.cdf, edges[1:], side="left")
            self._cells = lo.astype(np.intp), sure
        lo, sure = self._cells
        x = u * u.dtype.type(_CELLS)        # exact: a power of two
        inside = (x >= 0) & (x < _CELLS)    # False for NaN
        cell = np.fmax(np.minimum(x, _CELLS - 1), 0).astype(np.intp)
        idx = np.take(lo, cell)
        sure = np.take(sure, cell) & inside
        if not sure.all():
            rows = np.nonzero(~sure)[0]
            idx[rows] = np.searchsorted(self.cdf, np.take(u, rows), side="right")
        return idx

    def sample_discrete(self, u):
        """Index of the chosen item and the u re-stretched to [0, 1) inside it."""
        idx = self.locate(u) - 1
        idx = np.clip(idx, 0, self.count - 1)
        lo = self.cdf[idx]
        width = self.cdf[idx + 1] - lo
        u_remapped = np.where(width > 0, (u - lo) / np.where(width > 0, width, 1), 0.0)
        return idx, np.clip(u_remapped, 0.0, 0.99999994).astype(np.float32)

    def sample_continuous(self, u):
        """Point in [0, 1) and its density (bins of width 1/count)."""
        idx, frac = self.sample_discrete(u)
        x = (idx + frac) / self.count
        return x.astype(np.float32), (self.pmf[idx] * self.count).astype(np.float32)

    def sample_point(self, u):
        """sample_continuous's point alone."""
        idx, frac = self.sample_discrete(u)
        return ((idx + frac) / self.count).astype(np.float32)
