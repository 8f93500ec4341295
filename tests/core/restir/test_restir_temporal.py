"""Temporal reuse of ReSTIR GI (core/restir/temporal.py, validation.py and the
state kept by ReSTIRGI): reprojection after camera and object motion,
rejection of disoccluded pixels, reset on a resolution change, sample
validation removing a light that was switched off, bounded memory and M."""

import dataclasses

import numpy as np
import pytest

from restir_gi.core import Camera, Lights, Materials, RenderContext, make_scene
from restir_gi.core.camera.projection import PixelFilter
from restir_gi.core.restir import BIASED, UNBIASED, ReSTIRGI, ReSTIRSettings
from restir_gi.core.restir.gbuffer import trace_gbuffer
from restir_gi.core.restir.temporal import reproject
from restir_gi.core.scene import LIGHT_POINT
from support.scenes import Builder, cornell_box, look_at, quad
from support.scenes import EYE, TARGET, inside_box, sharp


def project_pixel(camera, width, height, p):
    """Pixel (x, y), y = 0 at the bottom, where a perspective camera with the
    default horizontal sensor fit images the points p: written out from the
    pinhole model, independently of core.camera.projection."""
    m = np.asarray(camera.to_world, np.float64)
    axes = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)
    local = (np.asarray(p, np.float64) - m[:3, 3]) @ axes
    depth = -local[:, 2]
    scale = camera.lens / camera.sensor_width * max(width, height)
    fx = local[:, 0] / depth * scale + 0.5 * width
    fy = local[:, 1] / depth * scale + 0.5 * height
    return np.floor(fx).astype(int), np.floor(fy).astype(int), depth


def frame_gbuffer(ctx, frame=1):
    return trace_gbuffer(ctx, 0, frame, PixelFilter(0.0))


# --- (1) a small camera move ------------------------------------------------------------

def test01_small_camera_move_finds_history():
    scene = inside_box(24, 24)
    ctx = RenderContext.build(scene)
    try:
        restir = ReSTIRGI()
        settings = ReSTIRSettings(seed=1)
        first = restir.render_frame(ctx, settings, 0)
        assert first.history_found == 0.0
        cam_a = scene.camera
        history = restir.history
        # About half a pixel sideways and a little closer.
        scene.camera = dataclasses.replace(cam_a, to_world=look_at(EYE + [0.04, 0.1, 0.02], TARGET + [0.03, 0, 0]))
        gb = frame_gbuffer(ctx)
        prev = reproject(scene, gb, history)
        found = prev[gb.index] >= 0
        assert found.mean() > 0.9, found.mean()

        # The previous pixel is where the visible point projects in camera A ...
        pix = gb.index[found]
        q = prev[pix]
        x, y, _ = project_pixel(cam_a, 24, 24, gb.p[pix])
        assert np.array_equal(q, y * 24 + x)
        # ... and last frame's visible point there is the same surface, nearby
        # (within two pixel footprints at that depth).
        footprint = gb.depth[pix] * cam_a.sensor_width / cam_a.lens / 24
        gap = np.linalg.norm(history.p[q] - gb.p[pix], axis=1)
        assert (gap < 2.0 * footprint).mean() > 0.95

        # Driving the whole frame gives the same fraction.
        second = restir.render_frame(ctx, settings, 1)
        assert second.history_found == pytest.approx(found.mean())
    finally:
        ctx.close()


def test02_camera_pan_reveals_pixels_without_history():
    """Pixels whose point lay outside the previous image have no history."""
    scene = card_scene(0.0, width=24, height=24)
    ctx = RenderContext.build(scene)
    try:
        restir = ReSTIRGI()
        restir.render_frame(ctx, ReSTIRSettings(seed=2), 0)
        cam_a = scene.camera
        scene.camera = dataclasses.replace(cam_a, to_world=look_at(EYE, TARGET + [0.5, 0, 0]))
        gb = frame_gbuffer(ctx)
        assert gb.valid.all()
        prev = reproject(scene, gb, restir.history)
        x, y, depth = project_pixel(cam_a, 24, 24, gb.p[gb.index])
        outside = (x < 0) | (x >= 24) | (y < 0) | (y >= 24)
        assert outside.sum() >= 2 * 24                      # a few new columns
        assert (prev[gb.index[outside]] == -1).all()
        assert (prev[gb.index[~outside]] >= 0).mean() > 0.85
    finally:
        ctx.close()


# --- (2) disocclusion and object motion ------------------------------------------------

def card_scene(card_x, motion=False, width=32, height=32):
    """A wall at y = 1 and a square card (0.8 wide) at y = -0.5 in front of it,
    centred at x = card_x; object 0 is the wall, object 1 the card. With
    motion, the scene carries the objects' keys and transforms."""
    b = Builder()
    b.add(*quad((-3, 1, -2), (6, 0, 0), (0, 0, 6)), 0)
    b.add(*quad((card_x - 0.4, -0.5, 0.6), (0.8, 0, 0), (0, 0, 0.8)), 0)
    v, t, m = b.arrays()
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": (0, -2, 2), "power": (200,) * 3}])
    cam = Camera(to_world=look_at(EYE, TARGET), lens=50.0, sensor_width=36.0)
    scene = make_scene(v, t, m, Materials.from_list([{"base_color": (0.7, 0.7, 0.7)}]), lights, cam,
                       object_ids=np.array([0, 0, 1, 1]), width=width, height=height, filter_width=0.0)
    if motion:
        card = np.eye(4)
        card[0, 3] = card_x
        scene.object_keys = ["wall", "card"]
        scene.object_matrices = np.stack([np.eye(4), card])
    return scene


def two_frames(motion):
    """History of the card at x = -0.5, then the G-buffer and reprojection with
    the card moved to x = +0.5 (further than its width)."""
    s0 = card_scene(-0.5, motion)
    ctx0 = RenderContext.build(s0)
    restir = ReSTIRGI()
    try:
        restir.render_frame(ctx0, ReSTIRSettings(seed=3), 0)
        gb0 = frame_gbuffer(ctx0, 0)
    finally:
        ctx0.close()
    s1 = card_scene(0.5, motion)
    ctx1 = RenderContext.build(s1)
    try:
        gb1 = frame_gbuffer(ctx1)
        prev = reproject(s1, gb1, restir.history)
        result = restir.render_frame(ctx1, ReSTIRSettings(seed=3), 1)
    finally:
        ctx1.close()
    return gb0, gb1, prev, result


def test03_disoccluded_pixels_are_rejected():
    """Without object motion: wall pixels the card uncovered, and the card's
    new pixels, have no history; the wall seen in both frames keeps it."""
    gb0, gb1, prev, _ = two_frames(motion=False)
    card0 = gb0.object_id == 1
    card1 = gb1.object_id == 1
    wall1 = gb1.object_id == 0
    uncovered = card0 & wall1
    assert uncovered.sum() >= 30 and card1.sum() >= 30
    assert (prev[uncovered] == -1).all()
    assert (prev[card1 & ~card0] == -1).all()
    stable = wall1 & (gb0.object_id == 0)
    assert (prev[stable] >= 0).mean() > 0.98


def test04_moving_object_finds_its_history():
    """With the objects' transforms, the card's pixels are carried back to where
    the card was and find their history; the uncovered wall still does not."""
    gb0, gb1, prev, result = two_frames(motion=True)
    card1 = gb1.object_id == 1
    assert (prev[card1] >= 0).mean() > 0.9
    # The history found lies on the card, at the same point of the card.
    q = prev[card1 & (prev >= 0)]
    assert (gb0.object_id[q] == 1).all()
    rows = card1 & (prev >= 0)
    moved_back = gb1.p[rows] - np.float32([1.0, 0, 0])
    footprint = gb1.depth[rows] * 36.0 / 50.0 / 32
    assert (np.linalg.norm(gb0.p[q] - moved_back, axis=1) < 2 * footprint).all()
    uncovered = (gb0.object_id == 1) & (gb1.object_id == 0)
    assert (prev[uncovered] == -1).all()
    assert result.history_found == pytest.approx((prev[gb1.valid] >= 0).mean())


def test04b_samples_and_their_owners_ride_with_the_moved_object():
    """Stored sample points on the card (the wall's light bounced off its
    back) move with the card (here 1 along x), and so do the points they
    were drawn from (history.owners), whatever object those lie on; samples
    elsewhere keep theirs, also on the card's own pixels; the G-buffer
    history stays; without object transforms nothing moves."""
    from restir_gi.core.restir.temporal import carry_with_objects
    s0 = card_scene(-0.5, motion=True)
    ctx0 = RenderContext.build(s0)
    restir = ReSTIRGI()
    try:
        for f in range(3):
            restir.render_frame(ctx0, ReSTIRSettings(seed=4, max_bounces=2), f)
    finally:
        ctx0.close()
    h = restir.history
    before = [(r.x2.copy(), r.n2.copy(), r.prim2.copy()) for r in (h.temporal, h.spatial)]
    p_before = h.p.copy()
    assert carry_with_objects(card_scene(-0.5, motion=False), h) == 0      # no transforms: no motion
    assert h.owners() is h.p and h.owners(spatial=True) is h.p
    moved = carry_with_objects(card_scene(0.5, motion=True), h)
    assert moved > 0
    card_px = h.object_id == 1
    for k, (r, (x2, n2, prim2)) in enumerate(zip((h.temporal, h.spatial), before)):
        on_card = (prim2 >= 2)                      # triangles 2 and 3 are the card's
        assert on_card.sum() >= 10
        assert np.allclose(r.x2[on_card] - x2[on_card], [1.0, 0, 0], atol=1e-5)
        assert np.array_equal(r.x2[~on_card], x2[~on_card])
        assert np.allclose(r.n2, n2, atol=1e-6)     # a translation turns no normal
        owners = h.owners(spatial=bool(k))
        assert np.allclose(owners[on_card] - p_before[on_card], [1.0, 0, 0], atol=1e-5)
        assert np.array_equal(owners[~on_card], p_before[~on_card])
        assert (card_px & ~on_card).sum() >= 10     # the card's own pixels, samples on the wall
    assert np.array_equal(h.p, p_before)


# --- (3) resolution change ------------------------------------------------------------

def test05_resolution_change_resets():
    scene = inside_box(24, 24)
    ctx = RenderContext.build(scene)
    try:
        restir = ReSTIRGI()
        settings = ReSTIRSettings(seed=4)
        restir.render_frame(ctx, settings, 0)
        assert restir.render_frame(ctx, settings, 1).history_found > 0.9
        big = restir.nbytes
        scene.width, scene.height = 16, 12
        r = restir.render_frame(ctx, settings, 2)
        assert r.history_found == 0.0
        assert r.color.shape == (16 * 12, 3)
        assert restir.frames == 1
        assert (restir.history.width, restir.history.height) == (16, 12)
        assert len(restir.history.temporal) == 16 * 12
        assert restir.nbytes == pytest.approx(big * (16 * 12) / (24 * 24), rel=1e-6)
        assert restir.render_frame(ctx, settings, 3).history_found > 0.9
    finally:
        ctx.close()


# --- (4) validation: a light switched off ---------------------------------------------

def lights_off(scene):
    lights = dataclasses.replace(scene.lights, power=np.zeros_like(scene.lights.power))
    return dataclasses.replace(scene, lights=lights)


def indirect_after_switch_off(interval, frames_lit=9):
    """Mean indirect radiance before the switch, and for each frame after it."""
    scene = sharp(cornell_box("area", 16, 16))
    settings = ReSTIRSettings(seed=5, validation_interval=interval)
    restir = ReSTIRGI()
    ctx = RenderContext.build(scene)
    try:
        for f in range(frames_lit):
            lit = restir.render_frame(ctx, settings, f)
    finally:
        ctx.close()
    ctx = RenderContext.build(lights_off(scene))
    after = []
    try:
        for f in range(frames_lit, frames_lit + max(interval, 4) + 1):
            r = restir.render_frame(ctx, settings, f)
            after.append((float(r.indirect.mean()), float(np.abs(r.indirect).max()), float(r.direct.max())))
    finally:
        ctx.close()
    return float(lit.indirect.mean()), after


def test06_validation_removes_a_switched_off_light():
    """With validation every 4 frames, the stale indirect light of a switched-off
    light is gone everywhere within validation_interval + 1 frames; the frames
    before the validation show that it was still there (history persists)."""
    interval = 4
    before, after = indirect_after_switch_off(interval)
    assert before > 0.05
    assert all(d == 0 for _, _, d in after)             # direct light is gone at once
    assert after[0][0] > 0.2 * before                    # stale samples are reused ...
    assert after[interval][1] <= 1e-4 * before           # ... until validated, everywhere


def test07_without_validation_the_light_persists():
    """Same switch with validation off: the stale light is still there after
    the same number of frames, so it is validation that removes it."""
    before, after = indirect_after_switch_off(0)
    assert after[4][0] > 0.2 * before, (before, after)


# --- (5) bounded state -------------------------------------------------------------------

def test08_memory_stays_flat():
    scene = sharp(cornell_box("area", 12, 12))
    ctx = RenderContext.build(scene)
    try:
        restir = ReSTIRGI()
        settings = ReSTIRSettings(seed=6, validation_interval=2)
        sizes = []
        for f in range(30):
            restir.render_frame(ctx, settings, f)
            sizes.append(restir.nbytes)
    finally:
        ctx.close()
    assert sizes[0] > 0
    assert all(s == sizes[0] for s in sizes), sizes


@pytest.mark.parametrize("mode", [BIASED, UNBIASED])
def test09_temporal_M_is_capped(mode):
    """The temporal reservoir's M never exceeds temporal_M_cap + samples, and
    reaches it on a static view."""
    scene = sharp(cornell_box("area", 12, 12))
    ctx = RenderContext.build(scene)
    cap, samples = 5.0, 2
    try:
        restir = ReSTIRGI()
        settings = ReSTIRSettings(mode=mode, seed=7, samples=samples, temporal_M_cap=cap)
        top = []
        for f in range(10):
            restir.render_frame(ctx, settings, f)
            top.append(float(restir.history.temporal.M.max()))
    finally:
        ctx.close()
    assert max(top) <= cap + samples, top
    assert top[-1] == cap + samples, top


def lit_history(size, settings, frames):
    """A ReSTIRGI after ``frames`` frames of the lit box, and the box."""
    scene = sharp(cornell_box("area", size, size))
    restir = ReSTIRGI()
    ctx = RenderContext.build(scene)
    try:
        for f in range(frames):
            restir.render_frame(ctx, settings, f)
    finally:
        ctx.close()
    return restir, scene


def test10_validation_is_skipped_while_nothing_changes():
    """Re-tracing stored paths in an unchanged scene cannot change them, so
    validation only runs after the lighting changed (here: once, after the
    light is switched off), and it runs by the next interval."""
    settings = ReSTIRSettings(seed=3, validation_interval=2, max_bounces=2)
    restir, scene = lit_history(12, settings, 7)
    assert restir.validations == 0
    ctx = RenderContext.build(lights_off(scene))
    try:
        restir.render_frame(ctx, settings, 7)          # frame count 7: not a validation frame
        assert restir.validations == 0
        for f in range(8, 14):
            restir.render_frame(ctx, settings, f)
        assert restir.validations == 1
    finally:
        ctx.close()


def test11_validation_traces_shared_samples_once():
    """Temporal and spatial reservoirs share many samples: validating both in
    one call drops exactly what two calls drop, with fewer rays."""
    from restir_gi.core.restir.validation import validate
    restir, scene = lit_history(16, ReSTIRSettings(seed=8, validation_interval=0, max_bounces=2), 6)
    ctx = RenderContext.build(lights_off(scene))
    try:
        h = restir.history
        apart = [h.temporal.copy(), h.spatial.copy()]
        together = [h.temporal.copy(), h.spatial.copy()]
        rays0 = ctx.accel.rays_traced
        dropped_apart = validate(ctx, apart[0], 2) + validate(ctx, apart[1], 2)
        rays1 = ctx.accel.rays_traced
        dropped_together = validate(ctx, together, 2)
        rays2 = ctx.accel.rays_traced
    finally:
        ctx.close()
    assert dropped_apart == dropped_together > 0
    for a, b in zip(apart, together):
        assert np.array_equal(a.M, b.M)
    shared = np.intersect1d(h.temporal.seed[h.temporal.prim2 >= 0], h.spatial.seed[h.spatial.prim2 >= 0])
    assert len(shared) > 0
    assert rays2 - rays1 < rays1 - rays0


@pytest.mark.slow
def test10_unbiased_merge_of_several_initial_samples_keeps_the_mean():
    """A frame of several initial samples (settings.samples) streams them
    into one reservoir of M candidates; the unbiased merge with the history
    must weigh it by W = w_sum / (M p_hat), not count it M times (indirect
    light 63 % too bright with two samples before)."""
    from restir_gi.core import RenderSettings, render_frame
    from restir_gi.core.util.vectors import luminance
    from support.restir_reference import assert_same_mean
    SIZE = 12
    ctx = RenderContext.build(sharp(cornell_box("area", SIZE, SIZE)))
    try:
        film = render_frame(ctx, RenderSettings(samples=512, max_bounces=3, seed=0))
        ref = (luminance(film.mean().reshape(-1, 3)).astype(np.float64),
               film.variance_of_mean().reshape(-1).astype(np.float64))
        out = []
        for r in range(48):
            restir = ReSTIRGI()
            settings = ReSTIRSettings(mode=UNBIASED, seed=40 + r, max_bounces=3, samples=2, spatial=False)
            for f in range(3):
                result = restir.render_frame(ctx, settings, f)
            out.append(luminance(result.color))
        assert_same_mean(np.stack(out).astype(np.float64), ref, "two initial samples a frame, unbiased")
    finally:
        ctx.close()


def test12_object_motions_of_many_objects():
    """_object_motions compares every object's matrix in one pass: the
    objects that moved (not new ones, not those scaled to nothing) and their
    current -> last frame matrices, as one comparison per object finds."""
    from types import SimpleNamespace

    from restir_gi.core.restir.temporal import _object_motions
    rng = np.random.default_rng(4)
    n = 300
    prev = np.tile(np.eye(4), (n, 1, 1))
    prev[:, :3, :3] += 0.3 * rng.normal(size=(n, 3, 3))
    prev[:, :3, 3] = rng.normal(size=(n, 3))
    cur = prev.copy()
    moving = rng.choice(n, 40, replace=False)
    cur[moving, :3, 3] += rng.normal(size=(40, 3))
    cur[moving[0], :3, :3] = 0.0                        # scaled to nothing: no motion to follow
    cur[moving[1], :3, 3] = prev[moving[1], :3, 3] + 1e-9     # within tolerance: still
    keys = [("obj", i) for i in range(n)]
    order = rng.permutation(n)                          # last frame listed them in another order
    history = SimpleNamespace(object_keys=[keys[i] for i in order] + [("gone", 0)],
                              object_matrices=np.concatenate([prev[order], np.eye(4)[None]]))
    scene = SimpleNamespace(object_keys=keys + [("new", 0)], object_matrices=np.concatenate([cur, np.eye(4)[None]]))
    got = _object_motions(scene, history)
    where = {k: j for j, k in enumerate(history.object_keys)}
    expected = {}
    for i in range(n):
        j = where[keys[i]]
        if not np.allclose(cur[i], history.object_matrices[j], atol=1e-7) and np.linalg.det(cur[i]) != 0:
            expected[i] = (j, history.object_matrices[j] @ np.linalg.inv(cur[i]))
    assert sorted(got) == sorted(expected) and len(got) == 38
    for i, (j, m) in expected.items():
        assert got[i][0] == j
        np.testing.assert_allclose(got[i][1], m, atol=1e-9)
