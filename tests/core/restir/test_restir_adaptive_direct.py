"""Adaptive, stratified shadow rays for the direct light of visible points
(core/restir/adaptive_direct.py and the direct light of initial.py).

- The 3x3 neighbourhood range is what a brute-force loop gives.
- Shadow edges are flagged, flat lit and flat dark regions are not; a flag
  holds for HOLD_FRAMES frames; counts follow flags and missing history.
- Many stratified light samples estimate the same direct light as one sample
  (z-test over seeds) with far less variance than as many independent ones.
"""

import numpy as np
import pytest

from restir_gi.core import RenderContext
from restir_gi.core.camera.projection import PixelFilter
from restir_gi.core.restir.adaptive_direct import (HOLD_FRAMES, light_sample_counts, neighbourhood_range,
                                         reprojected_hold, update_noise_hold)
from restir_gi.core.restir.gbuffer import trace_gbuffer
from restir_gi.core.restir.initial import InitialSampling, initial_samples
from restir_gi.core.util.vectors import luminance
from support.scenes import cornell_box, glow_by_wall


def test01_neighbourhood_range_matches_brute_force():
    rng = np.random.default_rng(3)
    w, h = 7, 5
    values = rng.random(w * h).astype(np.float32)
    valid = rng.random(w * h) > 0.3
    mx, mn = neighbourhood_range(values, valid, w, h)
    img, ok = values.reshape(h, w), valid.reshape(h, w)
    for y in range(h):
        for x in range(w):
            win = img[max(y - 1, 0):y + 2, max(x - 1, 0):x + 2][ok[max(y - 1, 0):y + 2, max(x - 1, 0):x + 2]]
            assert mx[y * w + x] == (win.max() if len(win) else -np.inf)
            assert mn[y * w + x] == (win.min() if len(win) else np.inf)


def test02_shadow_edges_are_flagged_and_held():
    w, h = 12, 6
    direct = np.zeros((w * h, 3), np.float32)
    lit = (np.arange(w * h) % w) < 6                      # left half lit, right half in shadow
    direct[lit] = 2.0
    direct[lit] *= 1.0 + 0.05 * np.arange(w * h)[lit, None] / (w * h)   # a smooth gradient
    valid = np.ones(w * h, bool)
    hold = update_noise_hold(direct, valid, w, h, None)
    col = np.arange(w * h) % w
    assert (hold[(col == 5) | (col == 6)] == HOLD_FRAMES).all()        # the edge
    assert (hold[(col <= 3) | (col >= 8)] == 0).all()                  # flat lit, flat dark
    # Without new triggers a flag counts down, then is gone.
    flat = np.full((w * h, 3), 1.0, np.float32)
    for left in range(HOLD_FRAMES - 1, -1, -1):
        hold = update_noise_hold(flat, valid, w, h, hold)
        assert (hold[col == 5] == left).all()
    # Pixels without a visible point are never flagged.
    assert (update_noise_hold(direct, np.zeros(w * h, bool), w, h, None) == 0).all()


def test03_counts_follow_flags_and_history():
    """Flags travel with the reprojection (a camera move shifts them)."""
    index = np.arange(6)
    prev_pix = np.array([1, 2, -1, 4, 5, 0])          # last frame's pixel of each pixel
    prev_hold = np.array([0, 0, 3, 0, 0, 1], np.int8)   # last frame: pixels 2 and 5 noisy
    hold = reprojected_hold(prev_pix, prev_hold)
    assert list(hold) == [0, 3, 0, 0, 1, 0]
    assert list(light_sample_counts(index, prev_pix, hold, 16)) == [1, 16, 16, 1, 16, 1]
    # Pixels without a visible point are not in index.
    assert list(light_sample_counts(np.array([1, 4]), prev_pix, hold, 16)) == [16, 16]
    assert (light_sample_counts(index, prev_pix, None, 16) == 1).all()     # first frame: its
    # own noise decides the next frame's counts
    assert (light_sample_counts(index, prev_pix, hold, 1) == 1).all()


@pytest.fixture(scope="module")
def box():
    scene = cornell_box("area", 16, 16)
    scene.filter_width = 0.0
    ctx = RenderContext.build(scene)
    yield ctx, trace_gbuffer(ctx, 0, 0, PixelFilter(0.0), jitter=False)
    ctx.close()


def direct_runs(ctx, gb, counts, runs):
    """Luminance of the direct light of every pixel over independent frames, (runs, P)."""
    return np.stack([luminance(initial_samples(ctx, gb, 11, f, 0, InitialSampling(0, light_samples=counts))[1])
                     for f in range(runs)]).astype(np.float64)


@pytest.mark.slow
def test04_stratified_samples_are_unbiased_and_better_than_independent(box):
    ctx, gb = box
    one = direct_runs(ctx, gb, 1, 1024)
    many = direct_runs(ctx, gb, 16, 256)
    # Same mean: image sums, z-test over the independent frames.
    a, b = one.sum(axis=1), many.sum(axis=1)
    z = (a.mean() - b.mean()) / np.sqrt(a.var(ddof=1) / len(a) + b.var(ddof=1) / len(b))
    print(f"direct light: one sample {a.mean():.3f}, 16 stratified {b.mean():.3f}, z = {z:.2f}")
    assert abs(z) < 3.3
    # Variance per pixel: below a sixteenth of one sample's (independent
    # samples would give exactly a sixteenth), where the box has penumbrae.
    noisy = one.var(axis=0) > 1e-3 * one.var(axis=0).max()
    ratio = many.var(axis=0, ddof=1)[noisy].sum() / one.var(axis=0, ddof=1)[noisy].sum()
    print(f"variance of 16 stratified samples: {ratio:.4f} of one sample's (1/16 = {1 / 16:.4f})")
    assert noisy.mean() > 0.2
    assert ratio < 0.75 / 16


def test05_counts_per_pixel_mix(box):
    """A count per visible point: pixels with one sample get the one-sample
    estimate of the same seeds, pixels with many the stratified one."""
    ctx, gb = box
    v = len(gb.index)
    mixed = np.where(np.arange(v) % 2 == 0, 1, 8)
    d_mixed = initial_samples(ctx, gb, 4, 0, 0, InitialSampling(0, light_samples=mixed))[1][gb.index]
    d_one = initial_samples(ctx, gb, 4, 0, 0, InitialSampling(0, light_samples=1))[1][gb.index]
    d_many = initial_samples(ctx, gb, 4, 0, 0, InitialSampling(0, light_samples=8))[1][gb.index]
    assert np.allclose(d_mixed[mixed == 1], d_one[mixed == 1])
    assert np.allclose(d_mixed[mixed == 8], d_many[mixed == 8])
    assert not np.allclose(d_one, d_many)


@pytest.mark.slow
def test06_light_samples_near_an_emitter_count_in_the_mis_weights():
    """On a wall lit by an emissive cube a few centimetres away, where BSDF
    rays find the cube often, 16 light samples a point are weighed against
    the one BSDF ray as 16 samples: the direct light's variance falls far
    below one sample's, and the mean stays. Measured: 0.024 of one sample's
    variance; 0.085 with area sampling of the cube's triangles; weighed as
    one sample each (the BSDF ray keeping its share and its noise) 0.33,
    and 0.47 with area sampling too."""
    scene = glow_by_wall()
    scene.filter_width = 0.0
    ctx = RenderContext.build(scene)
    try:
        gb = trace_gbuffer(ctx, 0, 0, PixelFilter(0.0), jitter=False)
        one = direct_runs(ctx, gb, 1, 512)
        many = direct_runs(ctx, gb, 16, 128)
    finally:
        ctx.close()
    a, b = one.sum(axis=1), many.sum(axis=1)
    z = (a.mean() - b.mean()) / np.sqrt(a.var(ddof=1) / len(a) + b.var(ddof=1) / len(b))
    wall = one.mean(axis=0) < 5.0       # the cube's own pixels show its emission
    ratio = many.var(axis=0, ddof=1)[wall].sum() / one.var(axis=0, ddof=1)[wall].sum()
    print(f"near an emitter: 16 light samples give {ratio:.3f} of one sample's variance, z = {z:.2f}")
    assert abs(z) < 3.3
    assert ratio < 0.15


@pytest.mark.slow
def test07_a_stream_of_frames_spreads_its_light_samples(box):
    """Along an image stream (stream_index: the frames of a still) each
    pixel's light samples follow its scrambled sequences: the mean of 16
    consecutive frames is the same as that of 16 independent ones (z-test
    over runs, each run its own seed) with far less variance in the
    penumbrae. Measured: 0.036 of the independent frames' variance."""
    ctx, gb = box

    def runs(stream):
        out = []
        for r in range(96):
            seed = 100 + r
            frames = [initial_samples(ctx, gb, seed, f, 0, InitialSampling(0), stream_index=f if stream else None)[1]
                      for f in range(16)]
            out.append(luminance(np.mean(frames, axis=0)))
        return np.array(out, np.float64)

    along, independent = runs(True), runs(False)
    a, b = along.sum(axis=1), independent.sum(axis=1)
    z = (a.mean() - b.mean()) / np.sqrt(a.var(ddof=1) / len(a) + b.var(ddof=1) / len(b))
    noisy = independent.var(axis=0) > 1e-3 * independent.var(axis=0).max()
    ratio = along.var(axis=0, ddof=1)[noisy].sum() / independent.var(axis=0, ddof=1)[noisy].sum()
    print(f"16 frames along a stream: {ratio:.3f} of 16 independent frames' variance, z = {z:.2f}")
    assert abs(z) < 3.3
    assert noisy.mean() > 0.2
    assert ratio < 0.15
