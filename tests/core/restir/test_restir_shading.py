"""Final shading's visibility: traced, or carried from a recent frame only
while nothing could have changed it (core/restir/shading.py)."""

import numpy as np

from restir_gi.core import RenderContext
from restir_gi.core.restir import ReSTIRGI, ReSTIRSettings
from restir_gi.core.restir.shading import VISIBILITY_MAX_AGE, VISIBILITY_MAX_MOVE, carried_visibility
from restir_gi.core.restir.shift import visible
from support.scenes import inside_box


def test01_carried_states_age_and_expire():
    n = 6
    x2 = np.tile(np.array([[0.0, 0.0, 10.0]], np.float32), (n, 1))
    p = np.zeros((n, 3), np.float32)
    owner = p.copy()
    owner[4] = (0.0, 2 * VISIBILITY_MAX_MOVE * 10.0, 0.0)       # moved too far
    prev = np.array([1, -1, VISIBILITY_MAX_AGE, 0, 1, 2], np.int8)
    from_prev = np.array([True, True, True, True, True, False])
    got = carried_visibility(prev, from_prev, owner, p, x2)
    # visible and hidden age by one; too old, unknown, moved or not last
    # frame's sample: trace again (0).
    assert got.tolist() == [2, -2, 0, 0, 0, 0]


def render(scene, frames, restir=None, settings=None):
    restir = restir or ReSTIRGI()
    settings = settings or ReSTIRSettings(max_bounces=1, seed=5)
    ctx = RenderContext.build(scene)
    try:
        for f in range(frames):
            restir.render_frame(ctx, settings, f)
        h = restir.history
        idx = np.nonzero(h.valid)[0]
        traced = visible(ctx, h.p[idx], h.ng[idx], h.n[idx], h.spatial.view(idx))
    finally:
        ctx.close()
    return restir, idx, traced


def test02_carried_visibility_is_what_a_ray_finds_in_a_static_scene():
    restir, idx, traced = render(inside_box(24, 24), 8)
    state = restir.history.visibility[idx]
    carried = np.abs(state) > 1
    assert carried.mean() > 0.3           # reuse happens (the test is not vacuous) ...
    has = restir.history.spatial.has_sample[idx]
    assert np.array_equal((state > 0)[carried & has], traced[carried & has])   # ... and is right
    assert not (traced & ~has).any()


def test03_moved_geometry_is_traced_again():
    restir, _, _ = render(inside_box(24, 24), 6)
    assert (np.abs(restir.history.visibility) > 1).any()
    scene = inside_box(24, 24)
    scene.vertices[:4] += np.float32(1e-3)      # any triangle that moves, however little
    restir, idx, traced = render(scene, 1, restir)
    state = restir.history.visibility[idx]
    assert (np.abs(state) <= 1).all()
    has = restir.history.spatial.has_sample[idx]
    assert np.array_equal((state > 0)[has], traced[has])


def test04_biased_mode_does_not_carry_hidden_samples():
    """A sample found hidden at final shading is dropped from the carried
    spatial reservoir in the biased mode (it would keep its pixel black for
    frames). The unbiased mode's spatial targets include visibility from the
    pixel (spatial.py), so what it chooses is never hidden there."""
    from restir_gi.core.restir import BIASED, UNBIASED
    scene = inside_box(24, 24)
    restir, idx, _ = render(scene, 6, settings=ReSTIRSettings(mode=BIASED, max_bounces=1, seed=5))
    h = restir.history
    hidden = h.visibility[idx] < 0
    assert hidden.sum() >= 3                        # hidden samples happen here
    assert not (hidden & h.spatial.has_sample[idx]).any()
    restir, idx, _ = render(scene, 6, settings=ReSTIRSettings(mode=UNBIASED, max_bounces=1, seed=5))
    h = restir.history
    chosen = h.spatial.has_sample[idx]
    assert chosen.sum() > len(idx) // 2
    assert (h.visibility[idx][chosen] > 0).all()
