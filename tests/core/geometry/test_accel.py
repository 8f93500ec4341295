"""Embree queries of core.geometry.accel against a brute-force Moller-Trumbore in numpy,
occlusion against closest hits, threaded against single-threaded batches, and
robustness to degenerate input."""

import numpy as np
import pytest

from restir_gi.core.geometry import accel as A
from restir_gi.core.geometry.accel import Accel


def random_triangles(rng, count=150):
    centres = rng.uniform(-1, 1, (count, 1, 3))
    v = (centres + rng.normal(scale=0.25, size=(count, 3, 3))).reshape(-1, 3).astype(np.float32)
    return v, np.arange(len(v), dtype=np.int32).reshape(-1, 3)


def random_rays(rng, vertices, count):
    o = rng.uniform(-2, 2, (count, 3))
    # Half aimed at triangle centroids (hits), half anywhere (mostly misses).
    tri = vertices.reshape(-1, 3, 3).astype(np.float64)
    target = tri[rng.integers(0, len(tri), count)].mean(axis=1)
    d = np.where((np.arange(count) % 2 == 0)[:, None], target - o, rng.normal(size=(count, 3)))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return o.astype(np.float32), d.astype(np.float32)


def brute_force(vertices, triangles, o, d, margin=1e-4):
    """Closest hit per ray in float64 and a mask of rays too close to call
    (near an edge, two hits at nearly the same distance, or tmax ties)."""
    p = vertices[triangles].astype(np.float64)
    p0, e1, e2 = p[:, 0], p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    o, d = o.astype(np.float64), d.astype(np.float64)
    pv = np.cross(d[:, None, :], e2[None])                      # (R, T, 3)
    det = np.einsum("tk,rtk->rt", e1, pv)
    inv = 1.0 / np.where(np.abs(det) > 1e-14, det, np.nan)
    s = o[:, None, :] - p0[None]
    u = np.einsum("rtk,rtk->rt", s, pv) * inv
    q = np.cross(s, e1[None])
    v = np.einsum("rk,rtk->rt", d, q) * inv
    t = np.einsum("tk,rtk->rt", e2, q) * inv
    edge = np.minimum(np.minimum(u, v), 1 - u - v)
    front = t > 1e-6
    valid = front & (edge >= 0)
    t_hit = np.where(valid, t, np.inf)
    prim = np.argmin(t_hit, axis=1)
    rows = np.arange(len(o))
    best = t_hit[rows, prim]
    hit = np.isfinite(best)
    second = np.sort(t_hit, axis=1)[:, 1] if t_hit.shape[1] > 1 else np.full(len(o), np.inf)
    near_edge = (front & (np.abs(edge) < margin) & (t <= np.where(hit, best, np.inf)[:, None] + margin)).any(axis=1)
    with np.errstate(invalid="ignore"):
        ambiguous = near_edge | (np.abs(second - best) < margin)
    return hit, np.where(hit, prim, -1), best, u[rows, prim], v[rows, prim], ambiguous


@pytest.fixture
def scene(rng):
    v, t = random_triangles(rng)
    acc = Accel(v, t, threads=1)
    yield v, t, acc
    acc.close()


def test01_closest_hit_matches_brute_force(scene, rng):
    v, t, acc = scene
    o, d = random_rays(rng, v, 3000)
    hit, prim, t_ref, u_ref, v_ref, amb = brute_force(v, t, o, d)
    assert amb.mean() < 0.05 and hit.mean() > 0.3
    res = acc.intersect_closest(o, d)
    ok = ~amb
    assert np.array_equal(res.hit[ok], hit[ok])
    assert np.array_equal(res.prim[ok], prim[ok])
    h = ok & hit
    assert np.allclose(res.t[h], t_ref[h], rtol=1e-4, atol=1e-5)
    assert np.allclose(res.u[h], u_ref[h], atol=1e-4) and np.allclose(res.v[h], v_ref[h], atol=1e-4)
    assert (res.t[~res.hit] == np.inf).all()
    assert res.t.dtype == np.float32 and res.prim.dtype == np.int32


def test02_tmax_limits_hits_and_occlusion_agrees(scene, rng):
    v, t, acc = scene
    o, d = random_rays(rng, v, 3000)
    hit, prim, t_ref, _, _, amb = brute_force(v, t, o, d)
    tmax = rng.uniform(0.1, 4.0, len(o)).astype(np.float32)
    ok = ~amb & ~(np.abs(t_ref - tmax) < 1e-4)
    expect = hit & (t_ref < tmax)
    res = acc.intersect_closest(o, d, tmax)
    assert np.array_equal(res.hit[ok], expect[ok])
    occ = acc.occluded(o, d, tmax)
    assert occ.dtype == bool
    assert np.array_equal(occ[ok], expect[ok])
    # Occlusion agrees with the closest-hit query on every ray, ambiguous or not.
    assert np.array_equal(occ, res.hit)
    # A scalar tmax broadcasts.
    assert np.array_equal(acc.occluded(o, d, 2.0)[ok], (hit & (t_ref < 2.0))[ok])


@pytest.mark.parametrize("threads", [2, 3])
def test03_threaded_batches_equal_single_threaded(threads, rng):
    v, t = random_triangles(rng, 300)
    single = Accel(v, t, threads=1)
    multi = Accel(v, t, threads=threads)
    assert multi._pool is not None
    n = 2 * A._SPLIT_MIN + 1237           # above the split threshold, not a multiple of the thread count
    o, d = random_rays(rng, v, n)
    tmax = rng.uniform(0.5, 5.0, n).astype(np.float32)
    a, b = single.intersect_closest(o, d), multi.intersect_closest(o, d)
    for field in ("t", "prim", "u", "v"):
        assert np.array_equal(getattr(a, field), getattr(b, field))
    assert np.array_equal(single.occluded(o, d, tmax), multi.occluded(o, d, tmax))
    assert a.hit.sum() > n // 4
    single.close()
    multi.close()


def test04_bad_rays_miss_without_crashing(scene):
    v, t, acc = scene
    c = v.reshape(-1, 3, 3)[0].mean(axis=0)                    # a triangle's centroid
    o = np.float32([c + [0, 0, 3], [np.nan, 0, 0], c + [0, 0, 3], c + [0, 0, 3], c + [0, 0, 3],
                    [np.inf, 0, 0], c + [0, 0, 3]])
    towards = (c - o[0]) / np.linalg.norm(c - o[0])
    d = np.float32([towards, towards, [np.nan, 0, 1], towards, towards, towards, towards])
    tmax = np.float32([np.inf, 10, 10, 0.0, -1.0, 10, np.nan])
    res = acc.intersect_closest(o, d, tmax)
    assert res.hit[0]                                           # unbounded ray still hits
    assert not res.hit[1:].any()
    assert (res.t[1:] == np.inf).all()
    occ = acc.occluded(o, d, tmax)
    assert occ[0] and not occ[1:].any()
    # The good ray gives the same answer alone as beside the bad ones.
    alone = acc.intersect_closest(o[:1], d[:1], tmax[:1])
    assert alone.prim[0] == res.prim[0] and alone.t[0] == res.t[0]


def test05_bad_rays_miss_geometry_through_the_world_origin():
    # A floor through (0, 0, 0), as in most scenes: whatever stands in for a bad
    # ray inside the query must not report it.
    floor = Accel(np.float32([[-1, -1, 0], [1, -1, 0], [0, 1, 0]]), np.int32([[0, 1, 2]]), threads=1)
    o = np.float32([[np.nan, 0, 1], [0, 0, 1], [0, 0, 1], [0, 0, 1]])
    d = np.float32([[0, 0, -1], [np.inf, 0, -1], [0, 0, -1], [0, 0, -1]])
    tmax = np.float32([5, 5, np.nan, -2])
    assert not floor.intersect_closest(o, d, tmax).hit.any()
    assert not floor.occluded(o, d, tmax).any()
    floor.close()


def test06_empty_inputs():
    empty = Accel(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32))
    o = np.zeros((4, 3), np.float32)
    d = np.float32([[0, 0, 1]] * 4)
    res = empty.intersect_closest(o, d)
    assert not res.hit.any() and (res.t == np.inf).all() and len(res.prim) == 4
    assert not empty.occluded(o, d, 10.0).any()
    empty.close()
    v, t = random_triangles(np.random.default_rng(0), 5)
    acc = Accel(v, t, threads=2)
    res = acc.intersect_closest(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32))
    assert len(res.t) == 0 and len(acc.occluded(np.zeros((0, 3)), np.zeros((0, 3)), 1.0)) == 0
    acc.close()


def test07_mismatched_lengths_raise(scene):
    _, _, acc = scene
    o = np.zeros((5, 3), np.float32)
    d = np.float32([[0, 0, 1]] * 4)
    with pytest.raises(ValueError):
        acc.intersect_closest(o, d)
    with pytest.raises(ValueError):
        acc.occluded(o, d, 1.0)
    with pytest.raises(ValueError):
        acc.intersect_closest(o[:4], d, np.ones(3, np.float32))
    with pytest.raises(ValueError):
        acc.occluded(o[:4], d, np.ones(5, np.float32))


def test08_offset_origins_leave_the_surface(scene, rng):
    """A ray leaving a hit point, moved off the surface by offset_origins, does
    not find the surface it starts on."""
    v, t, acc = scene
    o, d = random_rays(rng, v, 4000)
    res = acc.intersect_closest(o, d)
    h = res.hit
    tri = v[t[res.prim[h]]].astype(np.float64)
    p = (1 - res.u[h] - res.v[h])[:, None] * tri[:, 0] + res.u[h][:, None] * tri[:, 1] + res.v[h][:, None] * tri[:, 2]
    ng = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    ng /= np.linalg.norm(ng, axis=1, keepdims=True)
    new_d = rng.normal(size=(h.sum(), 3))
    new_d /= np.linalg.norm(new_d, axis=1, keepdims=True)
    o2 = A.offset_origins(p.astype(np.float32), ng.astype(np.float32), new_d.astype(np.float32), 1e-4)
    again = acc.intersect_closest(o2, new_d.astype(np.float32))
    assert (again.prim != res.prim[h]).all()
