"""ReSTIR GI against the reference path tracer, statistically.

Every ReSTIR run is independent (its own seed, a fresh ReSTIRGI, a few frames
of a static view; the last frame is kept), so the spread over runs gives the
standard error of their mean. The reference is render_frame with many samples;
its film's per-pixel variance gives its standard error (pixels of the path
tracer are independent). Means are compared with z-tests: on the whole image
and on blocks of pixels (Sidak correction over the blocks). The pixel filter
is off for both, so every pixel sees the same visible point.

- The unbiased mode, with and without reuse, has the path tracer's mean.
- The biased mode trades that for far less variance than 1 spp path tracing.
"""

import math

import numpy as np
import pytest

from restir_gi.core import Camera, RenderContext, RenderSettings, render_frame
from restir_gi.core.restir import BIASED, UNBIASED, ReSTIRGI, ReSTIRSettings
from restir_gi.core.util.vectors import luminance
from support.scenes import cornell_box, look_at, open_yard
from support.restir_reference import (
    BLOCK, MAX_BOUNCES, SIZE, Reference, assert_same_mean, blocks, restir_runs)

REFERENCE_SPP = 1024
RUNS = 96               # independent ReSTIR runs per mode


def make_scene():
    scene = cornell_box("area", SIZE, SIZE)
    scene.filter_width = 0.0
    # The camera a little off the box's axis: on the axis the centres of the
    # diagonal pixels lie exactly on the seams between walls, where a visible
    # point finds no light by reconnection (its neighbour wall at distance
    # zero) and a path does. Points of zero area: with a pixel filter no
    # camera ray hits them, but without one these pixels biased the blocks.
    scene.camera = Camera(to_world=look_at((0.011, -3.9, 1.007), (0.011, 0, 1.007)), lens=50.0,
                          sensor_width=36.0)
    return scene


@pytest.fixture(scope="module")
def ctx():
    c = RenderContext.build(make_scene())
    yield c
    c.close()


@pytest.fixture(scope="module")
def reference(ctx):
    return Reference(render_frame(ctx, RenderSettings(samples=REFERENCE_SPP, max_bounces=MAX_BOUNCES, seed=0)))


def no_reuse_runs(ctx, runs):
    """Without temporal or spatial reuse every frame is independent: one
    ReSTIRGI, one frame per run."""
    restir = ReSTIRGI()
    settings = ReSTIRSettings(mode=UNBIASED, seed=77, max_bounces=MAX_BOUNCES, temporal=False,
                              spatial=False, validation_interval=0)
    return np.stack([luminance(restir.render_frame(ctx, settings, f).color)
                     for f in range(runs)]).astype(np.float64)


def test01_reference_is_lit(reference):
    """The comparison means something: the image is lit, most blocks are, and
    the reference's image mean has a standard error below 0.5 %."""
    assert reference.count == REFERENCE_SPP
    assert reference.mean.mean() > 0.05
    assert (blocks(reference.mean) / BLOCK ** 2 > 0.01).mean() > 0.9
    assert math.sqrt(reference.var_of_mean.sum()) / reference.mean.sum() < 0.005


@pytest.mark.slow
def test02_unbiased_without_reuse_matches_path_tracing(ctx, reference):
    runs = no_reuse_runs(ctx, 4 * RUNS)
    assert_same_mean(runs, reference, "unbiased, no reuse")


@pytest.mark.slow
def test03_unbiased_matches_path_tracing(ctx, reference):
    runs = restir_runs(ctx, RUNS, mode=UNBIASED)
    assert_same_mean(runs, reference, "unbiased")


@pytest.mark.slow
def test04_biased_has_far_less_variance(ctx, reference):
    """Mean per-pixel variance over runs against path tracing at 1 spp (with
    one NEE sample for the direct light too, so only the reuse differs)."""
    runs = restir_runs(ctx, RUNS // 2, mode=BIASED, light_samples=1)
    ratio = reference.var_1spp.mean() / runs.var(axis=0, ddof=1).mean()
    print(f"biased: per-pixel variance {ratio:.1f}x below 1 spp path tracing; "
          f"mean {runs.mean():.5f} vs {reference.mean.mean():.5f}")
    assert ratio > 3.0, ratio
    # Biased, but not wildly so.
    assert abs(runs.mean() / reference.mean.mean() - 1.0) < 0.1


@pytest.mark.slow
def test05_unbiased_with_the_pixel_filter_is_within_one_percent():
    """With the pixel filter on, visible points move every frame, so the
    history often cannot hold this frame's new sample (temporal.py weighs the
    two by the balance heuristic). The image mean stays within 1 % of path
    tracing's (measured 0.996 +- 0.0014 on 200 runs at 24x24 with 1/Z in the
    spatial pass, 0.992 with 1/Z in both), and no run's pixel is a firefly of over 50x the image mean."""
    scene = make_scene()
    scene.filter_width = 1.5
    ctx = RenderContext.build(scene)
    try:
        ref = luminance(render_frame(ctx, RenderSettings(samples=REFERENCE_SPP, max_bounces=MAX_BOUNCES, seed=3))
                        .mean().reshape(-1, 3)).mean()
        runs = restir_runs(ctx, RUNS, mode=UNBIASED)
    finally:
        ctx.close()
    means = runs.mean(axis=1)
    ratio, se = means.mean() / ref, means.std(ddof=1) / math.sqrt(len(means)) / ref
    print(f"unbiased with the filter: {ratio:.4f} +- {se:.4f} of path tracing")
    assert abs(ratio - 1.0) < 0.01 + 3 * se, (ratio, se)
    assert runs.max() < 50 * ref


@pytest.mark.slow
def test06_unbiased_spatial_reuse_lowers_variance():
    """Spatial reuse in the unbiased mode adds neighbours' samples to the
    temporal reservoir's: the indirect light's per-pixel variance over runs
    must fall (pairwise MIS: 1.19x on this open yard, with each frame's
    samples hashed anew). With 1/Z weights (every reservoir that could hold
    the sample weighed alike) it rose instead on open scenes (0.77x here;
    the corpus courtyard 2.2x). With the first bounce's sequences over the
    frames (the default) the temporal reservoirs alone already hold evenly
    spread samples: variance 1.38-1.42x lower than hashed, with spatial
    reuse 1.15x, so spatial reuse adds little on top of them here
    (0.98-1.01x). Neither may be worse than hashed."""
    ctx = RenderContext.build(open_yard())
    try:
        var = {}
        for sequences in (False, True):
            for spatial in (False, True):
                runs = restir_runs(ctx, RUNS // 3, part="indirect", mode=UNBIASED, spatial=spatial,
                                   sequences=sequences)
                var[sequences, spatial] = runs.var(axis=0, ddof=1).mean()
    finally:
        ctx.close()
    ratio = var[False, False] / var[False, True]
    print(f"unbiased: spatial reuse lowers the indirect light's per-pixel variance {ratio:.2f}x; with the "
          f"sequences {var[True, False] / var[True, True]:.2f}x; the sequences {var[False, False] / var[True, False]:.2f}x "
          f"(temporal only) and {var[False, True] / var[True, True]:.2f}x (with spatial reuse)")
    assert ratio > 1.05, ratio
    assert var[True, False] < var[False, False] and var[True, True] < var[False, True], var
