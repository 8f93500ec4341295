"""Emissive triangles as lights (core/lights/emissive_triangles.py): the density of
the points they give next-event estimation, in both of its regimes (area
sampling from afar, solid-angle sampling close by), the pdf a BSDF ray that
hits one is weighed with, which faces emit, and their bounds.

The estimator checked is E[1 / pdf] over sampled directions: it equals the
solid angle the triangle covers exactly when the pdf is the density of the
directions sampled and every direction through the triangle can be drawn;
the solid angle comes from the closed form of Van Oosterom and Strackee."""

import numpy as np
import pytest

from restir_gi.core import Materials, make_scene
from restir_gi.core.lights.emissive_triangles import EmissiveTriangles

N = 200_000
CORNERS = np.array([[-0.5, -0.4, 1.0], [0.7, -0.2, 1.1], [0.1, 0.6, 1.2]])
LE = (3.0, 1.5, 0.75)


def triangles(corners=CORNERS, two_sided=True, emission=LE):
    v = np.asarray(corners, np.float32)
    mats = Materials.from_list([{"base_color": (0, 0, 0), "emission": emission}])
    scene = make_scene(v, np.array([[0, 1, 2]], np.int32), materials=mats)
    return EmissiveTriangles(scene, two_sided=two_sided)


def solid_angle(p, corners):
    """Solid angle of a triangle seen from p (Van Oosterom and Strackee 1983)."""
    a, b, c = (np.asarray(q, np.float64) - p for q in corners)
    la, lb, lc = (np.linalg.norm(v) for v in (a, b, c))
    num = abs(a @ np.cross(b, c))
    den = la * lb * lc + (a @ b) * lc + (a @ c) * lb + (b @ c) * la
    return 2.0 * np.arctan2(num, den)


# Points from which the triangle covers 4.1 sr and 0.39 sr (sampled by solid
# angle), 0.012 sr and, nearly in its plane, 0.0007 sr (sampled by area).
POINTS = {"close": (0.1, 0.0, 0.95), "middle": (0.0, 0.0, 0.0), "far": (1.0, -2.0, -5.0),
          "grazing": (2.5, 0.3, 1.3)}


@pytest.mark.parametrize("name", sorted(POINTS))
def test01_inverse_pdf_integrates_to_the_solid_angle(name, rng):
    tri = triangles()
    p = np.asarray(POINTS[name], np.float64)
    P = np.ascontiguousarray(np.broadcast_to(np.float32(p), (N, 3)))
    slot = np.zeros(N, np.int32)
    wi, dist, rad, pdf, delta = tri.sample(slot, P, rng.random((N, 2), dtype=np.float32))
    assert not delta.any() and (pdf > 0).all() and np.isfinite(pdf).all()
    inv = 1.0 / pdf.astype(np.float64)
    omega = solid_angle(p, CORNERS)
    err = inv.std() / np.sqrt(N)
    assert abs(inv.mean() - omega) <= 4.5 * err + 1e-4 * omega, (inv.mean(), omega, err)
    # Every sample lies on the triangle and carries its emission.
    q = p + wi.astype(np.float64) * dist.astype(np.float64)[:, None]
    n = np.cross(CORNERS[1] - CORNERS[0], CORNERS[2] - CORNERS[0])
    assert np.abs((q - CORNERS[0]) @ (n / np.linalg.norm(n))).max() < 1e-4 * max(1.0, np.linalg.norm(p))
    assert np.allclose(rad, LE)
    # A BSDF ray that hits the same point is weighed with the same density.
    again = tri.pdf(slot, P, q.astype(np.float32), wi)
    assert np.allclose(again, pdf, rtol=2e-3), np.abs(again / pdf - 1).max()


def test02_the_integral_tells_a_wrong_density(rng):
    """The estimator of test01 fails a density off by the cosine at the
    triangle (area measure taken for solid angle): it can fail."""
    tri = triangles()
    p = np.asarray(POINTS["far"], np.float64)
    P = np.ascontiguousarray(np.broadcast_to(np.float32(p), (N, 3)))
    wi, dist, _rad, pdf, _ = tri.sample(np.zeros(N, np.int32), P, rng.random((N, 2), dtype=np.float32))
    cos_l = np.abs(wi.astype(np.float64) @ tri.normal[0].astype(np.float64))
    wrong = 1.0 / (pdf.astype(np.float64) / cos_l)
    err = wrong.std() / np.sqrt(N)
    assert abs(wrong.mean() - solid_angle(p, CORNERS)) > 10 * err


def test03_faces_that_emit():
    """Two-sided triangles emit toward rays from either side (Cycles' mesh
    lights); one-sided ones only from the side their winding faces, and a
    point behind them gets no light sample."""
    prim, front = np.zeros(2, np.int64), np.array([True, False])
    both = triangles(two_sided=True)
    assert np.allclose(both.emitted(prim, front), LE)
    one = triangles(two_sided=False)
    assert np.allclose(one.emitted(prim, front), [LE, (0, 0, 0)])
    n = one.normal[0].astype(np.float64)
    centre = CORNERS.mean(axis=0)
    for side, lit in ((1.0, True), (-1.0, False)):
        P = np.float32(centre + side * n)[None].repeat(64, axis=0)
        *_, rad, pdf, _ = one.sample(np.zeros(64, np.int32), P, np.full((64, 2), 0.3, np.float32))
        assert (pdf > 0).all() == lit and (np.abs(rad).max() > 0) == lit


def test04_only_emitting_faces_are_lights_and_boxes_hold_them():
    dark = triangles(emission=(0, 0, 0))
    assert len(dark) == 0 and (dark.slot == -1).all()
    tri = triangles()
    assert len(tri) == 1 and tri.slot.tolist() == [0]
    lo, hi = tri.boxes()[0]
    assert np.allclose(lo, CORNERS.min(axis=0)) and np.allclose(hi, CORNERS.max(axis=0))
    assert np.isclose(tri.area[0], 0.5 * np.linalg.norm(np.cross(CORNERS[1] - CORNERS[0], CORNERS[2] - CORNERS[0])))
