"""The reconnection shift of ReSTIR GI (core/restir/shift.py).

A sample point x2 reused by another visible point keeps its position, so its
solid-angle density changes by the ratio of the solid angles a small patch
around x2 subtends from the two visible points. ``jacobian(x1_from, x1_to, ...)``
is that ratio (solid angle at x1_to over solid angle at x1_from), which is what
turns the owner's contribution weight W (per solid angle at x1_from) into one
per solid angle at x1_to in ``shift_weight``."""

import numpy as np
import pytest

from restir_gi.core.restir.reservoirs import Reservoirs
from restir_gi.core.restir.shift import J_CLAMP, J_MAX, J_MIN, jacobian, shift_weight, target_at


def unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def tangents(n):
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    t = unit(np.cross(helper, n))
    return t, np.cross(n, t)


def triangle_solid_angle(o, a, b, c):
    """Solid angle of triangles (a, b, c) seen from o (Van Oosterom and Strackee)."""
    a, b, c = a - o, b - o, c - o
    la, lb, lc = (np.linalg.norm(v, axis=-1) for v in (a, b, c))
    num = np.abs(np.einsum("ij,ij->i", a, np.cross(b, c)))
    den = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", a, c) * lb
           + np.einsum("ij,ij->i", b, c) * la)
    return 2.0 * np.arctan2(num, den)


def patch_solid_angle(o, centre, t, b, half):
    """Solid angle of the square centre +- half t +- half b seen from o."""
    c = [centre + sx * half * t + sy * half * b for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    return triangle_solid_angle(o, c[0], c[1], c[2]) + triangle_solid_angle(o, c[0], c[2], c[3])


def hemisphere_points(x2, n2, rng, cos_min=0.15):
    """Points in front of (x2, n2) at distance 0.3..3, at least cos_min off the plane."""
    n = len(x2)
    t, b = tangents(n2)
    cos = cos_min + (1 - cos_min) * rng.random(n)
    phi = 2 * np.pi * rng.random(n)
    sin = np.sqrt(1 - cos * cos)
    d = (sin * np.cos(phi))[:, None] * t + (sin * np.sin(phi))[:, None] * b + cos[:, None] * n2
    return x2 + d * rng.uniform(0.3, 3.0, n)[:, None]


def sample_reservoirs(x2, ng2, lo=1.0, W=1.0, M=1.0):
    n = len(x2)
    r = Reservoirs.empty(n)
    r.x2[:] = x2
    r.ng2[:] = ng2
    r.n2[:] = ng2
    r.prim2[:] = 0
    r.lo[:] = lo
    r.W[:] = W
    r.M[:] = M
    return r


# --- (1) the Jacobian ----------------------------------------------------------------

def test01_jacobian_is_ratio_of_solid_angles(rng):
    """J(from -> to) = solid angle of a small patch at x2 seen from x1_to over
    that seen from x1_from, measured from the patch's corners."""
    n = 500
    x2 = rng.uniform(-2, 2, (n, 3))
    n2 = unit(rng.normal(size=(n, 3)))
    x1_from = hemisphere_points(x2, n2, rng)
    x1_to = hemisphere_points(x2, n2, rng)
    t, b = tangents(n2)
    half = 1e-4
    omega_from = patch_solid_angle(x1_from, x2, t, b, half)
    omega_to = patch_solid_angle(x1_to, x2, t, b, half)
    expected = omega_to / omega_from
    j = jacobian(x1_from.astype(np.float32), x1_to.astype(np.float32), x2.astype(np.float32),
                 n2.astype(np.float32)).astype(np.float64)
    rel = np.abs(j - expected) / expected
    assert rel.max() < 1e-2, (rel.max(), j[rel.argmax()], expected[rel.argmax()])
    # Swapping the ends inverts it; the side of the surface does not matter.
    j_back = jacobian(x1_to, x1_from, x2, n2).astype(np.float64)
    assert np.allclose(j * j_back, 1.0, rtol=1e-4)
    assert np.allclose(jacobian(x1_from, x1_to, x2, -n2), j, rtol=1e-5)


def test02_jacobian_degenerate_is_finite():
    """A visible point in the plane of x2 (zero cosine) gives a finite value, not NaN."""
    x2 = np.zeros((2, 3), np.float32)
    n2 = np.float32([[0, 0, 1], [0, 0, 1]])
    a = np.float32([[1, 0, 0], [0, 0, 1]])
    b = np.float32([[0, 0, 1], [1, 0, 0]])
    j = jacobian(a, b, x2, n2)
    assert np.isfinite(j).all()
    assert (j[1] == 0) and (j[0] == 0 or j[0] > J_MAX)


def test03_shifted_weights_integrate_at_the_receiver(rng):
    """Samples found by cosine-sampling directions at the owner, shifted to the
    receiver with shift_weight (lo = 1, M = 1, W = 1 / pdf at the owner), have
    mean equal to the integral of the receiver's cosine over the solid angle of
    the surface they lie on: the Jacobian converts densities the right way round."""
    n = 400_000
    owner = np.array([0.0, 0.0, 0.0])
    receiver = np.array([0.6, 0.3, 0.1])
    n_owner = unit(np.array([0.0, 0.2, 1.0]))
    n_recv = unit(np.array([0.3, -0.1, 1.0]))
    # A rectangle above both, facing down: z = 1.2, x in [-0.5, 1.5], y in [-1, 0.8].
    z, xr, yr = 1.2, (-0.5, 1.5), (-1.0, 0.8)
    ng = np.array([0.0, 0.0, -1.0])

    t, b = tangents(n_owner[None])
    u = rng.random((n, 2))
    r, phi = np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
    cz = np.sqrt(np.maximum(0, 1 - r * r))
    d = (r * np.cos(phi))[:, None] * t + (r * np.sin(phi))[:, None] * b + cz[:, None] * n_owner
    pdf = cz / np.pi
    s = (z - owner[2]) / np.where(d[:, 2] > 0, d[:, 2], np.nan)
    x2 = owner + s[:, None] * d
    hit = (d[:, 2] > 0) & (x2[:, 0] >= xr[0]) & (x2[:, 0] <= xr[1]) & (x2[:, 1] >= yr[0]) & (x2[:, 1] <= yr[1])
    x2, pdf = x2[hit], pdf[hit]
    res = sample_reservoirs(x2.astype(np.float32), np.tile(ng, (len(x2), 1)).astype(np.float32),
                            W=(1.0 / pdf).astype(np.float32))
    m = len(x2)
    w = shift_weight(res, np.tile(owner, (m, 1)).astype(np.float32), np.tile(receiver, (m, 1)).astype(np.float32),
                     np.tile(n_recv, (m, 1)).astype(np.float32), np.tile(n_recv, (m, 1)).astype(np.float32),
                     biased=False).astype(np.float64)
    est = np.zeros(n)
    est[np.nonzero(hit)[0]] = w
    # Reference: integral over the rectangle of cos_recv cos_x2 / d^2 (and the
    # same J window shift_weight applies), by the midpoint rule.
    k = 600
    gx = xr[0] + (np.arange(k) + 0.5) / k * (xr[1] - xr[0])
    gy = yr[0] + (np.arange(k) + 0.5) / k * (yr[1] - yr[0])
    px, py = np.meshgrid(gx, gy, indexing="ij")
    p = np.stack([px.ravel(), py.ravel(), np.full(k * k, z)], axis=1)
    to = p - receiver
    d2 = np.einsum("ij,ij->i", to, to)
    cos_r = np.maximum(to @ n_recv, 0) / np.sqrt(d2)
    cos_2 = np.abs(to @ ng) / np.sqrt(d2)
    jj = jacobian(np.tile(owner, (k * k, 1)), np.tile(receiver, (k * k, 1)), p, np.tile(ng, (k * k, 1)))
    inside = (jj >= J_MIN) & (jj <= J_MAX)
    area = (xr[1] - xr[0]) * (yr[1] - yr[0]) / (k * k)
    expected = float((cos_r * cos_2 / d2 * inside).sum() * area)
    err = est.std() / np.sqrt(n)
    assert abs(est.mean() - expected) < 4.5 * err + 1e-3 * expected, (est.mean(), expected, err)
    assert inside.mean() > 0.9          # the test is about J, not its window


# --- (2) the target function at a receiver ---------------------------------------------

def test04_target_at_is_zero_behind_either_surface():
    x2 = np.zeros((6, 3), np.float32)
    ng2 = np.tile(np.float32([0, 0, 1]), (6, 1))        # x2 faces +z
    res = sample_reservoirs(x2, ng2, lo=2.0)
    x1 = np.float32([[0, 0, 1], [0, 0, 1], [0, 0, -1], [1, 0, 1], [0, 0, 1], [1, 0, 1]])
    ng1 = np.float32([[0, 0, -1], [0, 0, 1], [0, 0, 1], [-1, 0, 0], [0, 0, -1], [-1, 0, 0]])
    ns1 = ng1.copy()
    ns1[5] = [1, 0, 0]                                    # shading normal facing away
    res.prim2[4] = Reservoirs.NO_SAMPLE
    t = target_at(res, x1, ng1, ns1)
    # 0: facing each other, cos 1; 1: x2 behind the receiver; 2: receiver behind
    # x2; 3: at 45 degrees; 4: no sample; 5: shading cosine negative.
    assert t[0] == pytest.approx(2.0, rel=1e-5)
    assert t[1] == 0 and t[2] == 0 and t[4] == 0 and t[5] == 0
    assert t[3] == pytest.approx(2.0 * np.sqrt(0.5), rel=1e-5)


# --- (3) rejecting and clamping --------------------------------------------------------

@pytest.mark.parametrize("j_true", [0.05, 0.09, 0.2, 0.5, 1.0, 2.0, 5.0, 9.0, 11.0, 20.0])
def test05_shift_weight_rejects_and_clamps(j_true):
    """x2 at the origin facing +z; owner and receiver straight above it at
    distances with d_owner^2 / d_receiver^2 = J. Unbiased: p_hat W M J inside
    [J_MIN, J_MAX], 0 outside; biased: J clamped to J_CLAMP inside, 0 outside."""
    d_owner = 1.0
    d_recv = d_owner / np.sqrt(j_true)
    res = sample_reservoirs(np.zeros((1, 3), np.float32), np.float32([[0, 0, 1]]), lo=1.0, W=0.7, M=3.0)
    owner = np.float32([[0, 0, d_owner]])
    recv = np.float32([[0, 0, d_recv]])
    down = np.float32([[0, 0, -1]])
    assert jacobian(owner, recv, res.x2, res.ng2)[0] == pytest.approx(j_true, rel=1e-4)
    ub = shift_weight(res, owner, recv, down, down, biased=False)[0]
    bi = shift_weight(res, owner, recv, down, down, biased=True)[0]
    if J_MIN <= j_true <= J_MAX:
        assert ub == pytest.approx(1.0 * 0.7 * 3.0 * j_true, rel=1e-4)
        assert bi == pytest.approx(1.0 * 0.7 * 3.0 * np.clip(j_true, *J_CLAMP), rel=1e-4)
    else:
        assert ub == 0 and bi == 0


def test06_shift_weight_is_zero_where_target_is():
    """A sample behind the receiver gets no weight, whatever J."""
    res = sample_reservoirs(np.zeros((1, 3), np.float32), np.float32([[0, 0, 1]]))
    up = np.float32([[0, 0, 1]])
    w = shift_weight(res, np.float32([[0, 0, 1]]), np.float32([[0, 0, 1.2]]), up, up, biased=True)
    assert w[0] == 0
