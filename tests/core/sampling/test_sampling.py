"""Warps of core.sampling.warps against their densities (Mitsuba's test_warp style):
each density integrates to one, each sampler matches its density by a
chi-square test, batch results equal one-at-a-time results, and the MIS and
frame helpers keep their algebraic properties."""

import numpy as np
import pytest

from support.chi2 import (ChiSquareTest, box_domain, chi2_sf, disk_domain, integrate, pooled_chi2,
                  spherical_domain, triangle_domain)
from restir_gi.core.sampling import warps as S
from restir_gi.core.util import vectors as V

N = 400_000


def _u(rng, n=N):
    return rng.random((n, 2), dtype=np.float32)


# --- the chi-square helper itself ------------------------------------------------------

def test01_chi2_sf_matches_tables():
    # Critical values from standard chi-square tables.
    for stat, dof, p in ((3.841459, 1, 0.05), (6.634897, 1, 0.01), (18.307038, 10, 0.05),
                         (124.342113, 100, 0.05), (0.584375, 3, 0.9)):
        assert chi2_sf(stat, dof) == pytest.approx(p, rel=1e-5)
    assert chi2_sf(0.0, 4) == 1.0
    assert chi2_sf(1e4, 10) < 1e-300 or chi2_sf(1e4, 10) == 0.0


def test02_chi2_rejects_a_wrong_density(rng):
    # Uniform hemisphere samples against the cosine density must be rejected,
    # and so must a density that is right except for a 5 % tilt in phi.
    dom = spherical_domain()
    test = ChiSquareTest(lambda n: S.square_to_uniform_hemisphere(_u(rng, n)),
                         lambda w: S.cosine_hemisphere_pdf(w[:, 2]), dom, sample_count=100_000)
    assert not test.run()
    tilted = ChiSquareTest(lambda n: S.square_to_cosine_hemisphere(_u(rng, n)),
                           lambda w: S.cosine_hemisphere_pdf(w[:, 2]) * (1 + 0.05 * np.sign(w[:, 1])),
                           dom, sample_count=400_000)
    assert not tilted.run()


def test03_pooled_chi2_flags_samples_outside_the_support():
    p, *_ = pooled_chi2([10, 0, 3], [13, 0, 0])
    assert p == 0.0
    p, stat, dof, _ = pooled_chi2([100, 100], [100, 100])
    assert p == 1.0 and stat == 0.0 and dof == 1


# --- directions ----------------------------------------------------------------------------

DIRECTION_WARPS = {
    "cosine_hemisphere": (S.square_to_cosine_hemisphere, lambda w: S.cosine_hemisphere_pdf(w[:, 2])),
    "uniform_hemisphere": (S.square_to_uniform_hemisphere, lambda w: S.uniform_hemisphere_pdf(w[:, 2])),
    "uniform_sphere": (S.square_to_uniform_sphere, lambda w: S.uniform_sphere_pdf(len(w))),
}
for _cm in (0.5, 0.95, -0.3):
    DIRECTION_WARPS[f"uniform_cone_{_cm}"] = (
        lambda u, c=_cm: S.square_to_uniform_cone(u, np.float32(c)),
        lambda w, c=_cm: np.where(w[:, 2] >= c, S.uniform_cone_pdf(np.float32(c)), 0.0))


@pytest.mark.parametrize("name", sorted(DIRECTION_WARPS))
def test04_direction_pdf_integrates_to_one(name):
    _, pdf = DIRECTION_WARPS[name]
    # 40 cos bins: the cone edges 0.5, 0.95, -0.3 and the horizon fall on bin edges.
    assert integrate(pdf, spherical_domain(), res=(40, 16)) == pytest.approx(1.0, abs=2e-4)


@pytest.mark.parametrize("name", sorted(DIRECTION_WARPS))
def test05_direction_chi2(name, rng):
    warp, pdf = DIRECTION_WARPS[name]
    samples = warp(_u(rng))
    assert samples.dtype == np.float32
    assert np.allclose(np.linalg.norm(samples, axis=1), 1.0, atol=1e-5)
    test = ChiSquareTest(lambda n: samples, pdf, spherical_domain(), res=(40, 24), sample_count=N,
                         test_count=len(DIRECTION_WARPS))
    assert test.run()


def test06_cone_accepts_per_sample_angles(rng):
    u = _u(rng, 1000)
    cos_max = rng.uniform(-1, 1, 1000).astype(np.float32)
    w = S.square_to_uniform_cone(u, cos_max)
    assert (w[:, 2] >= cos_max - 1e-6).all()
    single = np.concatenate([S.square_to_uniform_cone(u[i:i + 1], cos_max[i]) for i in range(len(u))])
    assert np.allclose(w, single, atol=1e-7)
    assert np.allclose(S.uniform_cone_pdf(cos_max), 1 / (2 * np.pi * (1 - cos_max.astype(np.float64))),
                       rtol=1e-5)


# --- points --------------------------------------------------------------------------------

def test07_concentric_disk(rng):
    pdf = lambda p: np.where(p[:, 0] ** 2 + p[:, 1] ** 2 <= 1, 1 / np.pi, 0.0)  # noqa: E731
    assert integrate(pdf, disk_domain()) == pytest.approx(1.0, abs=1e-6)
    pts = S.square_to_concentric_disk(_u(rng))
    assert (np.einsum("ij,ij->i", pts, pts) <= 1 + 1e-6).all()
    assert ChiSquareTest(lambda n: pts, pdf, disk_domain(), res=(24, 32), sample_count=N).run()
    # Also in Cartesian bins, where the map's square-to-wedge seams run diagonally.
    assert ChiSquareTest(lambda n: pts, pdf, box_domain([[-1, 1], [-1, 1]]), res=(20, 20),
                         sample_count=N).run()


def test08_concentric_disk_centre_and_corners():
    u = np.float32([[0.5, 0.5], [0, 0], [1, 1], [0, 1], [1, 0], [0.5, 1], [1, 0.5]])
    p = S.square_to_concentric_disk(u)
    assert np.isfinite(p).all()
    assert np.allclose(p[0], 0)
    assert np.allclose(np.linalg.norm(p[1:], axis=1), 1, atol=1e-6)


def test09_uniform_triangle(rng):
    b0, b1 = S.square_to_uniform_triangle(_u(rng))
    pts = np.stack([b0, b1], axis=1)
    assert (b0 >= 0).all() and (b1 >= 0).all() and (b0 + b1 <= 1 + 1e-6).all()
    pdf = lambda b: np.where((b[:, 0] >= 0) & (b[:, 1] >= 0) & (b.sum(axis=1) <= 1), 2.0, 0.0)  # noqa: E731
    assert integrate(pdf, triangle_domain()) == pytest.approx(1.0, abs=1e-6)
    assert ChiSquareTest(lambda n: pts, pdf, triangle_domain(), res=(24, 24), sample_count=N).run()
    # In (b0, b1) bins too: the third barycentric must not be favoured either.
    assert ChiSquareTest(lambda n: pts, pdf, box_domain([[0, 1], [0, 1]]), res=(16, 16),
                         sample_count=N).run()


# --- tabulated distributions -----------------------------------------------------------------

def test10_distribution_discrete(rng):
    w = np.array([0.0, 3.0, 1.0, 0.5, 0.0, 7.0, np.nan, -2.0, 0.25])
    dist = S.Distribution1D(w)
    clean = np.where(np.isfinite(w) & (w > 0), w, 0.0)
    assert np.allclose(dist.pmf, clean / clean.sum())
    assert dist.pmf.sum() == pytest.approx(1.0, abs=1e-6)
    u = rng.random(N, dtype=np.float32)
    idx, remapped = dist.sample_discrete(u)
    assert (clean[idx] > 0).all()                          # never a zero-weight item
    counts = np.bincount(idx, minlength=len(w))
    p, *_ = pooled_chi2(counts, dist.pmf.astype(np.float64) * N)
    assert p > 0.01
    # The remapped numbers are fresh uniforms in [0, 1) within every item.
    assert (remapped >= 0).all() and (remapped < 1).all()
    for i in (1, 5):
        h = np.histogram(remapped[idx == i], bins=20, range=(0, 1))[0]
        p, *_ = pooled_chi2(h, np.full(20, h.sum() / 20))
        assert p > 0.001


def test11_distribution_all_zero_is_uniform():
    dist = S.Distribution1D([0.0, 0.0, 0.0, 0.0])
    assert np.allclose(dist.pmf, 0.25)
    idx, _ = dist.sample_discrete(np.float32([0.0, 0.3, 0.6, 0.99999994]))
    assert list(idx) == [0, 1, 2, 3]


def test12_distribution_continuous(rng):
    w = rng.random(13) * np.array([1, 0, 1, 1, 5, 1, 0, 0, 1, 2, 1, 1, 3])
    dist = S.Distribution1D(w)
    pdf = lambda p: dist.pmf[np.clip((p[:, 0] * dist.count).astype(int), 0, dist.count - 1)] * dist.count  # noqa: E731
    dom = box_domain([[0, 1], [0, 1]])
    # 52 bins: four per piece, so every bin lies inside one piece.
    assert integrate(pdf, dom, res=(52, 1)) == pytest.approx(1.0, abs=1e-6)
    x, density = dist.sample_continuous(rng.random(N, dtype=np.float32))
    assert (x >= 0).all() and (x < 1).all()
    assert np.allclose(density, pdf(x[:, None]), rtol=1e-6)
    pts = np.stack([x, np.full(N, 0.5)], axis=1)
    assert ChiSquareTest(lambda n: pts, pdf, dom, res=(52, 1), sample_count=N).run()



@pytest.mark.parametrize("weights", [
    "filter", [1.0], [0.0, 0.0, 1.0, 0.0], "steep", "many"])
def test12b_guided_search_equals_binary_search(weights, rng):
    """Distribution1D.locate (a table of cells) gives np.searchsorted's index for
    every u in [0, 1), at the cdf's own values and around them too, and falls
    back to it for anything else (NaN, 1, negative)."""
    from restir_gi.core.camera.projection import PixelFilter
    if weights == "filter":
        dist = PixelFilter(1.5).dist        # tails of bins far narrower than a guide cell
    elif weights == "steep":
        dist = S.Distribution1D(np.exp(-np.arange(300) / 8.0))
    elif weights == "many":
        dist = S.Distribution1D(rng.random(100_000) ** 4)
    else:
        dist = S.Distribution1D(weights)
    at = dist.cdf[:-1].astype(np.float32)
    u = np.concatenate([rng.random(200_000, dtype=np.float32), at, np.nextafter(at, np.float32(0)),
                        np.nextafter(at, np.float32(1)), np.float32([0.0, 0.99999994])])
    u = u[(u >= 0) & (u < 1)]
    expected = np.searchsorted(dist.cdf, u, side="right")
    assert np.array_equal(dist.locate(u), expected)
    odd = np.float32([np.nan, 1.0, -0.5, 0.25])
    assert np.array_equal(dist.locate(odd), np.searchsorted(dist.cdf, odd, side="right"))

# --- MIS and frames ---------------------------------------------------------------------------

def test13_power_heuristic(rng):
    a = rng.uniform(1e-3, 10, 1000)
    b = rng.uniform(1e-3, 10, 1000)
    w = S.power_heuristic(a, b)
    assert np.allclose(w + S.power_heuristic(b, a), 1.0, atol=1e-6)
    assert np.allclose(w, a * a / (a * a + b * b), rtol=1e-5)
    assert (S.power_heuristic(np.zeros(3), [0.0, 1.0, np.inf]) == 0).all()    # no pdf, no weight
    assert (S.power_heuristic([1.0, 5.0, 1e30], [0.0, 0.0, 0.0]) == 1).all()  # the other never samples it
    assert S.power_heuristic([np.inf], [1.0])[0] == 1                          # delta against finite
    assert S.power_heuristic([1.0], [np.inf])[0] == 0
    assert (S.power_heuristic([np.nan, 1.0, np.inf], [1.0, np.nan, np.inf]) == 0).all()
    big = S.power_heuristic([1e30, 3e38], [1e30, 3e38])      # no overflow to NaN
    assert np.allclose(big, 0.5)
    assert S.power_heuristic(np.float32([2.0]), np.float32([1.0])).dtype == np.float32


def _unit(v):
    return (v / np.linalg.norm(v, axis=1, keepdims=True)).astype(np.float32)


def test14_orthonormal_basis(rng):
    n = _unit(rng.normal(size=(20000, 3)))
    near_minus_z = _unit(np.stack([rng.normal(scale=s, size=200) for s in (1e-4, 1e-4)]
                                  + [-np.ones(200)], axis=1))
    special = np.float32([[0, 0, -1], [0, 0, 1], [1, 0, 0], [0, 1, 0], [-0.0, 0.0, -1],
                          [1e-7, 0, -1], [0, -1e-7, -1], [-1, 0, 0]])
    n = np.concatenate([n, near_minus_z, _unit(special)])
    t, b = V.orthonormal_basis(n)
    assert t.dtype == np.float32 and b.dtype == np.float32
    assert np.isfinite(t).all() and np.isfinite(b).all()
    for u, v in ((t, n), (b, n), (t, b)):
        assert np.abs(np.einsum("ij,ij->i", u, v)).max() < 1e-5
    for u in (t, b):
        assert np.abs(np.linalg.norm(u, axis=1) - 1).max() < 1e-5
    assert np.abs(np.cross(t, b) - n).max() < 1e-5        # right-handed
    # to_local and to_world are inverse.
    w = _unit(rng.normal(size=(len(n), 3)))
    local = V.to_local(w, t, b, n)
    assert np.abs(V.to_world(local, t, b, n) - w).max() < 1e-5
    assert np.abs(local[:, 2] - np.einsum("ij,ij->i", w, n)).max() < 1e-6


def test15_area_to_solid_angle():
    pdf = S.area_to_solid_angle(np.float32([2.0, 2.0, 1.0]), np.float32([4.0, 4.0, 1.0]),
                                np.float32([0.5, -0.5, 0.0]))
    assert np.allclose(pdf, [16.0, 16.0, 0.0])              # grazing: zero, not inf


def test16_normalize_keeps_zero_vectors():
    v = V.normalize(np.float32([[3, 4, 0], [0, 0, 0]]))
    assert np.allclose(v, [[0.6, 0.8, 0], [0, 0, 0]])


# --- vectorised against scalar ---------------------------------------------------------------

@pytest.mark.parametrize("warp", [S.square_to_concentric_disk, S.square_to_cosine_hemisphere,
                                  S.square_to_uniform_hemisphere, S.square_to_uniform_sphere,
                                  lambda u: np.stack(S.square_to_uniform_triangle(u), axis=1)])
def test17_vectorised_equals_scalar(warp, rng):
    u = _u(rng, 64)
    batch = warp(u)
    single = np.concatenate([warp(u[i:i + 1]) for i in range(len(u))])
    assert np.array_equal(batch, single)
