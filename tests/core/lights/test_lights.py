"""Emitters of core.lights.light_set against closed-form or numerically integrated
irradiance (conventions in docs/cycles-conventions.md), the consistency of
light sampling with what BSDF rays see (MIS of both converges to the same
irradiance), and power-proportional light selection."""

import numpy as np
import pytest

from support.chi2 import pooled_chi2
from restir_gi.core import Lights, Materials, make_scene
from restir_gi.core.geometry.accel import Accel
from restir_gi.core.geometry.interaction import surface_hits
from restir_gi.core.lights.light_set import LightSet
from restir_gi.core.util.vectors import luminance
from restir_gi.core.sampling.warps import power_heuristic, square_to_cosine_hemisphere
from restir_gi.core.scene import (LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN, SHAPE_DISK, SHAPE_ELLIPSE,
                        SHAPE_RECTANGLE, SHAPE_SQUARE)

N = 200_000
COLOR = np.array([1.0, 0.5, 0.25])
ORIGIN = np.zeros(3)
UP = np.array([0.0, 0.0, 1.0])


def unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


TILTED = unit([0.4, -0.3, 1.0])


def light_set(rows, tri_verts=None, emission=(0, 0, 0), two_sided=True):
    """A LightSet over analytic lights and, optionally, emissive triangles."""
    lights = Lights.from_list(rows)
    if tri_verts is None:
        scene = make_scene(np.zeros((0, 3)), np.zeros((0, 3)), lights=lights)
    else:
        v = np.asarray(tri_verts, np.float32).reshape(-1, 3)
        t = np.arange(len(v), dtype=np.int32).reshape(-1, 3)
        mats = Materials.from_list([{"base_color": (0, 0, 0), "emission": emission}])
        scene = make_scene(v, t, materials=mats, lights=lights)
    return scene, LightSet(scene, emission_two_sided=two_sided)


def nee(ls, p, n, rng, count=N):
    """Mean and standard error (3,) of radiance * cos / pdf over light samples."""
    P = np.ascontiguousarray(np.broadcast_to(np.float32(p), (count, 3)))
    s = ls.sample(P, rng.random(count, dtype=np.float32), rng.random((count, 2), dtype=np.float32))
    cos = np.maximum(s.wi.astype(np.float64) @ n, 0.0)
    val = np.where((s.pdf > 0)[:, None], s.radiance * (cos / np.where(s.pdf > 0, s.pdf, 1))[:, None], 0.0)
    return val.mean(axis=0), val.std(axis=0) / np.sqrt(count), s


def assert_close(est, err, ref, rel=2e-4, max_rel_err=0.01):
    ref = np.asarray(ref, np.float64)
    assert (err <= max_rel_err * np.abs(ref).max() + 1e-12).all(), "too noisy to tell anything"
    assert (np.abs(est - ref) <= 4.5 * err + rel * np.abs(ref) + 1e-9).all(), (est, ref, err)


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


def area_row(shape, su, sv, centre, au, av, power):
    au, av = unit(au), unit(av)
    return {"kind": LIGHT_AREA, "position": centre, "direction": np.cross(au, av), "axis_u": au,
            "axis_v": av, "power": power, "shape": shape, "size_u": su, "size_v": sv}


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


TRIANGLE = np.array([[-0.5, -0.4, 1.3], [0.7, -0.2, 1.1], [0.1, 0.6, 1.6]])


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


# --- NEE and BSDF sampling agree (MIS) -----------------------------------------------------

HITTABLE = {
    "area_square": lambda: ([area_row(SHAPE_SQUARE, 0.8, 0.8, (0.3, 0.2, 1.2), (1, 0.2, 0), (0.2, -1, -0.1),
                                      60 * COLOR)], None),
    "area_ellipse": lambda: ([area_row(SHAPE_ELLIPSE, 1.2, 0.5, (0.3, 0.2, 1.2), (1, 0.2, 0), (0.2, -1, -0.1),
                                       60 * COLOR)], None),
    "point_disk": lambda: ([{"kind": LIGHT_POINT, "position": (0.4, 0.3, 1.5), "power": 100 * COLOR,
                             "radius": 0.5, "soft_falloff": True}], None),
    "point_sphere": lambda: ([{"kind": LIGHT_POINT, "position": (0.4, 0.3, 1.5), "power": 100 * COLOR,
                               "radius": 0.5, "soft_falloff": False}], None),
    "spot_sphere": lambda: ([{"kind": LIGHT_SPOT, "position": (0.4, 0.3, 1.5), "direction": unit([-0.1, -0.1, -1]),
                              "power": 100 * COLOR, "radius": 0.5, "soft_falloff": False,
                              "spot_size": np.radians(70), "spot_blend": 0.6}], None),
    "triangle": lambda: ([], TRIANGLE),
    # Light Falloff in the lights' node trees: rays that cross the light see
    # the falloff of its samples.
    "point_disk_linear_falloff": lambda: ([{"kind": LIGHT_POINT, "position": (0.4, 0.3, 1.5),
                                            "power": 100 * COLOR, "radius": 0.5, "falloff": 1.0}], None),
    "point_sphere_smooth_falloff": lambda: ([{"kind": LIGHT_POINT, "position": (0.4, 0.3, 1.5),
                                              "power": 100 * COLOR, "radius": 0.5, "soft_falloff": False,
                                              "falloff_smooth": 1.5}], None),
    "area_constant_falloff": lambda: ([{**area_row(SHAPE_SQUARE, 0.8, 0.8, (0.3, 0.2, 1.2), (1, 0.2, 0),
                                                   (0.2, -1, -0.1), 60 * COLOR),
                                        "falloff": 2.0, "falloff_smooth": 0.7}], None),
}
AUX = {"kind": LIGHT_POINT, "position": (-1.0, 0.5, 2.0), "power": (40, 40, 40), "radius": 0.0}


def bsdf_rays(scene, ls, p, n, rng, count, mis, accel):
    """Irradiance estimate from cosine-sampled rays that find the lights, each
    weighted against NEE by the power heuristic (or by one)."""
    t = unit(np.cross(n, [1, 0, 0]))
    b = np.cross(n, t)
    local = square_to_cosine_hemisphere(rng.random((count, 2), dtype=np.float32)).astype(np.float64)
    wi = (local[:, 0:1] * t + local[:, 1:2] * b + local[:, 2:3] * n).astype(np.float32)
    pdf_b = (local[:, 2] / np.pi).astype(np.float32)
    o = np.ascontiguousarray(np.broadcast_to(np.float32(p), (count, 3)))
    hits = accel.intersect_closest(o, wi)
    L = ls.emitted_along(o, wi, hits.t, pdf_bsdf=pdf_b if mis else None)
    surf, idx = surface_hits(scene, o, wi, hits)
    if len(idx):
        le = ls.triangle_emission(surf.prim, surf.front)
        w = power_heuristic(pdf_b[idx], ls.pdf_triangle(surf.prim, o[idx], surf.p, wi[idx])) if mis else 1.0
        L[idx] += le * np.asarray(w)[..., None] if mis else le
    val = L.astype(np.float64) * np.pi      # L cos / pdf with pdf = cos / pi
    return val


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(HITTABLE))
def test09_mis_of_nee_and_bsdf_sampling(name, rng):
    rows, tri = HITTABLE[name]()
    Le = np.array([3.0, 1.5, 0.75])
    scene, ls = light_set(rows + [AUX], tri, Le)
    accel = Accel.from_scene(scene, threads=1)
    p, n = ORIGIN, TILTED
    # NEE alone: the reference the two other estimates must reach.
    ref_nee, err_nee, _ = nee(ls, p, n, rng, count=400_000)

    # NEE weighted by MIS (delta lights keep weight one) plus BSDF rays weighted by MIS.
    count = 400_000
    P = np.ascontiguousarray(np.broadcast_to(np.float32(p), (count, 3)))
    s = ls.sample(P, rng.random(count, dtype=np.float32), rng.random((count, 2), dtype=np.float32))
    cos = np.maximum(s.wi.astype(np.float64) @ n, 0.0)
    w = np.where(s.delta, 1.0, power_heuristic(s.pdf, (cos / np.pi).astype(np.float32)))
    nee_part = np.where((s.pdf > 0)[:, None],
                        s.radiance * (cos * w / np.where(s.pdf > 0, s.pdf, 1))[:, None], 0.0)
    bsdf_part = bsdf_rays(scene, ls, p, n, rng, count, True, accel)
    total = nee_part + bsdf_part
    est, err = total.mean(axis=0), total.std(axis=0) / np.sqrt(count)
    assert (np.abs(est - ref_nee) <= 4.5 * np.hypot(err, err_nee) + 1e-6).all(), (est, ref_nee, err, err_nee)
    assert (err < 0.01 * est).all()

    if tri is not None:
        # The NEE pdf of a sampled triangle point, recomputed from the point.
        on_tri = (s.pdf > 0) & (s.dist < 1e29) & (s.dist > 0) & ~s.delta
        q = P[on_tri] + s.wi[on_tri] * s.dist[on_tri][:, None]
        pdf_again = ls.pdf_triangle(np.zeros(on_tri.sum(), np.int32), P[on_tri], q, s.wi[on_tri])
        assert np.allclose(pdf_again, s.pdf[on_tri], rtol=1e-3)

    # BSDF rays alone (weight one) see the hittable light's full irradiance.
    for row in rows:
        row["camera_visible"] = True
    scene, ls_vis = light_set(rows, tri, Le)
    only = bsdf_rays(scene, ls_vis, p, n, rng, count, False, accel)
    ref_light, err_light, _ = nee(ls_vis, p, n, rng, count=400_000)
    est, err = only.mean(axis=0), only.std(axis=0) / np.sqrt(count)
    assert (np.abs(est - ref_light) <= 4.5 * np.hypot(err, err_light) + 1e-6).all(), (est, ref_light)
    accel.close()


# --- light selection ------------------------------------------------------------------------

def test10_selection_by_power_and_place(rng):
    rows = [
        {"kind": LIGHT_POINT, "position": (1, 0, 1), "power": (100, 100, 100)},
        {"kind": LIGHT_POINT, "position": (-1, 0, 1), "power": (300, 0, 0)},
        {"kind": LIGHT_SPOT, "position": (0, 1, 1), "power": (50, 80, 20), "spot_size": 3.0},
        {"kind": LIGHT_SUN, "direction": unit([0, -1, -1]), "power": (2, 2, 2)},
        {"kind": LIGHT_AREA, "position": (0, 0, 3), "power": (40, 40, 40), "size_u": 0.5, "size_v": 2.0},
    ]
    Le = np.array([5.0, 5.0, 5.0])
    tri = np.array([[-5, -5, 0], [5, -5, 0], [5, 5, 0]], float)    # area 50, also sets the scene size
    scene, ls = light_set(rows, tri, Le)
    radius = 0.5 * np.linalg.norm(tri.max(axis=0) - tri.min(axis=0))
    lum = [float(luminance(np.float32(r["power"]))) for r in rows]
    weights = np.array(lum[:3] + [lum[3] * np.pi * radius ** 2, lum[4],
                                  float(luminance(np.float32(Le))) * 50 * np.pi * 2])
    assert np.allclose(ls.distribution.pmf, weights / weights.sum(), rtol=1e-5)

    # Sampled frequencies: the delta lights are told apart by their direction.
    count = 200_000
    p = np.float32([0, 0, 1])
    P = np.ascontiguousarray(np.broadcast_to(p, (count, 3)))
    s = ls.sample(P, rng.random(count, dtype=np.float32), rng.random((count, 2), dtype=np.float32))
    dirs = np.array([unit(np.array(r["position"], float) - p) for r in rows[:3]] + [-np.array(rows[3]["direction"])])
    which = np.full(count, -1)
    for i, d in enumerate(dirs):
        which[np.all(np.abs(s.wi - d) < 1e-5, axis=1) & s.delta] = i
    which[(which < 0)] = 4          # area light and triangle: the rest, told apart by distance below
    which[(which == 4) & (s.wi[:, 2] < 0)] = 5
    counts = np.bincount(which, minlength=6)
    # The lamps and the triangle are chosen by where p is (core/lights/light_grid.py),
    # with the probability selection_pmf gives, which sums to one.
    pmf = ls.selection_pmf(np.arange(6), np.repeat(p[None], 6, axis=0))
    assert np.isclose(pmf.sum(), 1.0) and pmf[3] == ls.distribution.pmf[3]
    p_value, *_ = pooled_chi2(counts, pmf * count)
    assert p_value > 0.001, (counts, pmf * count)
    # Delta lights report their selection probability as their pdf.
    for i in range(4):
        assert np.allclose(s.pdf[which == i], pmf[i], rtol=1e-6)


def test11_no_lights_and_degenerate_points(rng):
    _, ls = light_set([])
    assert ls.count == 0
    s = ls.sample(np.zeros((5, 3), np.float32), rng.random(5, dtype=np.float32),
                  rng.random((5, 2), dtype=np.float32))
    assert (s.pdf == 0).all() and (s.radiance == 0).all()
    assert (ls.emitted_along(np.zeros((5, 3), np.float32), np.float32([[0, 0, 1]] * 5),
                             np.full(5, np.inf, np.float32), pdf_bsdf=np.ones(5, np.float32)) == 0).all()
    # A shading point exactly at a point light or on an area light: finite, zero or not, never NaN.
    _, ls = light_set([{"kind": LIGHT_POINT, "position": (0, 0, 0), "power": (10, 10, 10)},
                       area_row(SHAPE_SQUARE, 1, 1, (0, 0, 0), (1, 0, 0), (0, -1, 0), (10, 10, 10))])
    s = ls.sample(np.zeros((1000, 3), np.float32), rng.random(1000, dtype=np.float32),
                  rng.random((1000, 2), dtype=np.float32))
    assert np.isfinite(s.radiance).all() and np.isfinite(s.pdf).all() and np.isfinite(s.wi).all()


def test12_follow_matches_a_new_set(rng):
    """LightSet.follow (a frame where only non-emitting objects moved) gives
    the set a new build gives: the sun's weight follows the scene's size."""
    rows = [{"kind": LIGHT_SUN, "direction": unit([0, -1, -1]), "power": (2, 2, 2)},
            {"kind": LIGHT_POINT, "position": (1, 0, 1), "power": (100, 100, 100)}]
    v = np.float32([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [0, 0, 1], [0.5, 0, 1], [0, 0.5, 1]])
    mats = Materials.from_list([{"emission": (4, 4, 4)}, {"base_color": (0.5, 0.5, 0.5)}])
    make = lambda verts: make_scene(verts, np.int32([[0, 1, 2], [3, 4, 5]]),  # noqa: E731
                                    material_ids=np.int32([0, 1]), object_ids=np.int32([0, 1]),
                                    materials=mats, lights=Lights.from_list(rows))
    scene = make(v)
    ls = LightSet(scene)
    assert ls.emitting_objects.tolist() == [0]
    moved = v.copy()
    moved[3:] += np.float32([6, 0, 3])                  # the plain triangle, far out: the scene grows
    followed = ls.follow(make(moved))
    fresh = LightSet(make(moved))
    assert followed is ls and followed.scene_radius == fresh.scene_radius > 2.0
    assert np.allclose(followed.distribution.pmf, fresh.distribution.pmf, rtol=1e-6)
    assert not np.allclose(LightSet(scene).distribution.pmf, fresh.distribution.pmf, rtol=1e-3)
    p = rng.uniform(-1, 1, (500, 3)).astype(np.float32)
    u1, u2 = rng.random(500, dtype=np.float32), rng.random((500, 2), dtype=np.float32)
    a, b = followed.sample(p, u1, u2), fresh.sample(p, u1, u2)
    assert np.array_equal(a.wi, b.wi) and np.allclose(a.pdf, b.pdf, rtol=1e-6)


@pytest.mark.parametrize("k,smooth", [(1.0, 0.0), (2.0, 0.0), (0.0, 3.0), (1.0, 0.5)])
def test13_light_falloff(k, smooth, rng):
    """Light Falloff (Cycles' svm light falloff): a point lamp's radiance
    times d^k and d^2 / (s + d^2), d the distance to it; a sun's stays."""
    c = np.array([0.3, -0.2, 2.0])
    d2 = c @ c
    _, ls = light_set([{"kind": LIGHT_POINT, "position": c, "power": 100 * COLOR, "falloff": k,
                        "falloff_smooth": smooth}])
    est, _, _ = nee(ls, ORIGIN, UP, rng, count=100)
    law = d2 ** (k / 2) * (d2 / (smooth + d2) if smooth > 0 else 1.0)
    assert np.allclose(est, 100 * COLOR / (4 * np.pi) * (unit(c) @ UP) / d2 * law, rtol=1e-5)
    _, sun = light_set([{"kind": LIGHT_SUN, "direction": (0, 0, -1), "power": COLOR, "falloff": k,
                         "falloff_smooth": smooth}])
    est, _, _ = nee(sun, ORIGIN, UP, rng, count=100)
    assert np.allclose(est, COLOR, rtol=1e-5)
