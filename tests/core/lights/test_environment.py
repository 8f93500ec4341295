"""The world as a light (core.lights.environment): Cycles' equirectangular mapping and
importance map, the sampler against its density (chi-square), the density's
normalisation, and the world in the path tracer: a closed form under a
constant world, quadrature under a map, and the variance NEE + MIS saves on a
small bright sun against BSDF sampling alone."""

import time

import numpy as np
import pytest

from support.chi2 import ChiSquareTest, Domain, integrate, spherical_domain
from restir_gi.core import Camera, Materials, make_scene
from restir_gi.core.lights.environment import Environment, direction_to_uv, uv_to_direction
from restir_gi.core.integrators.path import escaped_radiance
from restir_gi.core.lights.light_set import INF_DIST, LightSet
from restir_gi.core.sampling.warps import power_heuristic, square_to_cosine_hemisphere
from support.scenes import Builder, look_at, path_samples, quad

N = 400_000
UP = np.array([0.0, 0.0, 1.0])


def unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


SPOT = unit([0.3, -0.5, 0.8])


def sky(peak=40.0, width=0.12, spot=SPOT):
    """radiance_fn of a synthetic world: a blue gradient (bright overhead, dim
    below) plus a smooth bright spot of angular width ``width`` about ``spot``."""
    tint = np.array([1.0, 0.85, 0.6])

    def fn(d):
        d = np.asarray(d, np.float64)
        base = np.array([0.3, 0.5, 1.0]) * (0.2 + 0.8 * (0.5 + 0.5 * d[:, 2]))[:, None]
        bump = peak * np.exp((d @ spot - 1.0) / width ** 2)
        return (base + bump[:, None] * tint).astype(np.float32)

    return fn


def uniforms(rng, n=N):
    return rng.random((n, 2), dtype=np.float32)


# --- the mapping -----------------------------------------------------------------------

def test01_cycles_equirectangular_mapping():
    """u = (atan2(y, x) - pi) / (-2 pi), v = (acos z - pi) / (-pi): known directions
    and the round trip."""
    d = np.float32([[1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1], [-1, 0, 1e-30]])
    u, v, sin_t = direction_to_uv(d)
    np.testing.assert_allclose(u[:5], [0.5, 0.25, 0.75, 0.5, 0.5], atol=1e-12)
    np.testing.assert_allclose(v, [0.5, 0.5, 0.5, 1.0, 0.0, 0.5], atol=1e-12)
    assert u[5] in (0.0, 1.0)           # -X is the seam
    np.testing.assert_allclose(sin_t, [1, 1, 1, 0, 0, 1], atol=1e-12)
    rng = np.random.default_rng(3)
    w = rng.normal(size=(10_000, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    back = uv_to_direction(*direction_to_uv(w)[:2])
    assert np.abs(back - w).max() < 1e-6
    # Near the poles theta keeps its precision (atan2, not acos of a float32 z).
    tiny = np.float32([[1e-4, 0, 1]])
    assert direction_to_uv(tiny)[1][0] == pytest.approx(1 - 1e-4 / np.pi, rel=1e-9)


def test02_equirect_image_lookup():
    """Bilinear lookup as Cycles' Linear interpolation; row 0 is the bottom
    (Blender's Image.pixels), so +Z reads the top row; texel centres read
    their own pixel."""
    h, w = 4, 8
    img = np.arange(h * w * 3, dtype=np.float32).reshape(h, w, 3)
    img[h - 1] = (7.0, 8.0, 9.0)                    # a constant top row
    env = Environment.from_equirect(img, strength=2.0)
    rad = env.radiance(np.float32([[1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]]))
    np.testing.assert_allclose(rad[0], 2 * img[1:3, 3:5].mean(axis=(0, 1)), rtol=1e-6)    # u = .5, v = .5
    np.testing.assert_allclose(rad[1], 2 * img[1:3, 1:3].mean(axis=(0, 1)), rtol=1e-6)    # u = .25
    np.testing.assert_allclose(rad[2], 2 * img[1:3, 5:7].mean(axis=(0, 1)), rtol=1e-6)    # u = .75
    np.testing.assert_allclose(rad[3], (14.0, 16.0, 18.0), rtol=1e-6)
    # Texel centres, and the map built from them.
    rows, cols = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    centres = uv_to_direction((cols.ravel() + 0.5) / w, (rows.ravel() + 0.5) / h)
    np.testing.assert_allclose(env.radiance(centres), 2 * img.reshape(-1, 3), rtol=1e-5, atol=1e-5)
    # A rotation about +Z turns the world: +Y now shows what +X showed.
    turned = Environment.from_equirect(img, rotation=-np.pi / 2)
    np.testing.assert_allclose(turned.radiance(np.float32([[0, 1, 0]]))[0], img[1:3, 3:5].mean(axis=(0, 1)),
                               rtol=1e-5)


def test03_importance_map_as_cycles():
    """Texel weight = average RGB x sin(theta) at the row centre; pdf =
    weight x W H / total / (2 pi^2 sin theta): known values at texel centres."""
    h, w = 4, 8
    rng = np.random.default_rng(5)
    img = rng.random((h, w, 3)).astype(np.float32) + 0.1
    env = Environment.from_equirect(img)
    sin_row = np.sin(np.pi * (np.arange(h) + 0.5) / h)
    weight = img.astype(np.float64).mean(axis=2) * sin_row[:, None]
    rows, cols = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    centres = uv_to_direction((cols.ravel() + 0.5) / w, (rows.ravel() + 0.5) / h)
    expected = weight.ravel() * w * h / weight.sum() / (2 * np.pi ** 2 * np.repeat(sin_row, w))
    np.testing.assert_allclose(env.pdf(centres), expected, rtol=1e-5)
    # The sampler picks texels in proportion to their weights.
    wi, pdf, _ = env.sample(uniforms(rng, 200_000))
    u, v, _ = direction_to_uv(wi)
    texel = np.clip((v * h).astype(int), 0, h - 1) * w + np.clip((u * w).astype(int), 0, w - 1)
    counts = np.bincount(texel, minlength=h * w)
    p = weight.ravel() / weight.sum()
    z = (counts - 200_000 * p) / np.sqrt(200_000 * p * (1 - p))
    assert np.abs(z).max() < 4.5, z.reshape(h, w)
    np.testing.assert_allclose(env.mean_radiance,
                               (img * sin_row[:, None, None]).sum(axis=(0, 1)) * np.pi / (2 * w * h), rtol=1e-5)


# --- sampler and density --------------------------------------------------------------

ENVIRONMENTS = {
    "spot_and_gradient": lambda: Environment(sky(), resolution=64),
    "sharp_spot": lambda: Environment(sky(peak=2000.0, width=0.04), resolution=128),
    "constant": lambda: Environment.constant_color((0.5, 1.0, 2.0)),
}


def uv_domain():
    """Directions as Cycles' (u, v); solid angle = 2 pi^2 sin(pi v) du dv."""
    return Domain([[0.0, 1.0], [0.0, 1.0]], lambda w: direction_to_uv(w)[:2], uv_to_direction,
                  lambda u, v: 2 * np.pi ** 2 * np.sin(np.pi * v), "equirectangular (u, v)")


@pytest.mark.parametrize("name", sorted(ENVIRONMENTS))
def test04_pdf_integrates_to_one(name):
    """Over the sphere (cos theta, phi): the steps of a map's density at texel
    edges limit the quadrature to about 1e-3; over texel-aligned (u, v) bins
    the integral of a map's density is exact."""
    env = ENVIRONMENTS[name]()
    total = integrate(lambda w: env.pdf(w), spherical_domain(), res=(96, 96))
    assert total == pytest.approx(1.0, abs=3e-3)
    if env.constant is None:
        total = integrate(lambda w: env.pdf(w), uv_domain(), res=(env.width, env.height), levels=0)
        assert total == pytest.approx(1.0, abs=1e-5)
    if env.constant is not None:      # about a normal: the cosine density
        n = np.float32(unit([0.2, -0.4, 0.9]))
        total = integrate(lambda w: env.pdf(w, np.broadcast_to(n, w.shape)), spherical_domain(), res=(64, 64))
        assert total == pytest.approx(1.0, abs=2e-3)


@pytest.mark.parametrize("name", sorted(ENVIRONMENTS))
def test05_sample_matches_pdf(name, rng):
    """Chi-square over (u, v) bins of 2 x 2 texels (the density's integral over
    them is exact) for maps, and over the sphere (cos theta, phi) where
    quadrature is accurate: the smooth map and constant worlds, caps at the
    poles (where a map's density grows as 1 / sin(theta)) left to the
    test's outside cell. A fixed 64 x 64 midpoint rule per bin: the
    adaptive one settles early on a density with steps."""
    env = ENVIRONMENTS[name]()
    if env.constant is None:
        test = ChiSquareTest(lambda n: env.sample(uniforms(rng, n))[0], lambda w: env.pdf(w),
                             uv_domain(), res=(env.width // 2, env.height // 2), sample_count=N, test_count=2)
        assert test.run(), test.messages
    if name != "sharp_spot":
        test = ChiSquareTest(lambda n: env.sample(uniforms(rng, n))[0], lambda w: env.pdf(w),
                             spherical_domain(cos_range=(-0.98, 0.98)), res=(24, 48), sample_count=N,
                             test_count=2, sub=64, levels=0)
        assert test.run(), test.messages
    if env.constant is not None:
        n = np.float32(unit([0.2, -0.4, 0.9]))

        def about_n(k):
            return env.sample(uniforms(rng, k), np.ascontiguousarray(np.broadcast_to(n, (k, 3))))[0]

        test = ChiSquareTest(about_n, lambda w: env.pdf(w, np.broadcast_to(n, w.shape)),
                             spherical_domain(n), res=(24, 48), sample_count=N)
        assert test.run(), test.messages


@pytest.mark.parametrize("name", sorted(ENVIRONMENTS))
def test06_sample_agrees_with_pdf_and_radiance(name, rng):
    """sample's pdf is pdf(wi) (up to a texel boundary moved by rounding) and
    its radiance is radiance(wi)."""
    env = ENVIRONMENTS[name]()
    wi, pdf, rad = env.sample(uniforms(rng, 100_000))
    assert np.isfinite(wi).all() and np.isfinite(pdf).all() and np.isfinite(rad).all()
    assert (pdf > 0).all()
    np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1.0, atol=1e-6)
    again = env.pdf(wi)
    same = np.abs(again - pdf) <= 1e-4 * pdf
    assert same.mean() > 0.9999, (~same).sum()
    np.testing.assert_array_equal(rad, env.radiance(wi))


def test07_black_and_bad_inputs(rng):
    """A black world is flagged and samples nothing; NaN radiance and bad
    directions never leak out."""
    black = Environment(lambda d: np.zeros((len(d), 3), np.float32), resolution=32)
    assert black.is_black and Environment.constant_color((0, 0, 0)).is_black
    wi, pdf, rad = black.sample(uniforms(rng, 100))
    assert (pdf == 0).all() and (rad == 0).all() and np.isfinite(wi).all()

    def nasty(d):
        out = np.ones((len(d), 3), np.float32)
        out[d[:, 0] > 0.5] = np.nan
        out[d[:, 1] > 0.5] = -3.0
        out[d[:, 2] > 0.9] = np.inf
        return out

    env = Environment(nasty, resolution=32)
    bad = np.float32([[0, 0, 0], [np.nan, 0, 1], [np.inf, 1, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    for values in (env.radiance(bad), env.pdf(bad), *env.sample(np.float32([[np.nan, 2.0], [0.3, 0.7]]))):
        assert np.isfinite(values).all()
    assert (env.radiance(bad) >= 0).all()
    np.testing.assert_array_equal(env.radiance(np.float32([[1, 0, 0], [0, 1, 0], [0, 0, 1]])), 0.0)


def test08_map_of_a_large_image_builds_fast(rng):
    img = rng.random((512, 1024, 3), dtype=np.float32)
    t0 = time.perf_counter()
    env = Environment.from_equirect(img)
    elapsed = time.perf_counter() - t0
    assert (env.width, env.height) == (1024, 512)
    assert elapsed < 1.0, elapsed


def test09_lighting_key_follows_the_world():
    scene = make_scene(np.zeros((0, 3)), np.zeros((0, 3)))
    k0 = scene.lighting_key()
    scene.environment = Environment(sky(), resolution=32)
    k1 = scene.lighting_key()
    scene.environment = Environment(sky(peak=41.0), resolution=32)
    k2 = scene.lighting_key()
    assert len({k0, k1, k2}) == 3
    scene.environment = Environment(sky(peak=41.0), resolution=32)
    assert scene.lighting_key() == k2
    scene.environment.version += 1
    assert scene.lighting_key() != k2


# --- the world in the path tracer --------------------------------------------------------

def lit_plane(environment=None, world_color=(0, 0, 0), albedo=(0.5, 0.5, 0.5), size=16):
    """A 200 m Lambert plane seen straight down by an orthographic camera:
    nothing but the sky above, so each pixel is albedo / pi x irradiance."""
    b = Builder()
    b.add(*quad((-100, -100, 0), (200, 0, 0), (0, 200, 0)), 0)
    v, t, m = b.arrays()
    cam = Camera(to_world=look_at((0, 0, 5), (0, 0, 0), up=(0, 1, 0)), projection="ORTHO", ortho_scale=0.5)
    scene = make_scene(v, t, m, Materials.from_list([{"base_color": albedo}]), camera=cam,
                       world_color=world_color, width=size, height=size)
    scene.environment = environment
    return scene


def irradiance(fn, n=UP):
    """Irradiance at a point of normal n from radiance_fn, by quadrature (3,)."""
    n = np.asarray(n, np.float64)
    return integrate(lambda w: fn(w.astype(np.float32)) * np.maximum(w @ n, 0.0)[:, None],
                     spherical_domain(n, (0.0, 1.0)), res=(96, 96))


def test10_constant_environment_plane_is_exact():
    """Under a constant world L a Lambert plane of albedo a shows a L on every
    path: NEE samples the cosine about the normal, so both MIS strategies
    share one density and each contributes a L / 2 exactly."""
    a, L = np.float32([0.2, 0.5, 0.8]), np.float32([1.0, 2.0, 0.5])
    colour = path_samples(lit_plane(Environment.constant_color(L), albedo=a, size=10), 2, 2)
    np.testing.assert_allclose(colour, np.broadcast_to(a * L, colour.shape), rtol=1e-5)
    # The same world given as world_color (built by the LightSet) and seen directly.
    assert LightSet(lit_plane(world_color=L)).environment.constant is not None
    scene = make_scene(np.zeros((0, 3)), np.zeros((0, 3)), camera=Camera(), width=4, height=4)
    scene.environment = Environment.constant_color(L)
    np.testing.assert_allclose(path_samples(scene, 1, 2), np.broadcast_to(L, (16, 3)))


@pytest.mark.parametrize("name", ["spot_and_gradient", "sharp_spot"])
def test11_environment_map_plane_matches_quadrature(name):
    """Pixels of a plane under a map, with NEE toward the map and MIS for
    the escaping BSDF rays, average albedo / pi x the quadrature irradiance."""
    env = ENVIRONMENTS[name]()
    albedo = 0.6
    colour = path_samples(lit_plane(env, albedo=(albedo,) * 3), 48, 1)
    expected = albedo / np.pi * irradiance(env.radiance)
    mean = colour.mean(axis=0)
    err = colour.std(axis=0) / np.sqrt(len(colour))
    assert (err < 0.01 * expected).all()
    assert (np.abs(mean - expected) < 4.5 * err + 1e-4 * expected).all(), (mean, expected, err)


def test12_nee_and_mis_beat_bsdf_sampling_on_a_small_sun(rng):
    """A 1-degree sun 10^4 times brighter than the sky: light sampling with MIS
    (as the path tracer combines them) and BSDF sampling alone both reach the
    quadrature irradiance; MIS has far less variance."""
    env = Environment(sky(peak=1e4, width=0.012), resolution=512)
    scene = make_scene(np.zeros((0, 3)), np.zeros((0, 3)))
    scene.environment = env
    lights = LightSet(scene)
    assert lights.count == 1 and lights.world_pmf == 1.0
    count = 200_000
    n = np.ascontiguousarray(np.broadcast_to(np.float32(UP), (count, 3)))
    p = np.zeros((count, 3), np.float32)
    s = lights.sample(p, rng.random(count, dtype=np.float32), uniforms(rng, count), n)
    assert (s.dist == INF_DIST).all() and not s.delta.any() and s.world.all()
    cos = np.maximum(s.wi[:, 2], 0.0).astype(np.float64)
    w_l = power_heuristic(s.pdf, (cos / np.pi).astype(np.float32))
    nee = s.radiance * (cos * w_l / np.where(s.pdf > 0, s.pdf, 1.0))[:, None]
    wi = square_to_cosine_hemisphere(uniforms(rng, count))
    pdf_b = (wi[:, 2] / np.pi).astype(np.float32)
    bsdf_mis = np.pi * escaped_radiance(lights, wi, pdf_b, n, np.ones((count, 3), np.float32))
    bsdf_only = np.pi * env.radiance(wi).astype(np.float64)
    mis = nee + bsdf_mis
    expected = irradiance(env.radiance)
    for est in (mis, bsdf_only):
        mean, err = est.mean(axis=0), est.std(axis=0) / np.sqrt(count)
        assert (np.abs(mean - expected) < 4.5 * err + 2e-4 * expected).all(), (mean, expected, err)
    ratio = bsdf_only.var(axis=0) / mis.var(axis=0)
    assert (ratio > 20).all(), ratio
