"""ReSTIR GI under an environment: the world counted once.

The visible points' NEE takes the world's bright directions (world_share, a
function of the direction only) and the sky rays (core/restir/sky.py) carry
the rest for the diffuse lobe, or with sky_samples 0 the reservoirs' sky
samples, the glossy lobe split by MIS; a constant world is no NEE light. If
either side counted the world's light twice or not at all, the unbiased
mode's mean would leave the path tracer's. As in test_restir_vs_path.py,
independent runs give the standard error of ReSTIR's mean and the film's
per-pixel variance that of the reference; means are compared by z-tests on
the whole image and on blocks (Sidak correction)."""

import math

import numpy as np
import pytest

from restir_gi.core import Camera, Materials, RenderContext, RenderSettings, make_scene, render_frame
from restir_gi.core.lights.environment import Environment
from restir_gi.core.restir import UNBIASED, ReSTIRGI, ReSTIRSettings
from restir_gi.core.restir.initial import world_sample_radiance, world_share
from restir_gi.core.util.vectors import luminance
from support.scenes import Builder, look_at, quad
from support.restir_reference import assert_same_mean

SIZE = 12
BLOCK = 4
MAX_BOUNCES = 2
REFERENCE_SPP = 512
ALPHA = 1e-3
SUN = np.array([0.45, -0.55, 0.7]) / np.linalg.norm([0.45, -0.55, 0.7])


def sky(d):
    """A gradient sky with a bright sun-like spot (smooth, 0.1 rad wide)."""
    d = np.asarray(d, np.float64)
    base = np.array([0.3, 0.45, 0.8]) * (0.15 + 0.5 * (1.0 + d[:, 2]))[:, None]
    return (base + 150.0 * np.exp((d @ SUN - 1.0) / 0.1 ** 2)[:, None] * [1.0, 0.9, 0.75]).astype(np.float32)


WORLDS = {
    "map": lambda: Environment(sky, resolution=128),
    "map_metal_ground": lambda: Environment(sky, resolution=128),
    "constant": lambda: Environment.constant_color((0.6, 0.7, 0.9)),
}
GROUND = {"base_color": (0.7, 0.7, 0.7), "specular": 0.5, "roughness": 0.4}
METAL_GROUND = {"base_color": (0.9, 0.9, 0.9), "metallic": 1.0, "roughness": 0.5}


def make_world_scene(world):
    """A ground plane and a glossy box, seen from above at an angle with sky
    in the top rows of the image; the metal ground reflects the world by its
    glossy lobe alone."""
    b = Builder()
    b.add(*quad((-4, -4, 0), (8, 0, 0), (0, 8, 0)), 0)
    b.add_box((-0.5, -0.3, 0), (0.4, 0.6, 0.9), 1)
    v, t, m = b.arrays()
    mats = Materials.from_list([METAL_GROUND if world == "map_metal_ground" else GROUND,
                                {"base_color": (0.8, 0.5, 0.3), "metallic": 1.0, "roughness": 0.25}])
    cam = Camera(to_world=look_at((0.5, -4.5, 2.2), (0, 0, 0.6)), lens=30.0)
    scene = make_scene(v, t, m, mats, camera=cam, width=SIZE, height=SIZE)
    scene.filter_width = 0.0
    scene.environment = WORLDS[world]()
    return scene


@pytest.fixture(scope="module", params=sorted(WORLDS))
def setup(request):
    ctx = RenderContext.build(make_world_scene(request.param))
    film = render_frame(ctx, RenderSettings(samples=REFERENCE_SPP, max_bounces=MAX_BOUNCES, seed=0))
    ref = (luminance(film.mean().reshape(-1, 3)).astype(np.float64),
           film.variance_of_mean().reshape(-1).astype(np.float64))
    yield request.param, ctx, ref
    ctx.close()


def test01_split_of_the_world(setup):
    """A map's bright spot goes to NEE, its dim sky to the reservoirs; a
    constant world goes to the reservoirs whole: it is no NEE light (as in
    Cycles, which disables a constant background's light)."""
    world, ctx, _ = setup
    lights = ctx.lights
    d = np.float32([SUN, [0, 0, 1], [1, 0, 0.2]])
    share = world_share(lights, d)
    if world != "constant":
        assert lights.world_pmf > 0 and share[0] > 0.99 and (share[1:] < 0.2).all()
    else:
        assert lights.world_pmf == 0 and lights.environment is not None and (share == 0).all()
    np.testing.assert_allclose(world_sample_radiance(lights, d),
                               ctx.lights.world_radiance(d) * (1 - share)[:, None], rtol=1e-6)


def test02_reference_is_lit(setup):
    """The comparison means something: sky and lit ground in the image, and a
    reference standard error below 1 %."""
    _, _, (mean, var_of_mean) = setup
    assert (mean > 0.05).mean() > 0.9
    assert math.sqrt(var_of_mean.sum()) / mean.sum() < 0.01


@pytest.mark.slow
def test03_unbiased_without_reuse_matches_path_tracing(setup):
    world, ctx, ref = setup
    restir = ReSTIRGI()
    settings = ReSTIRSettings(mode=UNBIASED, seed=5, max_bounces=MAX_BOUNCES, temporal=False,
                              spatial=False, validation_interval=0)
    runs = np.stack([luminance(restir.render_frame(ctx, settings, f).color) for f in range(768)])
    assert_same_mean(runs.astype(np.float64), ref, f"{world}, unbiased, no reuse")


@pytest.mark.slow
def test04_unbiased_with_reuse_matches_path_tracing(setup):
    """Sky samples reused at other pixels keep their share: the mean stays."""
    world, ctx, ref = setup
    out = []
    for r in range(96):
        restir = ReSTIRGI()
        settings = ReSTIRSettings(mode=UNBIASED, seed=500 + r, max_bounces=MAX_BOUNCES)
        for f in range(4):
            result = restir.render_frame(ctx, settings, f)
        out.append(luminance(result.color))
    assert_same_mean(np.stack(out).astype(np.float64), ref, f"{world}, unbiased")


@pytest.mark.slow
def test05_sky_samples_in_the_reservoirs_match_path_tracing(setup):
    """Without sky rays the diffuse lobe's world light goes through the
    reservoirs as sky samples, reused at other pixels: the mean stays."""
    world, ctx, ref = setup
    out = []
    for r in range(96):
        restir = ReSTIRGI()
        settings = ReSTIRSettings(mode=UNBIASED, seed=900 + r, max_bounces=MAX_BOUNCES, sky_samples=0)
        for f in range(4):
            result = restir.render_frame(ctx, settings, f)
        out.append(luminance(result.color))
    assert_same_mean(np.stack(out).astype(np.float64), ref, f"{world}, unbiased, sky samples")
