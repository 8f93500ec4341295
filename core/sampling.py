"""Warps from the unit square to directions and points, each with its density.

Every sampler here has a matching pdf function (ReSTIR needs the source pdf of
any candidate, so it must always be recomputable). All functions work on whole
arrays: ``u`` is ``(N, 2)`` float32 in [0, 1), directions are ``(N, 3)``.
"""

import numpy as np

INV_PI = np.float32(1.0 / np.pi)
INV_2PI = np.float32(0.5 / np.pi)
INV_4PI = np.float32(0.25 / np.pi)


# --- small vector helpers -------------------------------------------------

def dot(a, b):
    """Row-wise dot product of (N, 3) arrays."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def normalize(v):
    """Row-wise normalisation; zero vectors stay zero instead of turning NaN."""
    n = np.sqrt(dot(v, v))
    return v / np.where(n > 0, n, 1).astype(v.dtype)[:, None]


def luminance(rgb):
    """Rec.709 luminance of (..., 3) linear RGB (Blender's default working space)."""
    return rgb @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)


def orthonormal_basis(n):
    """Tangent and bitangent for unit normals n (Duff et al. 2017, branchless)."""
    sign = np.where(n[:, 2] >= 0, 1.0, -1.0).astype(np.float32)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = np.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], axis=1)
    bt = np.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], axis=1)
    return t.astype(np.float32), bt.astype(np.float32)


def to_world(local, t, b, n):
    """Local (x along t, y along b, z along n) to world directions."""
    return local[:, 0:1] * t + local[:, 1:2] * b + local[:, 2:3] * n


def to_local(w, t, b, n):
    return np.stack([dot(w, t), dot(w, b), dot(w, n)], axis=1)


# --- disks, hemispheres, spheres, cones -----------------------------------

def square_to_concentric_disk(u):
    """Shirley-Chiu concentric map: uniform on the unit disk, low distortion."""
    a = 2.0 * u[:, 0] - 1.0
    b = 2.0 * u[:, 1] - 1.0
    use_a = np.abs(a) > np.abs(b)
    r = np.where(use_a, a, b)
    safe_a = np.where(a == 0, 1.0, a)
    safe_b = np.where(b == 0, 1.0, b)
    phi = np.where(use_a, (np.pi / 4) * (b / safe_a), (np.pi / 2) - (np.pi / 4) * (a / safe_b))
    phi = np.where((a == 0) & (b == 0), 0.0, phi)
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1).astype(np.float32)


def square_to_cosine_hemisphere(u):
    d = square_to_concentric_disk(u)
    z = np.sqrt(np.maximum(0.0, 1.0 - d[:, 0] ** 2 - d[:, 1] ** 2))
    return np.concatenate([d, z[:, None]], axis=1).astype(np.float32)


def cosine_hemisphere_pdf(cos_theta):
    return np.where(cos_theta > 0, cos_theta * INV_PI, 0.0).astype(np.float32)


def square_to_uniform_hemisphere(u):
    z = u[:, 0]
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1).astype(np.float32)


def uniform_hemisphere_pdf(cos_theta):
    return np.where(cos_theta > 0, INV_2PI, 0.0).astype(np.float32)


def square_to_uniform_sphere(u):
    z = 1.0 - 2.0 * u[:, 0]
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1).astype(np.float32)


def uniform_sphere_pdf(n):
    return np.full(n, INV_4PI, dtype=np.float32)


def square_to_uniform_cone(u, cos_max):
    """Uniform directions within angle acos(cos_max) of +z; cos_max may be an array."""
    cos_theta = (1.0 - u[:, 0]) + u[:, 0] * cos_max
    sin_theta = np.sqrt(np.maximum(0.0, 1.0 - cos_theta * cos_theta))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), cos_theta], axis=1).astype(np.float32)


def uniform_cone_pdf(cos_max):
    return (1.0 / (2.0 * np.pi * (1.0 - cos_max))).astype(np.float32)


def square_to_uniform_triangle(u):
    """Barycentrics (b1, b2) uniform over a triangle (Heitz 2019 low-distortion map)."""
    u0, u1 = u[:, 0], u[:, 1]
    low = u0 < u1
    b0 = np.where(low, u0 / 2, u0 - u1 / 2)
    b1 = np.where(low, u1 - u0 / 2, u1 / 2)
    return b0.astype(np.float32), b1.astype(np.float32)


# --- multiple importance sampling and measure conversion ------------------

def power_heuristic(pdf_a, pdf_b):
    """Weight of strategy a against b (beta = 2); zero where pdf_a vanishes.
    Written as 1 / (1 + (b / a)^2) so huge pdfs (sharp lobes) cannot overflow."""
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        r = np.asarray(pdf_b, np.float64) / np.asarray(pdf_a, np.float64)
        w = 1.0 / (1.0 + r * r)
    w = np.where(np.asarray(pdf_a) > 0, w, 0.0)
    return np.where(np.isfinite(w), w, 0.0).astype(np.float32)


def area_to_solid_angle(pdf_area, dist2, cos_at_light):
    """Convert an area-measure pdf at a light point to solid angle at the receiver."""
    with np.errstate(invalid="ignore", divide="ignore"):
        pdf = pdf_area * dist2 / np.abs(cos_at_light)
    return np.where(np.isfinite(pdf), pdf, 0.0).astype(np.float32)


# --- tabulated 1D distributions (filters, light selection) ----------------

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

    def sample_discrete(self, u):
        """Index of the chosen item and the u re-stretched to [0, 1) inside it."""
        idx = np.searchsorted(self.cdf, u, side="right") - 1
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
