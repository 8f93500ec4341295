"""Temporal gradients (core/restir/gradients.py): last frame's samples drawn
again in the new scene tell where the light changed, and only there do the
reservoirs and running means forget."""

import dataclasses

import numpy as np

from restir_gi.core import RenderContext
from restir_gi.core.camera.projection import PixelFilter
from restir_gi.core.restir import ReSTIRGI, ReSTIRSettings
from restir_gi.core.restir.moved_history import MOVING_CAP
from restir_gi.core.restir.gradients import (RADIUS, STRATUM, history_frames, kept_share, moved_points,
                                             redrawn_values, stratum_pixels, temporal_gradient)
from restir_gi.core.restir.initial import InitialSampling
from restir_gi.core.restir.temporal import ObjectMotion
from restir_gi.core.workers.parallel import Workers
from support.moving_card import SIZE, STANDING, scene_with

SETTINGS = ReSTIRSettings(seed=3, max_bounces=3)


def test_one_pixel_per_block_inside_it():
    w, h = 10, 7
    pix = stratum_pixels(w, h, 1, 5)
    x, y = pix % w, pix // w
    assert len(pix) == 4 * 3 and len(np.unique(pix)) == len(pix)
    blocks = sorted(zip(y // STRATUM, x // STRATUM))
    assert blocks == sorted((by, bx) for by in range(3) for bx in range(4))
    assert not np.array_equal(pix, stratum_pixels(w, h, 1, 6))     # a new place each frame


def test_lambda_is_zero_where_nothing_changed_and_local_where_one_value_did():
    w, h = 40, 30
    pix = stratum_pixels(w, h, 2, 0)
    rng = np.random.default_rng(0)
    old = rng.exponential(1.0, len(pix)).astype(np.float32)
    valid = np.ones(len(pix), bool)
    assert not temporal_gradient(pix, old, old.copy(), valid, w, h).any()
    new = old.copy()
    k = len(pix) // 2
    new[k] = old[k] + 10.0
    lam = temporal_gradient(pix, old, new, valid, w, h).reshape(h, w)
    cy, cx = divmod(int(pix[k]), w)
    yy, xx = np.mgrid[0:h, 0:w]
    near = np.maximum(abs(yy - cy), abs(xx - cx)) <= RADIUS
    assert (lam[near] > 0).all() and not lam[~near].any()
    assert lam.max() <= 1.0
    # A value left out (invalid) counts for nothing.
    valid[k] = False
    assert not temporal_gradient(pix, old, new, valid, w, h).any()


def test_history_kept_falls_with_lambda():
    lam = np.linspace(0, 1, 11, dtype=np.float32)
    frames = history_frames(lam, 16)
    assert frames[0] == 15 and frames[-1] == 0
    assert (np.diff(frames) < 0).all()
    share = kept_share(lam, 8)
    assert share[0] == 1.0 and share[-1] == 0.0


def redraw(ctx, restir, motion=None):
    how = InitialSampling(SETTINGS.max_bounces, SETTINGS.initial_sampling, 1, sky_rays=False)
    h = restir.history
    return redrawn_values(ctx, h, SETTINGS.seed, PixelFilter(ctx.scene.filter_width), how,
                          h.index if SETTINGS.sequences else None, motion)


def test_redrawn_samples_are_last_frames_in_a_still_scene_and_change_near_what_moved():
    restir = ReSTIRGI()
    ctx = RenderContext.build(scene_with(STANDING, 0.0, patch=True))
    try:
        for f in range(2):
            restir.render_frame(ctx, SETTINGS, f)
        pixels, old, new, valid = redraw(ctx, restir)
    finally:
        ctx.close()
    assert valid.sum() >= 0.95 * restir.history.valid[pixels].sum() > 0
    np.testing.assert_array_equal(new[valid], old[valid])      # the same random numbers, to the bit
    assert (old[valid] > 0).sum() >= 10       # (paths that escape bring nothing)
    # The card moved 10 cm: the light changed around it, not in the far corners.
    ctx = RenderContext.build(scene_with(STANDING, 0.1, patch=True))
    try:
        pixels, old, new, valid = redraw(ctx, restir)
    finally:
        ctx.close()
    lam = temporal_gradient(pixels, old, new, valid, SIZE, SIZE)
    floor = restir.history.object_id == 0
    assert lam[floor].max() > 0.5
    assert (lam[floor] == 0).mean() > 0.3


def test_a_moved_objects_samples_are_drawn_again_where_its_points_went():
    """Forward projection: a stratum whose point lay on the card is traced
    to where that point is now and its sample drawn there; the card moved
    a millimetre, so its values are nearly last frame's."""
    restir = ReSTIRGI()
    for f in range(2):
        ctx = RenderContext.build(scene_with(STANDING, 0.0, patch=True))
        try:
            restir.render_frame(ctx, SETTINGS, f)
        finally:
            ctx.close()
    h = restir.history
    scene = scene_with(STANDING, 0.001, patch=True)
    motion = ObjectMotion.between(scene, h)
    ctx = RenderContext.build(scene)
    try:
        pixels, old, new, valid = redraw(ctx, restir, motion)
    finally:
        ctx.close()
    card = h.valid[pixels] & (h.object_id[pixels] == 1)
    assert card.sum() >= 20
    # The strata are a pass over the context's workers: in ranges of 97
    # (the card's re-aimed rows among them) they come out the same.
    ctx = RenderContext.build(scene, threads=1)
    try:
        ctx = dataclasses.replace(ctx, workers=Workers(1, max_range=97))
        assert len(ctx.workers.ranges(len(pixels))) >= 4
        again = redraw(ctx, restir, motion)
    finally:
        ctx.close()
    for a, b in zip((pixels, old, new, valid), again):
        np.testing.assert_array_equal(a, b)
    rows, points = moved_points(h, pixels, h.p[pixels], motion)
    np.testing.assert_array_equal(rows, np.flatnonzero(card))
    np.testing.assert_allclose(points - h.p[pixels][rows], [[0.001, 0.0, 0.0]] * len(rows), atol=1e-6)
    assert valid[card].mean() > 0.9
    both = card & valid & (np.maximum(old, new) > 0)
    change = np.abs(new[both] - old[both]) / np.maximum(old[both], new[both])
    assert np.median(change) < 0.05, np.median(change)


def test_far_from_a_moving_object_the_running_means_keep_their_history():
    """Objects moving used to cut every pixel's running mean to MOVING_CAP
    frames; now pixels whose light did not change keep theirs, while those
    on the moving card are still cut."""
    restir = ReSTIRGI()
    settings = ReSTIRSettings(seed=3, max_bounces=3, validate_on_change=True)
    for f, x in enumerate([0.0] * 8 + list(np.linspace(0.0, 0.3, 8))):
        ctx = RenderContext.build(scene_with(STANDING, x, patch=True))
        try:
            restir.render_frame(ctx, settings, f)
        finally:
            ctx.close()
    h = restir.history
    count = h.accumulation.count
    card = h.object_id == 1
    assert np.percentile(count[card], 90) <= MOVING_CAP + 1
    kept = count[h.object_id == 0] > MOVING_CAP + 1
    assert kept.mean() > 0.3, kept.mean()
