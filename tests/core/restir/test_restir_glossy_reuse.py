"""Path reuse of the glossy lobe (core/restir/glossy_reuse.py).

A metal back wall in the Cornell box reflects walls and boxes that are purely
Lambertian (no specular layer), so a sample point's radiance does not depend
on the direction it leaves in and reuse is exact in expectation. Each run is
one frame's first pass (G-buffer and initial samples) with its own seed; the
reused estimate is compared with the pixel's own one-path estimate of the
same samples, by z-tests on the whole image and on blocks.
"""

import numpy as np
import pytest

from restir_gi.core import Materials, RenderContext, make_scene
from restir_gi.core.camera.projection import PixelFilter
from restir_gi.core.restir import UNBIASED, ReSTIRGI, ReSTIRSettings
from restir_gi.core.restir import glossy_reuse
from restir_gi.core.restir.gbuffer import FrameImage, trace_rows
from restir_gi.core.restir.glossy_reuse import OFFSETS, GlossySamples, reuse_glossy
from restir_gi.core.restir.initial import InitialSampling, initial_samples
from restir_gi.core.util.vectors import luminance
from support.scenes import Builder, cornell_box
from support.restir_reference import z_limit

SIZE = 40
BLOCK = 10
MAX_BOUNCES = 3
RUNS = 96


WALLS = {"metal": {"base_color": (0.9, 0.85, 0.8), "metallic": 1.0, "roughness": 0.35},
         # A dark dielectric: its specular layer reflects by the exact Fresnel curve (f_exact).
         "dielectric": {"base_color": (0.05, 0.05, 0.08), "specular": 0.5, "ior": 1.45, "roughness": 0.3}}


def metal_wall_scene(size=SIZE, wall="metal"):
    """The Cornell box (area light) with a rough metal back wall, and a
    pillar just in front of it that hides much of the room from the wall
    beside it (so that visibility differs between neighbours); every other
    surface Lambertian. wall: the back wall's material (WALLS)."""
    scene = with_pillar(cornell_box("area", size, size))
    scene.filter_width = 0.0
    base = scene.materials
    scene.materials = Materials.from_list([
        {"name": base.names[i], "base_color": tuple(base.base_color[i]), "specular": 0.0,
         "emission": tuple(base.emission[i])} for i in range(len(base))]
        + [{"name": wall, **WALLS[wall]}])
    centre = scene.vertices[scene.triangles].mean(axis=1)
    back = np.abs(centre[:, 1] - 1.0) < 1e-4
    scene.material_ids = np.where(back, len(base), scene.material_ids).astype(np.int32)
    return scene


def with_pillar(scene):
    b = Builder()
    b.add_box((-0.15, 0.75, 0.0), (0.15, 0.9, 1.7), 0)
    v, t, m = b.arrays()
    return make_scene(np.concatenate([scene.vertices, v]), np.concatenate([scene.triangles, t + len(scene.vertices)]),
                      np.concatenate([scene.material_ids, m]), scene.materials, scene.lights, scene.camera,
                      width=scene.width, height=scene.height)


@pytest.fixture(scope="module")
def ctx():
    c = RenderContext.build(metal_wall_scene())
    yield c
    c.close()


def first_pass(ctx, seed):
    """(the glossy light of surface samples drawn by the specular lobe, own
    one-path estimate (P, 3); GlossySamples; FrameImage) of one frame."""
    scene = ctx.scene
    w, h = scene.width, scene.height
    gb = trace_rows(ctx, seed, 3, PixelFilter(0.0), True, 0, w * h, None)
    _, _, everything = initial_samples(ctx, gb, seed, 3, 0, InitialSampling(MAX_BOUNCES))
    res, _, rest = initial_samples(ctx, gb, seed, 3, 0, InitialSampling(MAX_BOUNCES, own_surface_glossy=False))
    img = FrameImage(gb.valid, gb.depth, gb.object_id, gb.p, gb.n, gb.ng, w, h)
    return everything - rest, GlossySamples.of_range(gb, res), img


def block_sums(x):
    b = SIZE // BLOCK
    return x.reshape(len(x), b, BLOCK, b, BLOCK).sum(axis=(2, 4)).reshape(len(x), b * b)


def z_of_difference(a, b):
    """z of the difference of the means of two paired sets of runs (R, ...)."""
    d = a - b
    return d.mean(axis=0) / np.sqrt(np.maximum(d.var(axis=0, ddof=1) / len(d), 1e-30))


def paired_z(a, b, what):
    """(z of the image, z of the blocks, a summary) of the difference of two
    paired sets of runs (R, P)."""
    z_image = float(z_of_difference(a.sum(axis=1), b.sum(axis=1)))
    z_blocks = z_of_difference(block_sums(a), block_sums(b))
    summary = f"{what[0]} {a.sum(axis=1).mean():.4f}, {what[1]} {b.sum(axis=1).mean():.4f}, z = {z_image:.2f}; " \
              f"blocks z in [{z_blocks.min():.2f}, {z_blocks.max():.2f}]"
    print(summary)
    return z_image, z_blocks, summary


def runs(ctx, offsets=OFFSETS):
    own, reused = [], []
    for seed in range(RUNS):
        mine, gs, img = first_pass(ctx, 100 + seed)
        own.append(luminance(mine))
        reused.append(luminance(reuse_glossy(ctx, img, gs, 0, SIZE * SIZE, offsets)))
    return np.array(own, np.float64), np.array(reused, np.float64)


@pytest.fixture(scope="module")
def estimates(ctx):
    return runs(ctx)


def test01_the_metal_takes_part_and_the_rest_does_not(ctx):
    _, gs, img = first_pass(ctx, 1)
    metal = img.valid & (np.abs(img.p[:, 1] - 1.0) < 1e-3)
    assert metal.mean() > 0.1
    assert (gs.p_spec[metal] > 0).all() and (gs.p_spec[img.valid & ~metal] == 0).all()
    assert gs.has[metal].mean() > 0.5 and not gs.has[~metal].any()


def test02_without_neighbours_it_is_the_pixel_own_estimate(ctx):
    """K = 0: h / p_c is the one-path estimate initial.py gives the pixel."""
    own, gs, img = first_pass(ctx, 2)
    alone = reuse_glossy(ctx, img, gs, 0, SIZE * SIZE, ())
    assert luminance(own).sum() > 1.0
    np.testing.assert_allclose(alone, own, rtol=2e-3, atol=1e-6)


def test02b_a_dielectric_lobe_is_carried_whole():
    """The same on a dark dielectric wall: GlossySamples carry its lobe's
    exact-Fresnel share, so the lobe reuse evaluates is the pixel's own."""
    c = RenderContext.build(metal_wall_scene(wall="dielectric"))
    try:
        own, gs, img = first_pass(c, 2)
        alone = reuse_glossy(c, img, gs, 0, SIZE * SIZE, ())
    finally:
        c.close()
    assert luminance(own).sum() > 0.05 and gs.f_exact.max() > 0.5
    np.testing.assert_allclose(alone, own, rtol=2e-3, atol=1e-6)


@pytest.mark.slow
def test03_reuse_keeps_the_mean(estimates):
    """Unbiased: the reused estimate's mean is the own estimate's, on the
    whole image and on every block (z-tests)."""
    own, reused = estimates
    z_image, z_blocks, summary = paired_z(reused, own, ("reused", "own"))
    assert abs(z_image) < z_limit(1), summary
    assert np.abs(z_blocks).max() < z_limit(len(z_blocks)), summary


def test04_reuse_lowers_the_variance(estimates):
    own, reused = estimates
    lit = own.mean(axis=0) > 0.01
    ratio = own[:, lit].var(axis=0).mean() / reused[:, lit].var(axis=0).mean()
    print(f"variance over the metal's pixels {ratio:.2f}x lower")
    assert ratio > 1.4


@pytest.mark.slow
def test05_weights_that_do_not_sum_to_one_are_caught(ctx, monkeypatch):
    """The test above can fail: pairs weighed as two techniques each (p_j +
    p_c instead of K p_j + p_c) count the neighbours' samples K times over."""
    monkeypatch.setattr(glossy_reuse, "_pair_density", lambda k, p_j, p_c: p_j + p_c)
    own, reused = runs(ctx)
    z_image, z_blocks, _ = paired_z(reused, own, ("reused", "own"))
    assert abs(z_image) > z_limit(1) and np.abs(z_blocks).max() > z_limit(len(z_blocks))


@pytest.mark.parametrize("threads", [2])
def test06_frames_are_the_same_on_two_workers(threads):
    """Neighbours in other workers' ranges are read from whole-image arrays:
    the image does not depend on the split."""
    scene = metal_wall_scene(96)
    serial, parallel = RenderContext.build(scene, threads=1), RenderContext.build(scene, threads=threads)
    try:
        assert len(parallel.workers.ranges(96 * 96)) == 2
        settings = ReSTIRSettings(mode=UNBIASED, max_bounces=MAX_BOUNCES, seed=5)
        out = []
        for c in (serial, parallel):
            restir = ReSTIRGI()
            out.append([restir.render_frame(c, settings, f) for f in range(2)][-1])
            assert restir.last_timings["glossy"] > 0
        assert np.array_equal(out[0].color, out[1].color)
        off = ReSTIRGI().render_frame(serial, ReSTIRSettings(mode=UNBIASED, max_bounces=MAX_BOUNCES, seed=5,
                                                             glossy_reuse=False), 0)
        assert not np.array_equal(off.color, ReSTIRGI().render_frame(serial, settings, 0).color)
    finally:
        serial.close()
        parallel.close()


@pytest.mark.slow
def test07_whole_frames_keep_the_mean_of_frames_without_reuse():
    """Whole unbiased frames (temporal and spatial reuse, accumulation): the
    same seeds with and without path reuse differ only in the glossy lobe's
    estimate, and their mean does not change (paired z-tests on the image
    and on blocks), while the metal's variance falls."""
    c = RenderContext.build(metal_wall_scene(SIZE))
    try:
        out = {True: [], False: []}
        for r in range(48):
            for on in out:
                restir = ReSTIRGI()
                settings = ReSTIRSettings(mode=UNBIASED, seed=300 + r, max_bounces=MAX_BOUNCES, glossy_reuse=on)
                for f in range(3):
                    result = restir.render_frame(c, settings, f)
                out[on].append(luminance(result.color))
        on, off = (np.array(out[k], np.float64) for k in (True, False))
        z_image, z_blocks, summary = paired_z(on, off, ("with", "without"))
        assert abs(z_image) < z_limit(1), summary
        assert np.abs(z_blocks).max() < z_limit(len(z_blocks)), summary
        assert on.var(axis=0).sum() < off.var(axis=0).sum()
    finally:
        c.close()
