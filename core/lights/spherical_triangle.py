"""Sampling a triangle by the solid angle it subtends (Arvo 1995), for emitters
close to the point they light.

Area sampling's solid-angle pdf, d^2 / (cos A), varies over a triangle as much
as its distance and angle do: a wall a few centimetres behind a small emissive
cube sees pdfs an order of magnitude apart over the cube's face, and next-event
estimation there is noisy (so noisy that multiple importance sampling hands the
light to BSDF rays, one per path). Uniform sampling of the spherical triangle
has pdf 1 / solid angle everywhere on it. Cycles does the same for triangles
that are large against their distance.

Whole-array routines in float64 (the angles of small spherical triangles lose
their digits in float32); ``use_solid_angle`` decides per (point, triangle)
which of the two a light sample used, so the pdf of a BSDF-sampled hit is
evaluated by the same rule.
"""

import numpy as np

from ..util.rows import gather
from ..util.vectors import dot as _dot, normalize as _unit

# A triangle is sampled by solid angle from points that see it under more
# than this (steradians): beyond ~1e-3 Arvo's angles lose digits even in
# float64, and area sampling's pdf is nearly constant over a far triangle.
MIN_SOLID_ANGLE = 0.02
# ... and less than this: a point on (or a hair off) the triangle's own plane,
# inside it, sees it as a flat hemisphere, where Arvo's construction degenerates
# (and nothing there is lit by it anyway).
MAX_SOLID_ANGLE = 1.5 * np.pi


def _cross(a, b):
    """Row-wise cross product of (N, 3) arrays, column by column (np.cross is slow on rows)."""
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
                     a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


def solid_angle(p, v0, v1, v2):
    """(N,) solid angle of triangles (v0, v1, v2) seen from points p (N, 3 each;
    Van Oosterom and Strackee 1983), in float64."""
    a = _unit(np.asarray(v0, np.float64) - p)
    b = _unit(np.asarray(v1, np.float64) - p)
    c = _unit(np.asarray(v2, np.float64) - p)
    det = np.abs(_dot(a, _cross(b, c)))
    den = 1.0 + _dot(a, b) + _dot(b, c) + _dot(c, a)
    return 2.0 * np.arctan2(det, den)


def use_solid_angle(omega):
    """Where a triangle is sampled by solid angle (see MIN_SOLID_ANGLE)."""
    return (omega > MIN_SOLID_ANGLE) & (omega < MAX_SOLID_ANGLE)


def large_solid_angles(p, p0, e1, e2):
    """Solid angles of triangles (p0, e1, e2; rows or one broadcast row) from
    points p, where a first bound says they may be large (else 0), and the
    rows that sample them by solid angle (``sample``)."""
    n = len(p)
    omega = np.zeros(n, np.float64)
    if n == 0:
        return omega, np.zeros(0, np.int64)
    # A triangle lies within the sphere about its first corner of radius
    # its longest edge r: from a point at distance d > r from that corner
    # its solid angle is below 2 pi (1 - sqrt(1 - r^2 / d^2)) <= 2 pi r^2 / d^2.
    r2 = np.maximum(np.maximum(_dot(e1, e1), _dot(e2, e2)), _dot(e2 - e1, e2 - e1))
    to = p0 - p
    d2 = _dot(to, to)
    with np.errstate(invalid="ignore"):
        maybe = np.nonzero(2.0 * np.pi * r2 > MIN_SOLID_ANGLE * np.maximum(d2 - r2, 0.0))[0]
    if len(maybe) == 0:
        return omega, maybe
    rows = (lambda v: v if len(v) == 1 and n > 1 else gather(v, maybe))  # noqa: E731
    q0 = rows(p0)
    omega[maybe] = solid_angle(gather(p, maybe), q0, q0 + rows(e1), q0 + rows(e2))
    near = maybe[use_solid_angle(omega[maybe])]
    return omega, near


def sample(p, v0, v1, v2, u):
    """Directions (N, 3) uniform over the solid angle of each triangle from p,
    and the barycentrics (b1, b2) of where they cross it; all float64.
    u: (N, 2) uniforms. Degenerate rows give the triangle's centroid."""
    p = np.asarray(p, np.float64)
    a = _unit(np.asarray(v0, np.float64) - p)
    b = _unit(np.asarray(v1, np.float64) - p)
    c = _unit(np.asarray(v2, np.float64) - p)
    n_ab, n_bc, n_ca = _unit(_cross(a, b)), _unit(_cross(b, c)), _unit(_cross(c, a))
    # Interior angles of the spherical triangle at a, b and c.
    alpha = np.arccos(np.clip(-_dot(n_ab, n_ca), -1.0, 1.0))
    beta = np.arccos(np.clip(-_dot(n_bc, n_ab), -1.0, 1.0))
    gamma = np.arccos(np.clip(-_dot(n_ca, n_bc), -1.0, 1.0))
    area = alpha + beta + gamma - np.pi
    u0, u1 = np.asarray(u[:, 0], np.float64), np.asarray(u[:, 1], np.float64)
    # The sub-triangle (a, b, c') of area u0 * area: c' on the arc from a to c.
    ap = u0 * area
    s, t = np.sin(ap - alpha), np.cos(ap - alpha)
    cos_alpha, sin_alpha = np.cos(alpha), np.sin(alpha)
    cos_c = _dot(a, b)
    uu = t - cos_alpha
    vv = s + sin_alpha * cos_c
    with np.errstate(invalid="ignore", divide="ignore"):
        q = ((vv * t - uu * s) * cos_alpha - vv) / ((vv * s + uu * t) * sin_alpha)
    q = np.clip(np.where(np.isfinite(q), q, 1.0), -1.0, 1.0)
    c_perp = _unit(c - _dot(c, a)[:, None] * a)
    cp = q[:, None] * a + np.sqrt(np.maximum(1.0 - q * q, 0.0))[:, None] * c_perp
    # Then uniform in solid angle along the arc from b to c'.
    z = 1.0 - u1 * (1.0 - _dot(cp, b))
    cp_perp = _unit(cp - _dot(cp, b)[:, None] * b)
    w = z[:, None] * b + np.sqrt(np.maximum(1.0 - z * z, 0.0))[:, None] * cp_perp
    # Where the direction crosses the triangle's plane (Moller-Trumbore).
    e1 = np.asarray(v1, np.float64) - v0
    e2 = np.asarray(v2, np.float64) - v0
    h = _cross(w, e2)
    det = _dot(e1, h)
    with np.errstate(invalid="ignore", divide="ignore"):
        inv = 1.0 / det
        sv = p - v0
        b1 = _dot(sv, h) * inv
        b2 = _dot(w, _cross(sv, e1)) * inv
    bad = ~(np.isfinite(b1) & np.isfinite(b2) & (area > 0))
    b1 = np.clip(np.where(bad, 1.0 / 3.0, b1), 0.0, 1.0)
    b2 = np.clip(np.where(bad, 1.0 / 3.0, b2), 0.0, 1.0)
    over = b1 + b2 > 1.0
    total = np.where(over, b1 + b2, 1.0)
    return w, b1 / total, b2 / total
