"""Which pixels' direct light a moving object can have changed
(core/restir/shadow_reach.py)."""

from types import SimpleNamespace

import numpy as np

from restir_gi.core import RenderContext
from restir_gi.core.restir.accumulation import LIGHT_FRAMES
from restir_gi.core.restir import ReSTIRGI, ReSTIRSettings
from restir_gi.core.restir.moved_history import MOVING_CAP
from restir_gi.core.restir.shadow_reach import reached, segment_hits_box, swept_boxes
from support.moving_card import OCCLUDER, scene_with


def test_segments_and_boxes():
    lo, hi = np.zeros(3), np.ones(3)
    a = np.array([[-1, 0.5, 0.5], [-1, 0.5, 0.5], [0.5, 0.5, 0.5], [-1, 2.0, 0.5], [2, 0.5, 0.5]], float)
    b = np.array([[2, 0.5, 0.5], [-0.5, 0.5, 0.5], [0.6, 0.5, 0.5], [2, 2.0, 0.5], [3, 0.5, 0.5]], float)
    assert list(segment_hits_box(a, b, lo, hi)) == [True, False, True, False, False]


def motion_of(scene, dx):
    """ObjectMotion-like: the card (object 1) moved by dx along x since last frame."""
    back = np.tile(np.eye(4), (2, 1, 1))
    back[1, 0, 3] = -dx
    return SimpleNamespace(moved_now=np.array([False, True]), to_previous=back)


def test_shadow_rays_through_the_swept_box_and_points_near_it_are_reached():
    scene = scene_with(OCCLUDER, 0.2)           # a card half way up to a point lamp above the origin
    ctx = RenderContext.build(scene)
    try:
        motion = motion_of(scene, 0.2)
        (lo, hi), = swept_boxes(scene, motion)
        assert np.isclose(lo[0], -0.4) and np.isclose(hi[0], 0.6)      # where it was and is
        p = np.array([[0.0, 0.0, 0.0],          # under the card, toward the lamp: its shadow
                      [3.9, 3.9, 0.0],          # a far corner of the floor
                      [-3.9, -3.9, 0.0]], np.float32)
        out = reached(scene, ctx.lights, motion, p, np.ones(3, bool))
        assert list(out) == [True, False, False]
        assert not reached(scene, ctx.lights, motion, p, np.zeros(3, bool)).any()
    finally:
        ctx.close()


def test_far_from_a_moving_card_the_direct_light_keeps_its_history():
    """The light group's running means were cut to MOVING_CAP frames on every
    pixel while anything moved; now only where the card can shadow."""
    restir = ReSTIRGI()
    settings = ReSTIRSettings(seed=3, max_bounces=2, validate_on_change=True)
    for f, x in enumerate([0.0] * 6 + list(np.linspace(0.0, 0.2, 6))):
        ctx = RenderContext.build(scene_with(OCCLUDER, x))
        try:
            restir.render_frame(ctx, settings, f)
        finally:
            ctx.close()
    h = restir.history
    frames = h.accumulation.data[:, LIGHT_FRAMES]
    floor = h.object_id == 0
    assert (frames[floor] > MOVING_CAP + 1).mean() > 0.2
    assert (frames[floor] <= MOVING_CAP + 1).mean() > 0.05       # and near the card, not
