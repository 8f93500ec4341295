"""Light sampling with what BSDF rays see (MIS of both converges to the
same irradiance), power-proportional light selection, lights' moves
(LightSet.follow) and Light Falloff. Helpers: tests/support/light_util.py."""

import numpy as np
import pytest

from support.chi2 import pooled_chi2
from support.light_util import COLOR, ORIGIN, TILTED, TRIANGLE, UP, area_row, light_set, nee, unit
from restir_gi.core import Lights, Materials, make_scene
from restir_gi.core.lights.light_set import LightSet
from restir_gi.core.geometry.accel import Accel
from restir_gi.core.geometry.interaction import surface_hits
from restir_gi.core.util.vectors import luminance
from restir_gi.core.sampling.warps import power_heuristic, square_to_cosine_hemisphere
from restir_gi.core.scene import (LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN, SHAPE_ELLIPSE,
                                  SHAPE_SQUARE)


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
