"""Light probes (core/restir/light_probes.py): one light sample per pixel with
random numbers fixed per pixel, evaluated again in the next frame's scene,
tell where the direct light changed; only there does its running mean
forget."""

import numpy as np

from restir_gi.core import RenderContext
from restir_gi.core.restir import ReSTIRGI, ReSTIRSettings
from restir_gi.core.restir.light_probes import RADIUS, image_probes, light_change, probes_moved
from restir_gi.core.restir.temporal import ObjectMotion
from support.moving_card import OCCLUDER, SIZE, STANDING, scene_with

SETTINGS = ReSTIRSettings(seed=3, max_bounces=3)


def run(card, positions, patch=False):
    """The ReSTIRGI after frames over the card's ``positions``."""
    restir = ReSTIRGI()
    for f, x in enumerate(positions):
        ctx = RenderContext.build(scene_with(card, x, patch=patch))
        try:
            restir.render_frame(ctx, SETTINGS, f)
        finally:
            ctx.close()
    return restir


def test_lambda_is_zero_where_nothing_changed_and_local_where_a_probe_did():
    w, h = 30, 20
    rng = np.random.default_rng(1)
    old = rng.exponential(1.0, w * h).astype(np.float32)
    assert not light_change(old, old.copy(), w, h).any()
    new = old.copy()
    k = 10 * w + 12
    new[k] = 0.0                    # a shadow arrived in one pixel
    lam = light_change(old, new, w, h).reshape(h, w)
    yy, xx = np.mgrid[0:h, 0:w]
    near = np.maximum(abs(yy - 10), abs(xx - 12)) <= RADIUS
    assert (lam[near] > 0).all() and not lam[~near].any()
    assert lam.max() <= 1.0
    # Bad values count as no light.
    bad = old.copy()
    bad[k] = np.nan
    assert np.isfinite(light_change(old, bad, w, h)).all()


def test_probes_are_exact_in_a_still_scene_and_change_along_a_moving_shadow():
    # The card moved between frames 0 and 1: frame 1 stored its probes.
    restir = run(OCCLUDER, [0.0, 0.1])
    h = restir.history
    assert h.light_probe is not None and (h.light_probe[h.valid] > 0).mean() > 0.5
    ctx = RenderContext.build(scene_with(OCCLUDER, 0.1))
    try:
        again = probes_moved(ctx, h, None, SETTINGS.seed)
    finally:
        ctx.close()
    np.testing.assert_array_equal(again, h.light_probe)     # the same random numbers, to the bit
    # The card moves on by 20 cm: its shadow's edges on the floor change,
    # the floor far from them does not.
    scene = scene_with(OCCLUDER, 0.3)
    ctx = RenderContext.build(scene)
    try:
        new = probes_moved(ctx, h, ObjectMotion.between(scene, h), SETTINGS.seed)
    finally:
        ctx.close()
    lam = light_change(h.light_probe, new, SIZE, SIZE)
    floor = h.valid & (h.object_id == 0)
    assert (lam[floor] >= 0.99).sum() >= 20
    assert (lam[floor] == 0).mean() > 0.5


def test_a_moved_objects_probes_ride_with_it():
    """A card standing under a point light, moved sideways: its points'
    probes are evaluated where the card is now (carried with its motion),
    so they equal probes taken at those carried points directly."""
    restir = run(STANDING, [0.0, 0.1], patch=True)
    h = restir.history
    scene = scene_with(STANDING, 0.15, patch=True)
    motion = ObjectMotion.between(scene, h)
    assert motion is not None and motion.to_current is not None
    ctx = RenderContext.build(scene)
    try:
        new = probes_moved(ctx, h, motion, SETTINGS.seed)
        p = h.p.copy()
        card = h.valid & (h.object_id == 1)
        p[card, 0] += 0.05
        direct = image_probes(ctx, p, h.n, h.ng, h.valid, SETTINGS.seed)
    finally:
        ctx.close()
    assert card.sum() > 20
    np.testing.assert_allclose(new[card], direct[card], rtol=1e-4, atol=1e-6)


def test_probes_are_the_same_however_the_pixels_are_split():
    restir = run(OCCLUDER, [0.0, 0.1])
    h = restir.history
    images = []
    for threads, max_range in ((1, None), (2, 997)):
        ctx = RenderContext.build(scene_with(OCCLUDER, 0.1), threads=threads, processes=False)
        if max_range:
            ctx.workers.max_range = max_range
        try:
            images.append(image_probes(ctx, h.p, h.n, h.ng, h.valid, SETTINGS.seed))
        finally:
            ctx.close()
    np.testing.assert_array_equal(images[0], images[1])
    np.testing.assert_array_equal(images[0], h.light_probe)
