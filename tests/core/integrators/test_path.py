"""The reference path tracer on scenes with closed-form answers (in the manner
of pbrt's integrators_test): a furnace plane, a closed emissive box whose
truncated Neumann series is known for every bounce limit, direct lighting that
matches the Cycles measurements, determinism, and degenerate scenes."""

import numpy as np
import pytest

from restir_gi.core import Camera, Lights, Materials, RenderContext, RenderSettings, make_scene, render_frame
from restir_gi.core.scene import LIGHT_AREA, LIGHT_POINT, LIGHT_SUN
from support.scenes import Builder, cornell_box, furnace, look_at, path_samples, quad, tilted_emitter
from support.scenes import closed_box


def render(scene, samples, max_bounces, seed=0, frame=0):
    ctx = RenderContext.build(scene)
    try:
        return render_frame(ctx, RenderSettings(samples=samples, max_bounces=max_bounces, seed=seed), frame)
    finally:
        ctx.close()


def assert_mean(values, expected, z=4.5, rel=1e-5):
    mean = values.mean(axis=0)
    err = values.std(axis=0) / np.sqrt(len(values))
    assert (np.abs(mean - expected) <= z * err + rel * np.abs(expected)).all(), (mean, expected, err)
    return mean, err


# --- (1) furnace --------------------------------------------------------------------

@pytest.mark.parametrize("max_bounces", [0, 1, 3])
def test01_furnace_plane(max_bounces):
    """A Lambert plane of albedo a under a constant world L shows a L, exactly:
    every path bounces once and escapes with weight a."""
    film = render(furnace(albedo=0.5, world=1.0, width=16, height=16), 4, max_bounces)
    assert np.allclose(film.mean(), 0.5, rtol=1e-5)


def test02_furnace_plane_in_colour():
    a, world = np.float32([0.2, 0.5, 0.8]), np.float32([1.0, 2.0, 0.5])
    b = Builder()
    b.add(*quad((-50, -50, 0), (100, 0, 0), (0, 100, 0)), 0)
    v, t, m = b.arrays()
    cam = Camera(to_world=look_at((1, -2, 5), (0, 0, 0)), lens=35.0)
    scene = make_scene(v, t, m, Materials.from_list([{"base_color": a}]), Lights.empty(), cam,
                       world_color=world, width=12, height=10)
    colour = path_samples(scene, 2, 2)
    assert np.allclose(colour, a * world, rtol=1e-5)


# --- (2) closed box ---------------------------------------------------------------------


def box_radiance(albedo, emission, max_bounces):
    """Every path sees Le at the camera hit; each of the vertices 0..max_bounces
    adds a * (radiance arriving there) through NEE and the BSDF ray together,
    so L = Le (1 + a + ... + a^(max_bounces + 1))."""
    a = np.asarray(albedo, np.float64)
    return np.asarray(emission, np.float64) * sum(a ** j for j in range(max_bounces + 2))


@pytest.mark.parametrize("max_bounces", [0, 1, 2])
def test03_closed_box_few_bounces(max_bounces):
    a, le = (0.5, 0.7, 0.3), (1.0, 0.5, 2.0)
    colour = path_samples(closed_box(a, le), 24, max_bounces)
    mean, err = assert_mean(colour, box_radiance(a, le, max_bounces))
    assert (err < 0.01 * mean).all()
    # The neighbouring bounce limits are told apart.
    for other in (max_bounces - 1, max_bounces + 1):
        if other >= 0:
            assert (np.abs(mean - box_radiance(a, le, other)) > 6 * err).any()


@pytest.mark.slow
def test04_closed_box_many_bounces_with_russian_roulette():
    """Far past the roulette threshold the sum reaches Le / (1 - a)."""
    a, le = (0.6, 0.8, 0.4), (1.0, 1.0, 1.0)
    colour = path_samples(closed_box(a, le, size=16), 48, 40)
    limit = np.asarray(le) / (1 - np.asarray(a))
    assert np.allclose(box_radiance(a, le, 40), limit, rtol=1e-3)
    mean, err = assert_mean(colour, box_radiance(a, le, 40))
    assert (err < 0.01 * mean).all()


# --- direct lighting against the Cycles measurements ---------------------------------------

def lit_plane(lights, size=8):
    """A 20 m Lambert plane (albedo 0.8) seen by an orthographic camera looking
    straight down at a 2 cm patch, as in the conventions measurements."""
    b = Builder()
    b.add(*quad((-10, -10, 0), (20, 0, 0), (0, 20, 0)), 0)
    v, t, m = b.arrays()
    cam = Camera(to_world=look_at((0, 0, 5), (0, 0, 0), up=(0, 1, 0)), projection="ORTHO", ortho_scale=0.02)
    return make_scene(v, t, m, Materials.from_list([{"base_color": (0.8, 0.8, 0.8)}]),
                      Lights.from_list(lights), cam, width=size, height=size)


def test05_point_light_direct():
    scene = lit_plane([{"kind": LIGHT_POINT, "position": (0, 0, 2), "power": (100, 50, 25), "radius": 0.0}])
    colour = path_samples(scene, 2, 0)
    assert np.allclose(colour.mean(axis=0), [0.5066, 0.2533, 0.1266], rtol=1e-3)


@pytest.mark.parametrize("light,pixel", [
    ({"kind": LIGHT_AREA, "position": (0, 0, 1.5), "direction": (0, 0, -1), "power": (100, 100, 100),
      "size_u": 1.0, "size_v": 1.0}, 3.1403),
    ({"kind": LIGHT_POINT, "position": (0, 0, 2), "power": (100, 100, 100), "radius": 1.0,
      "soft_falloff": True}, 0.8 / np.pi * 100 / (4 * np.pi) / (2 ** 2 + 1 ** 2)),   # Cycles: 0.4053
    ({"kind": LIGHT_POINT, "position": (0, 0, 2), "power": (100, 100, 100), "radius": 1.0,
      "soft_falloff": False}, 0.8 / np.pi * 100 / (4 * np.pi) / 2 ** 2),             # Cycles: 0.5066
])
def test06_lights_through_nee_and_bsdf_rays(light, pixel):
    """Lights that BSDF rays can hit: the path tracer's MIS of both strategies
    must give the measured brightness (a missing or double-counted strategy
    shows up as a few percent)."""
    colour = path_samples(lit_plane([light], size=16), 32, 0)
    assert_mean(colour, np.full(3, pixel), rel=1e-3)


def test06b_shading_normals_across_the_face_keep_their_side():
    """Custom normals at right angles to their faces (foliage and cards
    shaded as a volume) are stored a hair across the face's plane. They are
    shaded as they point, as Cycles does (0.8 / pi S cos to the sun), not
    turned around to face away from the light (black)."""
    scene = lit_plane([{"kind": LIGHT_SUN, "direction": (-0.6, 0.0, -0.8), "power": (2.0,) * 3,
                        "angle": 0.0}])
    ns = np.float32([1.0, 0.0, -1e-4]) / np.float32(np.hypot(1.0, 1e-4))
    scene = make_scene(scene.vertices, scene.triangles, scene.material_ids, scene.materials, scene.lights,
                       scene.camera, normals=np.broadcast_to(ns, (scene.triangle_count, 3, 3)),
                       width=8, height=8)
    colour = path_samples(scene, 2, 0)
    assert_mean(colour, np.full(3, 0.8 / np.pi * 2.0 * 0.6), rel=1e-3)


# --- (3) determinism -----------------------------------------------------------------------

def test07_same_seed_same_image():
    scene = cornell_box(light="point", width=12, height=12)
    a = render(scene, 2, 3, seed=7).mean()
    b = render(scene, 2, 3, seed=7).mean()
    assert np.array_equal(a, b)
    assert not np.array_equal(a, render(scene, 2, 3, seed=8).mean())
    assert not np.array_equal(a, render(scene, 2, 3, seed=7, frame=1).mean())


# --- (4) degenerate scenes -------------------------------------------------------------------

def test08_degenerate_triangles_are_removed():
    box = cornell_box(width=10, height=10)
    v = np.concatenate([box.vertices, np.float32([[0, 0, 1], [0, 0, 1], [1, 1, 1],
                                                   [np.nan, 0, 0], [0, 1, 0], [1, 0, 0]])])
    extra = np.int32([[0, 1, 2], [3, 4, 5]]) + len(box.vertices)
    t = np.concatenate([box.triangles, extra, np.int32([[0, 0, 1]])])
    m = np.concatenate([box.material_ids, np.int32([0, 0, 0])])
    scene = make_scene(v, t, m, box.materials, box.lights, box.camera, width=10, height=10)
    assert scene.triangle_count == box.triangle_count
    assert scene.warnings
    img = render(scene, 2, 2).mean()
    assert np.isfinite(img).all() and img.max() > 0


def test09_no_lights_is_black():
    box = cornell_box(width=10, height=10)
    mats = Materials.from_list([{"base_color": (0.8, 0.8, 0.8)}])
    scene = make_scene(box.vertices, box.triangles, np.zeros(box.triangle_count, np.int32), mats,
                       Lights.empty(), box.camera, width=10, height=10)
    film = render(scene, 2, 3)
    assert (film.mean() == 0).all()


def test10_no_triangles_shows_the_world():
    world = (0.25, 0.5, 1.0)
    for lights in (Lights.empty(), Lights.from_list([{"kind": LIGHT_POINT, "position": (0, 0, 1),
                                                      "power": (10, 10, 10), "radius": 0.2}])):
        scene = make_scene(np.zeros((0, 3)), np.zeros((0, 3)), lights=lights, world_color=world,
                           camera=Camera(to_world=look_at((0, -3, 0), (0, 0, 0))), width=8, height=6)
        img = render(scene, 2, 2).mean()
        assert np.allclose(img, world)


def test11_no_nan_from_lights_touching_surfaces():
    """Lights lying on a surface or inside the box: finite images."""
    scene = cornell_box(light="area", width=10, height=10)
    lights = Lights.from_list([
        {"kind": LIGHT_AREA, "position": (0, 0, 0), "direction": (0, 0, -1), "power": (50, 50, 50)},
        {"kind": LIGHT_POINT, "position": (-1, 0, 1), "power": (50, 50, 50), "radius": 0.0},
        {"kind": LIGHT_POINT, "position": (0.3, -0.3, 0.6), "power": (50, 50, 50), "radius": 0.3,
         "soft_falloff": False},
    ])
    scene = make_scene(scene.vertices, scene.triangles, scene.material_ids, scene.materials, lights,
                       scene.camera, width=10, height=10)
    img = render(scene, 2, 3).mean()
    assert np.isfinite(img).all() and img.max() > 0


@pytest.mark.slow
def test12_pixel_positions_over_samples_are_spread():
    """A pixel's pixel-filter positions over a render's samples follow a
    rotated R2 sequence (as Cycles' Sobol pattern): at the pixels a bright
    outline crosses, 16 samples spread less over seeds than 16 independent
    ones would (the 1-sample spread over 16), with the same mean."""
    ctx = RenderContext.build(tilted_emitter(16, 16))
    try:
        lum = np.array([0.2126, 0.7152, 0.0722])
        sixteen = np.array([render_frame(ctx, RenderSettings(samples=16, max_bounces=0, seed=s)).mean() @ lum
                            for s in range(32)]).reshape(32, -1)
        one = np.array([render_frame(ctx, RenderSettings(samples=1, max_bounces=0, seed=s)).mean() @ lum
                        for s in range(100, 612)]).reshape(512, -1)
    finally:
        ctx.close()
    iid = one.var(axis=0, ddof=1) / 16
    edges = iid > 0.01 * iid.max()
    assert edges.sum() >= 15
    se = np.sqrt(sixteen.var(axis=0, ddof=1) / 32 + one.var(axis=0, ddof=1) / 512)[edges]
    assert (np.abs(sixteen.mean(axis=0) - one.mean(axis=0))[edges] <= 4.5 * se + 1e-9).all()
    ratio = sixteen.var(axis=0, ddof=1)[edges].sum() / iid[edges].sum()
    assert ratio < 0.6, ratio       # measured 0.39 (independent positions: 1)


def test13_small_images_trace_several_samples_per_pass():
    """A small image's samples are traced several to a batch (fewer passes,
    both workers busy), with the same paths: the film equals one pass per
    sample, bit for bit, on one worker and on two, including a last batch
    that is not full (64x64: 16 samples to a batch, 20 = 16 + 4)."""
    from restir_gi.core.render import samples_per_pass
    scene = cornell_box(light="area", width=64, height=64)
    assert samples_per_pass(64 * 64, 20) == 16 and samples_per_pass(320 * 180, 20) == 1
    per_sample = path_samples(scene, 20, 2, seed=3).reshape(20, -1, 3).mean(axis=0)
    for threads in (1, 2):
        ctx = RenderContext.build(scene, threads=threads)
        try:
            seen = []
            film = render_frame(ctx, RenderSettings(samples=20, max_bounces=2, seed=3),
                                on_sample=lambda f, _: seen.append(f.count))
        finally:
            ctx.close()
        assert seen == list(range(1, 21))
        assert np.array_equal(film.mean().reshape(-1, 3), per_sample.astype(np.float32)), threads


def test14_a_cancel_keeps_the_samples_of_the_batches_done():
    scene = cornell_box(light="area", width=64, height=64)
    ctx = RenderContext.build(scene, threads=1)
    polls = []
    try:
        film = render_frame(ctx, RenderSettings(samples=40, max_bounces=1, seed=0),
                            should_stop=lambda: polls.append(1) or len(polls) > 1)
    finally:
        ctx.close()
    assert film.count == 16 and np.isfinite(film.mean()).all() and film.mean().max() > 0
