"""Ghosts in the running means on a moving view (core/restir/ghosts.py): a
pixel keeps the history of the surfaces its footprint covers now, not of one
that an edge swept away, and on edges no more frames than the parallax lets
stay in place."""

import dataclasses

import numpy as np

from restir_gi.core import RenderContext, RenderSettings, render_frame
from restir_gi.core.restir import ReSTIRGI, ReSTIRSettings
from restir_gi.core.restir import accumulation
from restir_gi.core.restir.ghosts import (ALBEDO_TOLERANCE, SurfaceRange, history_share, kept_frames, parallax,
                                          surface_range)
from support.scenes import cornell_box, look_at


def test01_surface_range_is_the_3x3_min_and_max():
    w, h = 6, 4
    albedo = np.full((h, w, 3), 0.2, np.float32)
    albedo[:, 3:] = 0.8                                 # a step in albedo from column 3
    normal = np.zeros((h, w, 3), np.float32)
    normal[..., 2] = 1.0
    light = np.arange(w * h, dtype=np.float32)
    rng = surface_range(albedo.reshape(-1, 3), normal.reshape(-1, 3), light, w, h)
    lo, hi = rng.lo.reshape(h, w, 7), rng.hi.reshape(h, w, 7)
    assert np.allclose(lo[:, :3, 0], 0.2) and np.allclose(lo[:, 4:, 0], 0.8)
    assert np.allclose(hi[:, :2, 0], 0.2) and np.allclose(hi[:, 2:, 0], 0.8)
    assert np.allclose(lo[..., 5], 1.0) and np.allclose(hi[..., 5], 1.0)
    assert lo[1, 1, 6] == 0 and hi[1, 1, 6] == 2 * w + 2      # light: the corners of the 3x3


def _range(lo_albedo, hi_albedo, light_lo=0.0, light_hi=0.0, n=1):
    lo = np.tile(np.array([lo_albedo] * 3 + [0, 0, 1, light_lo], np.float32), (n, 1))
    hi = np.tile(np.array([hi_albedo] * 3 + [0, 0, 1, light_hi], np.float32), (n, 1))
    return SurfaceRange(lo, hi)


def test02_history_share_falls_to_zero_beyond_the_tolerance():
    rng = _range(0.3, 0.5, n=4)
    values = np.array([[a] * 3 + [0, 0, 1] for a in (0.4, 0.5 + ALBEDO_TOLERANCE / 2, 0.3 - ALBEDO_TOLERANCE,
                                                      0.9)], np.float32)
    share = history_share(values, rng)
    assert np.allclose(share, [1.0, 0.5, 0.0, 0.0], atol=1e-5)
    tilted = values.copy()
    tilted[0, 3:6] = [0.0, 0.6, 0.8]                    # the right albedo, another surface's normal
    assert history_share(tilted, rng)[0] == 0.0


def test03_light_inside_its_range_keeps_the_history():
    """A history whose light lies in this frame's 3x3 light range shows what
    the pixel shows now, whatever its albedo says (a lamp's surface, a
    texture's fine detail): it is kept."""
    rng = _range(0.3, 0.5, light_lo=1.0, light_hi=2.0, n=2)
    values = np.array([[0.9] * 3 + [0, 0, 1]] * 2, np.float32)
    share = history_share(values, rng, light=np.array([1.5, 5.0], np.float32))
    assert list(share) == [1.0, 0.0]


def test04_parallax_is_the_motion_difference_to_the_neighbours():
    w, h = 8, 5
    shift = np.zeros((h, w, 2), np.float32)
    shift[..., 0] = 0.3                                 # everything moves 0.3 px
    shift[:, 5:, 0] = 1.3                               # the right part 1 px more
    p = parallax(shift.reshape(-1, 2), w).reshape(h, w)
    assert np.allclose(p[:, 4:6], 1.0) and np.allclose(p[:, :4], 0.0) and np.allclose(p[:, 6:], 0.0)
    shift[2, -1, 0] = 5.0                               # a row's last pixel is no neighbour of the next row's first
    p = parallax(shift.reshape(-1, 2), w).reshape(h, w)
    assert p[3, 0] == 0.0 and p[1, 0] == 0.0 and np.isclose(p[2, -2], 3.7) and np.isclose(p[3, -1], 3.7)
    shift[0, 0] = np.nan                                # a point the projection could not place
    assert np.isfinite(parallax(shift.reshape(-1, 2), w)).all()


def test05_edges_keep_fewer_frames_the_faster_they_move():
    rng = _range(0.0, 1.0, n=3)
    rng.edges = np.array([True, True, False])
    rng.parallax = np.array([0.01, 1.0, 1.0], np.float32)
    frames = np.full(3, 16.0, np.float32)
    values = np.array([[0.5] * 3 + [0, 0, 1]] * 3, np.float32)
    out = kept_frames(frames, values, rng)
    assert out[0] == 16.0 and out[1] < 4.0 and out[2] == 16.0


def _pan(ghosts_on, monkeypatch, frames=24, size=40):
    """Accumulated albedo of a camera sliding sideways past the Cornell box's
    boxes, against a fresh render's of the last pose: mean squared error."""
    if not ghosts_on:
        monkeypatch.setattr(accumulation, "kept_frames", lambda f, *a, **k: f)
    restir = ReSTIRGI()
    scene = cornell_box("area", size, size)
    scene.filter_width = 1.5
    for f in range(frames):
        eye = np.array([-0.25 + 0.02 * f, -3.9, 1.0])
        scene.camera = dataclasses.replace(scene.camera, to_world=look_at(eye, eye + [0, 3.9, 0]))
        ctx = RenderContext.build(scene)
        try:
            out = restir.render_frame(ctx, ReSTIRSettings(seed=7, max_bounces=1), f)
            if f == frames - 1:
                ref = render_frame(ctx, RenderSettings(samples=256, max_bounces=1, seed=0)).aov("albedo", 3)
        finally:
            ctx.close()
    monkeypatch.undo()
    return float(((out.albedo.reshape(size, size, 3) - ref) ** 2).mean())


def test06_a_sliding_view_leaves_no_trails_behind_its_edges(monkeypatch):
    """With the camera sliding, the boxes' silhouettes sweep over the back
    wall. Without the test the pixels they leave keep the box's albedo in
    their running means for up to 16 frames: the accumulated albedo trails
    the edges (its error several times a fresh render's noise)."""
    with_test = _pan(True, monkeypatch)
    without = _pan(False, monkeypatch)
    print(f"albedo MSE: {with_test:.5f} with the test, {without:.5f} without")
    assert with_test < 0.5 * without
