"""Sampling emissive triangles by solid angle (core/lights/spherical_triangle.py) and
its use by next-event estimation (core/lights/light_set.py): distribution, solid angles,
the rule that picks it, and the estimate it gives where area sampling is poor."""

import numpy as np
import pytest

from support.chi2 import ChiSquareTest, Domain
from restir_gi.core.lights import spherical_triangle as st
from restir_gi.core.lights.light_set import LightSet
from support.scenes import closed_box

N = 400_000

# (point, three corners): a large triangle near the point, an oblique one, and
# the wall beside a floor point 0.1 from their shared edge.
CASES = {
    "near": ((0.0, 0.0, 0.0), (0.3, -0.2, 0.1), (-0.1, 0.4, 0.15), (0.2, 0.3, 0.5)),
    "oblique": ((0.0, 0.0, 0.0), (1.0, -1.0, 0.2), (1.5, 1.0, 0.1), (1.2, 0.2, 1.4)),
    "beside_edge": ((0.9, 0.0, 1e-4), (1.0, -1.0, 0.0), (1.0, 1.0, 0.0), (1.0, 1.0, 2.0)),
}


def _rows(p, v0, v1, v2, n):
    return [np.tile(np.asarray(a, np.float64), (n, 1)) for a in (p, v0, v1, v2)]


def _triangle_domain(p, v0, v1, v2):
    """Directions from p through the triangle, as (x, y) in the unit square
    with barycentrics b1 = x (1 - y), b2 = x y: solid angle per dx dy is
    2 A x |cos| / r^2 at the point it reaches, smooth over the whole square
    (a domain of directions would cut the triangle's outline through bins)."""
    p, v0, v1, v2 = p[0], v0[0], v1[0], v2[0]
    e1, e2 = v1 - v0, v2 - v0
    cross = np.cross(e1, e2)
    area2 = np.linalg.norm(cross)
    normal = cross / area2

    def to_coords(w):
        h = np.cross(w, e2)
        det = h @ e1
        sv = p - v0
        b1 = (h @ sv) / det
        b2 = (w @ np.cross(sv, e1)) / det
        x = b1 + b2
        return x, np.where(x > 0, b2 / np.where(x > 0, x, 1.0), 0.0)

    def point(x, y):
        return v0 + (x * (1 - y))[:, None] * e1 + (x * y)[:, None] * e2

    def to_points(x, y):
        d = point(x, y) - p
        return d / np.linalg.norm(d, axis=1)[:, None]

    def jacobian(x, y):
        d = point(x, y) - p
        r2 = (d * d).sum(1)
        return area2 * x * np.abs(d @ normal) / np.sqrt(r2) / r2

    return Domain([[0.0, 1.0], [0.0, 1.0]], to_coords, to_points, jacobian, "triangle")


def test01_solid_angle_of_an_octant_and_of_nothing():
    """The triangle (x, y, z unit points) covers an eighth of the sphere from
    the origin; a point in a triangle's plane outside it sees none of it."""
    p, *v = _rows((0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), 1)
    assert st.solid_angle(p, *v)[0] == pytest.approx(np.pi / 2, rel=1e-12)
    p, *v = _rows((3, 0, 0), (1, 0, 0), (0, 1, 0), (0, 2, 0), 1)
    assert st.solid_angle(p, *v)[0] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("case", sorted(CASES))
def test02_directions_are_uniform_over_the_solid_angle(case, rng):
    p, v0, v1, v2 = _rows(*CASES[case], N)
    omega = st.solid_angle(p[:1], v0[:1], v1[:1], v2[:1])[0]
    w, b1, b2 = st.sample(p, v0, v1, v2, rng.random((N, 2)))
    # Where the barycentrics put the point is where the direction points.
    q = v0 + b1[:, None] * (v1 - v0) + b2[:, None] * (v2 - v0)
    d = (q - p) / np.linalg.norm(q - p, axis=1)[:, None]
    assert np.abs(d - w).max() < 1e-9
    assert (b1 >= 0).all() and (b2 >= 0).all() and (b1 + b2 <= 1 + 1e-12).all()

    def pdf(dirs):
        return np.full(len(dirs), 1.0 / omega)

    test = ChiSquareTest(lambda n: w, pdf, _triangle_domain(p, v0, v1, v2), res=(32, 32), sample_count=N,
                         test_count=len(CASES), sub=8)
    assert test.run(), test.messages


def test03_the_test_rejects_area_sampling_claimed_uniform(rng):
    """The chi-square above can fail: uniform points on the triangle do not
    give uniform directions from a point this close."""
    p, v0, v1, v2 = _rows(*CASES["near"], N)
    omega = st.solid_angle(p[:1], v0[:1], v1[:1], v2[:1])[0]
    u = rng.random((N, 2))
    su = np.sqrt(u[:, 0])
    q = v0 + (1 - su)[:, None] * (v1 - v0) + (u[:, 1] * su)[:, None] * (v2 - v0)
    w = (q - p) / np.linalg.norm(q - p, axis=1)[:, None]

    def pdf(dirs):
        return np.full(len(dirs), 1.0 / omega)

    assert not ChiSquareTest(lambda n: w, pdf, _triangle_domain(p, v0, v1, v2), res=(32, 32), sample_count=N,
                             sub=8).run()


def _wall_points(rng, n):
    """Points on the six inner walls of tests/support/scenes.py's closed box, and their normals."""
    lo, hi = np.array([-1, -1.5, -0.8]), np.array([1.2, 1, 1])
    face = rng.integers(0, 6, n)
    axis, side = face // 2, face % 2
    p = lo + rng.random((n, 3)) * (hi - lo)
    p[np.arange(n), axis] = np.where(side == 0, lo[axis], hi[axis])
    nrm = np.zeros((n, 3))
    nrm[np.arange(n), axis] = np.where(side == 0, 1.0, -1.0)
    return p.astype(np.float32), nrm.astype(np.float32)


def _irradiance_over_pi(lights, p, nrm, rng):
    s = lights.sample(p, rng.random(len(p)).astype(np.float32), rng.random((len(p), 2)).astype(np.float32), nrm)
    cos = np.maximum((s.wi * nrm).sum(1), 0.0)
    return np.where(s.pdf > 0, s.radiance[:, 0] * cos / np.where(s.pdf > 0, s.pdf, 1.0), 0.0) / np.pi, s


@pytest.mark.slow
def test04_next_event_estimation_in_an_emitting_box(rng, monkeypatch):
    """Every wall of a box emitting Le everywhere receives irradiance pi Le:
    NEE gives it at points on all six walls (the ceiling's points lie in the
    plane of its own triangles, which they must not sample by solid angle),
    with several times less variance than area sampling alone."""
    lights = LightSet(closed_box((0.5, 0.5, 0.5), (1.0, 1.0, 1.0)))
    p, nrm = _wall_points(rng, N)
    e, s = _irradiance_over_pi(lights, p, nrm, rng)
    assert e.mean() == pytest.approx(1.0, abs=4.5 * e.std() / np.sqrt(N))
    # The pdf NEE reports for its sample is what pdf_triangle gives the same
    # point found by a BSDF ray from the same point and normal (multiple
    # importance sampling needs both).
    ok = np.nonzero(s.pdf > 0)[0][:20000]
    slot = s.index[ok] - lights.n_analytic
    prim = lights.tri_index[slot]
    q = p[ok] + s.wi[ok] * s.dist[ok][:, None]
    again = lights.pdf_triangle(prim, p[ok], q, s.wi[ok], nrm[ok])
    assert np.allclose(again, s.pdf[ok], rtol=2e-3)
    monkeypatch.setattr(st, "MIN_SOLID_ANGLE", np.inf)
    area, _ = _irradiance_over_pi(lights, p, nrm, rng)
    assert area.mean() == pytest.approx(1.0, abs=4.5 * area.std() / np.sqrt(N))
    print(f"NEE in an emitting box: area sampling's variance {area.var() / e.var():.1f}x solid angle's")
    assert area.var() > 4 * e.var(), (area.var(), e.var())
