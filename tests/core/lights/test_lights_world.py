"""The world as one more light of core.lights.light_set.LightSet (core/lights/environment.py):
its share of the selection, its samples and their pdf, NEE with and without
MIS against escaping BSDF rays (the path tracer's combination) matching
quadrature, and a constant world that is no NEE light (as in Cycles)."""

import numpy as np
import pytest

from restir_gi.core import Lights, Materials, make_scene
from restir_gi.core.lights.environment import Environment
from restir_gi.core.integrators.path import escaped_radiance
from restir_gi.core.lights.light_set import INF_DIST, LightSet
from restir_gi.core.util.vectors import luminance
from restir_gi.core.sampling.warps import power_heuristic, square_to_cosine_hemisphere
from restir_gi.core.scene import LIGHT_POINT, LIGHT_SUN

COLOR = np.array([1.0, 0.5, 0.25])


def unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


TILTED = unit([0.4, -0.3, 1.0])


def assert_close(est, err, ref, rel=2e-4, max_rel_err=0.01):
    ref = np.asarray(ref, np.float64)
    assert (err <= max_rel_err * np.abs(ref).max() + 1e-12).all(), "too noisy to tell anything"
    assert (np.abs(est - ref) <= 4.5 * err + rel * np.abs(ref) + 1e-9).all(), (est, ref, err)


SUN_DIR = unit([0.3, -0.5, 0.8])


def sky_radiance(d):
    """A synthetic world: a gradient, bright overhead, and a bright smooth spot."""
    d = np.asarray(d, np.float64)
    base = np.array([0.3, 0.5, 1.0]) * (0.2 + 0.4 * (1.0 + d[:, 2]))[:, None]
    return (base + 60.0 * np.exp((d @ SUN_DIR - 1.0) / 0.1 ** 2)[:, None]).astype(np.float32)


def world_irradiance(fn, n, k=1200):
    """Irradiance at normal n from radiance_fn, by midpoint quadrature over (cos theta, phi) about n."""
    t = unit(np.cross(n, [1, 0, 0]))
    b = np.cross(n, t)
    c = (np.arange(k) + 0.5) / k
    phi = (np.arange(2 * k) + 0.5) / (2 * k) * 2 * np.pi
    C, F = np.meshgrid(c, phi, indexing="ij")
    s = np.sqrt(1 - C * C).ravel()
    w = (s * np.cos(F.ravel()))[:, None] * t + (s * np.sin(F.ravel()))[:, None] * b + C.ravel()[:, None] * n
    return (fn(w).astype(np.float64) * C.ravel()[:, None]).sum(axis=0) * (1.0 / k) * (np.pi / k)


def with_world(rows, environment=None, world_color=(0, 0, 0), tri=None):
    lights = Lights.from_list(rows)
    v = np.zeros((0, 3)) if tri is None else np.asarray(tri, np.float32)
    t = np.arange(len(v), dtype=np.int32).reshape(-1, 3)
    scene = make_scene(v, t, materials=Materials.from_list([{}]), lights=lights, world_color=world_color)
    scene.environment = environment
    return scene, LightSet(scene)


def test01_world_is_one_more_light(rng):
    """The world's selection weight is its mean radiance x pi (Cycles' background
    energy) x pi R^2 (as a sun's irradiance); its samples are at INF_DIST, not
    delta, with pdf = pmf x the environment's pdf, which pdf_world recomputes."""
    env = Environment(sky_radiance, resolution=64)
    rows = [{"kind": LIGHT_POINT, "position": (0, 0, 2), "power": (100, 100, 100)},
            {"kind": LIGHT_SUN, "direction": (0, 0, -1), "power": (2, 2, 2)}]
    tri = np.array([[-5, -5, 0], [5, -5, 0], [5, 5, 0]], float)
    scene, ls = with_world(rows, env, tri=tri)
    radius = 0.5 * np.linalg.norm(tri.max(axis=0) - tri.min(axis=0))
    w = np.array([luminance(np.float32([100] * 3)), luminance(np.float32([2] * 3)) * np.pi * radius ** 2,
                  float(luminance(env.mean_radiance)) * np.pi * np.pi * radius ** 2])
    assert ls.world_index == 2 and ls.world_pmf == pytest.approx(w[2] / w.sum(), rel=1e-6)
    np.testing.assert_allclose(ls.distribution.pmf, w / w.sum(), rtol=1e-5)
    count = 100_000
    P = np.zeros((count, 3), np.float32)
    n = np.ascontiguousarray(np.broadcast_to(np.float32(TILTED), (count, 3)))
    s = ls.sample(P, rng.random(count, dtype=np.float32), rng.random((count, 2), dtype=np.float32), n)
    world = s.world
    p = ls.world_pmf
    assert abs(world.sum() - count * p) < 4.5 * np.sqrt(count * p * (1 - p))
    assert (s.dist[world] == INF_DIST).all() and not s.delta[world].any() and s.delta[~world].all()
    np.testing.assert_allclose(s.pdf[world], p * env.pdf(s.wi[world]), rtol=1e-5)
    np.testing.assert_array_equal(s.radiance[world], env.radiance(s.wi[world]))
    same = np.isclose(ls.pdf_world(s.wi[world]), s.pdf[world], rtol=1e-4)
    assert same.mean() > 0.999


@pytest.mark.slow
@pytest.mark.parametrize("world", ["map", "constant"])
def test02_world_nee_and_mis_match_quadrature(world, rng):
    """NEE alone, and NEE plus escaping BSDF rays both weighted by MIS (the
    path tracer's combination), give the irradiance of a point light plus the
    world's quadrature irradiance."""
    env = Environment(sky_radiance, resolution=128) if world == "map" else \
        Environment.constant_color((0.4, 0.7, 1.0))
    c = np.array([0.5, 0.2, 2.0])
    tri = np.array([[-3, -3, -1], [3, -3, -1], [3, 3, -1]], float)     # the scene's size only
    _, ls = with_world([{"kind": LIGHT_POINT, "position": c, "power": 50 * COLOR}], env, tri=tri)
    assert (0.1 < ls.world_pmf < 0.9) if world == "map" else ls.world_pmf == 0
    n = TILTED
    ref = world_irradiance(env.radiance, n) + 50 * COLOR / (4 * np.pi) * (unit(c) @ n) / (c @ c)
    count = 400_000
    P = np.zeros((count, 3), np.float32)
    N_ = np.ascontiguousarray(np.broadcast_to(np.float32(n), (count, 3)))
    s = ls.sample(P, rng.random(count, dtype=np.float32), rng.random((count, 2), dtype=np.float32), N_)
    cos = np.maximum(s.wi.astype(np.float64) @ n, 0.0)
    inv = np.where(s.pdf > 0, 1.0 / np.where(s.pdf > 0, s.pdf, 1), 0.0)
    if world == "map":      # a constant world is found by BSDF rays only
        alone = s.radiance * (cos * inv)[:, None]
        assert_close(alone.mean(axis=0), alone.std(axis=0) / np.sqrt(count), ref, rel=1e-3)
    w = np.where(s.delta, 1.0, power_heuristic(s.pdf, (cos / np.pi).astype(np.float32)))
    nee_part = s.radiance * (cos * w * inv)[:, None]
    t = unit(np.cross(n, [1, 0, 0]))
    local = square_to_cosine_hemisphere(rng.random((count, 2), dtype=np.float32)).astype(np.float64)
    wi = (local[:, 0:1] * t + local[:, 1:2] * np.cross(n, t) + local[:, 2:3] * n).astype(np.float32)
    pdf_b = (local[:, 2] / np.pi).astype(np.float32)
    bsdf_part = np.pi * escaped_radiance(ls, wi, pdf_b, N_, np.ones((count, 3), np.float32))
    total = nee_part + bsdf_part
    assert_close(total.mean(axis=0), total.std(axis=0) / np.sqrt(count), ref, rel=1e-3)


def test03_constant_world_is_no_nee_light(rng):
    """A constant world (a Background colour, the world_color) is left out of
    the selection, as Cycles disables a background light that does not vary
    with direction: the other emitters share it, no sample is the world's,
    and escaping rays read its radiance with MIS weight one."""
    rows = [{"kind": LIGHT_POINT, "position": (0, 0, 2), "power": (100, 100, 100)},
            {"kind": LIGHT_POINT, "position": (1, 0, 2), "power": (300, 300, 300)}]
    d = np.float32([[0, 0, 1], [1, 0, 0]])
    for scene_world in ({"environment": Environment.constant_color((1.0, 1.0, 1.0))},
                        {"world_color": (1.0, 1.0, 1.0)}):
        _, ls = with_world(rows, **scene_world)
        assert ls.environment is not None and ls.world_pmf == 0 and ls.world_index == -1
        np.testing.assert_allclose(ls.distribution.pmf, [0.25, 0.75], rtol=1e-6)
        s = ls.sample(np.zeros((1000, 3), np.float32), rng.random(1000, dtype=np.float32),
                      rng.random((1000, 2), dtype=np.float32), np.float32([[0, 0, 1]] * 1000))
        assert s.delta.all() and s.world is None
        assert (ls.pdf_world(d) == 0).all()
        np.testing.assert_array_equal(ls.world_radiance(d), 1.0)
        np.testing.assert_allclose(escaped_radiance(ls, d, np.float32([0.3, 0.1]), d, np.ones((2, 3), np.float32)),
                                   1.0)
    # A world that varies with direction stays a light.
    _, ls = with_world(rows, Environment(sky_radiance, resolution=64))
    assert ls.world_pmf > 0 and ls.world_index == 2 and ls.pdf_world(d)[1] > 0
    # Without any world there is nothing to sample or to see.
    _, none = with_world(rows)
    assert none.environment is None and none.world_pmf == 0
    assert (none.world_radiance(d) == 0).all() and (none.pdf_world(d) == 0).all()
