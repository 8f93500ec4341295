"""Emitters of core.lights.light_set against closed-form or numerically integrated
irradiance (conventions in docs/cycles-conventions.md). Light sampling
against BSDF rays and light selection: test_light_sampling.py."""

import numpy as np
import pytest

from support.light_util import COLOR, ORIGIN, TILTED, TRIANGLE, UP, area_row, assert_close, light_set, nee, unit
from restir_gi.core.scene import (LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN, SHAPE_DISK, SHAPE_ELLIPSE,
                                  SHAPE_RECTANGLE, SHAPE_SQUARE)


# --- reference irradiance ----------------------------------------------------------------

def polygon_irradiance(p, n, verts, radiance):
    """Lambert's formula: irradiance at p (normal n) from a uniform polygon that
    lies wholly above p's tangent plane."""
    v = [unit(q - p) for q in np.asarray(verts, np.float64)]
    total = 0.0
    for a, b in zip(v, v[1:] + v[:1]):
        c = np.cross(a, b)
        total += np.arccos(np.clip(a @ b, -1, 1)) * (c / np.linalg.norm(c)) @ n
    return abs(total) / 2 * np.asarray(radiance, np.float64)


def ellipse_irradiance(p, n, centre, eu, ev, emit_dir, radiance, mask=None, k=600):
    """Irradiance from an ellipse centre + x eu + y ev (x^2 + y^2 <= 1) emitting
    along emit_dir, by midpoint quadrature in polar coordinates."""
    rho = (np.arange(k) + 0.5) / k
    phi = (np.arange(k) + 0.5) / k * 2 * np.pi
    R, F = np.meshgrid(rho, phi, indexing="ij")
    R, F = R.ravel(), F.ravel()
    q = centre + (R * np.cos(F))[:, None] * eu + (R * np.sin(F))[:, None] * ev
    dA = np.linalg.norm(np.cross(eu, ev)) * R * (1.0 / k) * (2 * np.pi / k)
    d = q - p
    d2 = np.einsum("ij,ij->i", d, d)
    w = d / np.sqrt(d2)[:, None]
    cos_r = np.maximum(w @ n, 0)
    cos_l = np.maximum(-(w @ emit_dir), 0)
    m = 1.0 if mask is None else mask(-w)
    return (cos_r * cos_l * m * dA / d2).sum() * np.asarray(radiance, np.float64)


def rect_corners(centre, au, av, su, sv):
    au, av = np.asarray(au, np.float64), np.asarray(av, np.float64)
    return [centre + sx * 0.5 * su * au + sy * 0.5 * sv * av for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]


def spot_mask(dir_from_light, axis, size, blend):
    cos_a = dir_from_light @ axis
    cos_half = np.cos(size / 2)
    smooth = (1 - cos_half) * blend
    if smooth <= 0:
        return (cos_a > cos_half).astype(np.float64)
    t = np.clip((cos_a - cos_half) / smooth, 0, 1)
    return 3 * t * t - 2 * t * t * t


def test00_reference_helpers_agree():
    # Lambert's polygon formula against brute-force quadrature over a square.
    c, s = np.array([0.2, 0.1, 1.5]), 1.0
    poly = polygon_irradiance(ORIGIN, TILTED, rect_corners(c, [1, 0, 0], [0, 1, 0], s, s), 1.0)
    k = 800
    g = ((np.arange(k) + 0.5) / k - 0.5) * s
    X, Y = np.meshgrid(g, g)
    q = np.stack([c[0] + X.ravel(), c[1] + Y.ravel(), np.full(k * k, c[2])], axis=1)
    d2 = (q * q).sum(axis=1)
    w = q / np.sqrt(d2)[:, None]
    quad = (np.maximum(w @ TILTED, 0) * w[:, 2] / d2).sum() * (s / k) ** 2
    assert poly == pytest.approx(quad, rel=1e-5)
    # A disk facing the receiver on its axis: pi L r^2 / (d^2 + r^2).
    e = ellipse_irradiance(ORIGIN, UP, np.array([0, 0, 2.0]), np.array([0.5, 0, 0]), np.array([0, 0.5, 0]),
                           -UP, 1.0)
    assert e == pytest.approx(np.pi * 0.25 / (4 + 0.25), rel=1e-5)


# --- NEE against reference irradiance ----------------------------------------------------------

def test01_point_light_radius_zero(rng):
    c = np.array([0.3, -0.2, 2.0])
    _, ls = light_set([{"kind": LIGHT_POINT, "position": c, "power": 100 * COLOR, "radius": 0.0}])
    d2 = c @ c
    for n in (UP, TILTED):
        est, err, s = nee(ls, ORIGIN, n, rng, count=1000)
        assert s.delta.all() and np.allclose(s.pdf, 1.0)
        assert np.allclose(est, 100 * COLOR / (4 * np.pi) * (unit(c) @ n) / d2, rtol=1e-5)
    # Cycles: P = 100 W at 2 m straight above an albedo-0.8 Lambert plane gives 0.5066.
    _, ls = light_set([{"kind": LIGHT_POINT, "position": (0, 0, 2), "power": 100 * COLOR}])
    est, _, _ = nee(ls, ORIGIN, UP, rng, count=10)
    assert 0.8 / np.pi * est[0] == pytest.approx(0.5066, abs=1e-4)


@pytest.mark.parametrize("normal", ["up", "tilted"])
def test02_point_light_soft_falloff(normal, rng):
    """Soft falloff: a disk of radius r facing the receiver, radiance P / (4 pi^2 r^2)."""
    n = UP if normal == "up" else TILTED
    c, r = np.array([0.4, 0.3, 1.5]), 0.6
    _, ls = light_set([{"kind": LIGHT_POINT, "position": c, "power": 100 * COLOR, "radius": r,
                        "soft_falloff": True}])
    est, err, s = nee(ls, ORIGIN, n, rng)
    assert not s.delta.any()
    axis = unit(c)
    eu = unit(np.cross(axis, [1, 0, 0])) * r
    ev = np.cross(axis, eu / r) * r
    ref = ellipse_irradiance(ORIGIN, n, c, eu, ev, -axis, 100 * COLOR / (4 * np.pi ** 2 * r * r))
    if normal == "up":
        # Cycles' closed form for a receiver facing the light: I cos / (d^2 + r^2).
        ref_cycles = 100 * COLOR / (4 * np.pi) * (axis @ n) / (c @ c + r * r)
        assert np.allclose(ref, ref_cycles, rtol=0.02)
    assert_close(est, err, ref)


def test03_point_light_sphere(rng):
    """Soft falloff off: a sphere; irradiance I cos / d^2 while it is above the horizon."""
    c, r = np.array([0.5, 0.0, 2.0]), 0.5
    _, ls = light_set([{"kind": LIGHT_POINT, "position": c, "power": 100 * COLOR, "radius": r,
                        "soft_falloff": False}])
    for n in (UP, TILTED):
        est, err, s = nee(ls, ORIGIN, n, rng)
        assert_close(est, err, 100 * COLOR / (4 * np.pi) * (unit(c) @ n) / (c @ c))
    # From inside the sphere the light gives nothing (and no NaN).
    est, _, s = nee(ls, c + 0.1, UP, rng, count=100)
    assert np.isfinite(s.radiance).all() and np.allclose(est, 0)


@pytest.mark.parametrize("angle_deg,mask", [(0, 1.0), (15, 1.0), (22, 0.979), (25, 0.650), (28, 0.159), (35, 0.0)])
def test04_spot_light(angle_deg, mask, rng):
    """Spot of size 60 degrees and blend 0.5 above the receiver, seen at an angle
    off its axis; masks from the Cycles measurements in the conventions doc."""
    a = np.radians(angle_deg)
    c = np.array([2 * np.tan(a), 0.0, 2.0])
    size, blend = np.radians(60), 0.5
    _, ls = light_set([{"kind": LIGHT_SPOT, "position": c, "direction": (0, 0, -1), "power": 100 * COLOR,
                        "spot_size": size, "spot_blend": blend}])
    m = spot_mask(unit(-c), np.array([0, 0, -1.0]), size, blend)
    assert m == pytest.approx(mask, abs=1e-3)
    est, _, _ = nee(ls, ORIGIN, UP, rng, count=100)
    assert np.allclose(est, 100 * COLOR / (4 * np.pi) * m * unit(c)[2] / (c @ c), rtol=1e-5, atol=1e-9)


def test05_spot_light_with_radius_and_hard_edge(rng):
    # r = 0.5 on the axis, soft falloff: E = I / (d^2 + r^2) (Cycles: pixel 0.47679).
    _, ls = light_set([{"kind": LIGHT_SPOT, "position": (0, 0, 2), "direction": (0, 0, -1),
                        "power": 100 * COLOR, "radius": 0.5, "spot_size": np.radians(60), "spot_blend": 0.5}])
    est, err, _ = nee(ls, ORIGIN, UP, rng)
    assert 0.8 / np.pi * est[0] == pytest.approx(0.47679, rel=0.01)
    assert_close(est, err, 100 * COLOR / (4 * np.pi) / (4 + 0.25), rel=0.005)
    # blend 0: a hard edge, full brightness just inside, nothing just outside.
    for deg, expected in ((29, 1.0), (31, 0.0)):
        a = np.radians(deg)
        c = np.array([2 * np.tan(a), 0.0, 2.0])
        _, ls = light_set([{"kind": LIGHT_SPOT, "position": c, "direction": (0, 0, -1), "power": 100 * COLOR,
                            "spot_size": np.radians(60), "spot_blend": 0.0}])
        est, _, _ = nee(ls, ORIGIN, UP, rng, count=10)
        assert np.allclose(est, expected * 100 * COLOR / (4 * np.pi) * np.cos(a) / (c @ c), rtol=1e-5)


@pytest.mark.parametrize("angle_deg", [0.0, 0.526, 10.0])
def test06_sun(angle_deg, rng):
    """Irradiance S cos(theta) whatever the angular diameter (Cycles: normalised disk)."""
    to_sun = unit([0.3, 0.2, 1.0])
    _, ls = light_set([{"kind": LIGHT_SUN, "direction": -to_sun, "power": 3 * COLOR,
                        "angle": np.radians(angle_deg)}])
    for n in (UP, TILTED):
        est, err, s = nee(ls, ORIGIN, n, rng)
        assert s.delta.all()            # no BSDF ray ever finds the sun: no MIS
        assert_close(est, err, 3 * COLOR * (to_sun @ n), rel=1e-4)


AREA_CASES = {
    # name: (shape, size_u, size_v, Cycles pixel for P = 100 at h = 1.5 on albedo 0.8)
    "square": (SHAPE_SQUARE, 1.0, 1.0, 3.1403),
    "rectangle": (SHAPE_RECTANGLE, 2.0, 0.5, 2.7894),
    "disk": (SHAPE_DISK, 1.0, 1.0, 3.2423),
    "ellipse": (SHAPE_ELLIPSE, 2.0, 0.5, 2.9567),
}


def area_reference(shape, su, sv, centre, au, av, power, p, n):
    au, av = unit(au), unit(av)
    area = (np.pi / 4 if shape in (SHAPE_DISK, SHAPE_ELLIPSE) else 1.0) * su * sv
    L = np.asarray(power, np.float64) / (np.pi * area)
    if shape in (SHAPE_DISK, SHAPE_ELLIPSE):
        return ellipse_irradiance(p, n, centre, 0.5 * su * au, 0.5 * sv * av, np.cross(au, av), L)
    return polygon_irradiance(p, n, rect_corners(centre, au, av, su, sv), L)


@pytest.mark.parametrize("name", sorted(AREA_CASES))
def test07_area_light(name, rng):
    shape, su, sv, cycles_pixel = AREA_CASES[name]
    # Facing down from 1.5 m, as in the Cycles measurement.
    _, ls = light_set([area_row(shape, su, sv, (0, 0, 1.5), (1, 0, 0), (0, -1, 0), (100, 100, 100))])
    est, err, _ = nee(ls, ORIGIN, UP, rng)
    ref = area_reference(shape, su, sv, np.array([0, 0, 1.5]), (1, 0, 0), (0, -1, 0), (100,) * 3, ORIGIN, UP)
    assert 0.8 / np.pi * ref[0] == pytest.approx(cycles_pixel, rel=2e-4)
    assert_close(est, err, ref)
    # Rotated, off-centre and seen by a tilted receiver.
    centre, au = np.array([0.4, -0.3, 1.2]), unit([1, 0.3, 0.2])
    av = unit(np.cross(unit([0.1, -0.2, -1.0]), au))       # emits roughly downwards
    _, ls = light_set([area_row(shape, su, sv, centre, au, av, 100 * COLOR)])
    est, err, _ = nee(ls, ORIGIN, TILTED, rng)
    assert_close(est, err, area_reference(shape, su, sv, centre, au, av, 100 * COLOR, ORIGIN, TILTED))
    # One-sided: nothing reaches a receiver behind it.
    emit = np.cross(au, av)
    est, _, s = nee(ls, centre - 0.5 * emit, emit, rng, count=1000)
    assert np.allclose(est, 0) and (s.pdf == 0).all()



@pytest.mark.parametrize("winding", ["down", "up"])
def test08_emissive_triangle(winding, rng):
    """Both faces emit the emission colour x strength (Cycles' mesh lights)."""
    verts = TRIANGLE if winding == "down" else TRIANGLE[::-1]
    Le = np.array([3.0, 1.5, 0.75])
    _, ls = light_set([], verts, Le)
    for n in (UP, TILTED):
        est, err, s = nee(ls, ORIGIN, n, rng)
        assert_close(est, err, polygon_irradiance(ORIGIN, n, verts, Le))
    # One-sided emission: only the side the winding faces lights the receiver.
    _, ls1 = light_set([], verts, Le, two_sided=False)
    est, _, _ = nee(ls1, ORIGIN, UP, rng, count=20000)
    facing_receiver = (np.cross(verts[1] - verts[0], verts[2] - verts[0]) @ (ORIGIN - verts[0])) > 0
    assert np.allclose(est, 0) != facing_receiver
