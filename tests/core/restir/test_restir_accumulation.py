"""Reprojected accumulation of shaded frames (core/restir/accumulation.py) and
the estimators built on it: stills that average their warm-up frames, and
several frames of resampling per animation frame (core/render.py).

The pixel filter is on here (Blackman-Harris 1.5 px, the Blender default): the
visible point of a pixel moves every frame, which is what accumulation is for.
"""

import dataclasses
import math

import numpy as np
import pytest

from restir_gi.core import Materials, RenderContext, RenderSettings, render_frame
from restir_gi.core.camera.projection import PixelFilter
from restir_gi.core.render import render_restir, settle_frames, still_frame_weight
from restir_gi.core.restir import BIASED, UNBIASED, ReSTIRGI, ReSTIRSettings
from restir_gi.core.restir.accumulation import LIGHT_FRAMES, STILL, FrameValues, accumulate
from restir_gi.core.restir.reprojection import Footprint, previous_pixels
from restir_gi.core.restir.gbuffer import trace_gbuffer
from restir_gi.core.util.vectors import luminance
from support.scenes import cornell_box, look_at
from support.restir_reference import Reference, assert_same_mean

SIZE = 16
MAX_BOUNCES = 4


def filtered_box(width=SIZE, height=SIZE):
    scene = cornell_box("area", width, height)
    scene.filter_width = 1.5
    return scene


@pytest.fixture(scope="module")
def ctx():
    c = RenderContext.build(filtered_box())
    yield c
    c.close()


@pytest.fixture(scope="module")
def reference(ctx):
    return Reference(render_frame(ctx, RenderSettings(samples=1024, max_bounces=MAX_BOUNCES, seed=0)))


# --- (1) which pixel a pixel was -------------------------------------------------------

def test01_still_camera_maps_every_pixel_onto_itself():
    """Jittered visible points, misses included: a still view keeps every pixel's history."""
    scene = filtered_box(24, 24)
    ctx = RenderContext.build(scene)
    try:
        restir = ReSTIRGI()
        restir.render_frame(ctx, ReSTIRSettings(seed=1), 0)
        gb = trace_gbuffer(ctx, 0, 1, PixelFilter(1.5))
        assert (~gb.valid).sum() > 20 and gb.valid.sum() > 200     # both kinds of pixel
        prev = previous_pixels(scene, gb, restir.history, still_scene=True).nearest()
        assert (prev == np.arange(24 * 24)).all()
        # The same without knowing the scene is still: the 3x3 test keeps nearly all.
        assert (previous_pixels(scene, gb, restir.history).nearest() == np.arange(24 * 24)).mean() > 0.95
    finally:
        ctx.close()


def test02_camera_move_maps_pixels_by_the_motion():
    """A sideways camera move of two pixels' worth at the back wall's depth:
    back-wall pixels find the pixel two columns over."""
    scene = filtered_box(32, 32)
    ctx = RenderContext.build(scene)
    try:
        restir = ReSTIRGI()
        restir.render_frame(ctx, ReSTIRSettings(seed=2), 0)
        eye, target = np.array([0.0, -3.9, 1.0]), np.array([0.0, 0.0, 1.0])
        # Pixel size at the back wall (4.9 m away): sensor 36 mm / lens 50 mm over 32 pixels.
        step = 2 * 4.9 * 36.0 / 50.0 / 32
        scene.camera = dataclasses.replace(scene.camera, to_world=look_at(eye + [step, 0, 0], target + [step, 0, 0]))
        gb = trace_gbuffer(ctx, 0, 1, PixelFilter(1.5))
        prev = previous_pixels(scene, gb, restir.history).nearest()
        pix = np.arange(32 * 32)
        back = gb.valid & (np.abs(gb.p[:, 1] - 1.0) < 1e-3) & (pix % 32 < 28)
        assert back.sum() > 100
        assert (prev[back] == pix[back] + 2).mean() > 0.95
    finally:
        ctx.close()


def test03_disoccluded_pixels_start_over():
    """Moving the tall box away uncovers the wall behind it: those pixels have
    no history in their 3x3 neighbourhood and start over; the rest keep theirs."""
    scene = filtered_box(32, 32)
    ctx = RenderContext.build(scene)
    restir = ReSTIRGI()
    try:
        restir.render_frame(ctx, ReSTIRSettings(seed=3), 0)
        before = restir.history.object_id.copy(), restir.history.depth.copy()
    finally:
        ctx.close()
    moved = dataclasses.replace(scene, vertices=scene.vertices.copy())
    tall = (scene.vertices[:, 0] < -0.04) & (scene.vertices[:, 0] > -0.61) & (scene.vertices[:, 1] > -0.11) \
        & (scene.vertices[:, 1] < 0.51) & (scene.vertices[:, 2] > -0.01)
    moved.vertices[tall, 2] -= 5.0      # sunk through the floor
    ctx = RenderContext.build(moved)
    try:
        gb = trace_gbuffer(ctx, 0, 1, PixelFilter(1.5))
        prev = previous_pixels(moved, gb, restir.history).nearest()
    finally:
        ctx.close()
    depth0 = before[1]
    uncovered = gb.valid & (gb.depth > 1.2 * depth0) & (depth0 < 1e9)
    # Pixels 2+ pixels inside the old silhouette: nothing like them nearby last frame.
    inner = uncovered.reshape(32, 32)
    core = inner.copy()
    for dy in (-2, -1, 0, 1, 2):
        for dx in (-2, -1, 0, 1, 2):
            core &= np.roll(np.roll(inner, dy, 0), dx, 1)
    assert core.sum() >= 4
    assert (prev[core.reshape(-1)] == -1).all()
    unchanged = gb.valid & (np.abs(gb.depth - depth0) < 0.01 * depth0)
    assert (prev[unchanged] >= 0).mean() > 0.98


def test04_running_mean_and_its_cap():
    """accumulate() is the plain mean until the cap, then an exponential average."""
    n = 5
    acc = None
    values = [np.full((n, 3), float(v), np.float32) for v in (1, 2, 3, 4, 5, 6)]
    same = Footprint.none(n)
    same.taps[:, 0], same.weights[:, 0] = np.arange(n), 1.0
    for k, v in enumerate(values):
        acc = accumulate(acc, same if acc is not None else None, FrameValues(v, v, v, v), cap=4)
        if k < 4:
            assert np.allclose(acc.direct, np.mean([x[0, 0] for x in values[:k + 1]]))
    assert np.allclose(acc.count, 4)
    # After the cap, each new frame has weight 1/4.
    assert np.allclose(acc.direct, 0.75 * (0.75 * 2.5 + 0.25 * 5) + 0.25 * 6)
    lost = accumulate(acc, Footprint.none(n), FrameValues(*[values[0]] * 4), cap=4)
    assert np.allclose(lost.direct, 1.0) and np.allclose(lost.count, 1)
    # Half a pixel over: the mean of two pixels' histories.
    acc.data[:, 0:3] = np.arange(n, dtype=np.float32)[:, None]     # (direct is light + seen: a sum)
    half = Footprint.none(n)
    half.taps[:, 0], half.taps[:, 1] = np.arange(n), np.minimum(np.arange(n) + 1, n - 1)
    half.weights[:, :2] = 0.5
    mid = accumulate(acc, half, FrameValues(*[values[0]] * 4), cap=2)
    assert np.allclose(mid.direct[:-1, 0], 0.5 * (np.arange(n - 1) + 0.5) + 0.5)
    # Weighted frames (an unbiased still's first ones): the weighted mean, the
    # count summing the weights.
    acc, weights = None, (0.25, 0.5, 1.0, 1.0)
    for k, (v, wt) in enumerate(zip(values, weights)):
        acc = accumulate(acc, same if acc is not None else None, FrameValues(v, v, v, v, weight=wt), cap=STILL)
        expect = np.dot(weights[:k + 1], [x[0, 0] for x in values[:k + 1]]) / sum(weights[:k + 1])
        assert np.allclose(acc.direct, expect) and np.allclose(acc.count, sum(weights[:k + 1]))


# --- (2) estimators ----------------------------------------------------------------------

@pytest.mark.slow
def test05_unbiased_still_matches_path_tracing(ctx, reference):
    """A still in the unbiased mode (the mean of its warm-up frames, the first
    ones weighted less) has the path tracer's mean, with the filter on."""
    runs = []
    for r in range(40):
        out = render_restir(ctx, ReSTIRGI(), ReSTIRSettings(mode=UNBIASED, seed=2000 + r, max_bounces=MAX_BOUNCES),
                            0, frames=8, fresh=True)
        runs.append(luminance(out.color))
    assert_same_mean(np.stack(runs).astype(np.float64), reference, "unbiased still, 8 frames")


@pytest.mark.slow
def test06_several_frames_per_frame_match_path_tracing(ctx, reference):
    """Animation frames after the first, with three frames of resampling each
    (samples = 3), keep the path tracer's mean in the unbiased mode."""
    runs = []
    for r in range(40):
        restir = ReSTIRGI()
        settings = ReSTIRSettings(mode=UNBIASED, seed=3000 + r, max_bounces=MAX_BOUNCES, accumulate=4)
        render_restir(ctx, restir, settings, 0, frames=4, fresh=True)
        out = render_restir(ctx, restir, settings, 1, frames=3)
        runs.append(luminance(out.color))
    assert_same_mean(np.stack(runs).astype(np.float64), reference, "unbiased, 3 frames per frame")


@pytest.mark.slow
@pytest.mark.parametrize("mode", [BIASED, UNBIASED])
def test07_still_error_falls_as_warmup_grows(ctx, reference, mode):
    """The warm-up frames are not wasted: four times as many halve the error at least."""
    def mse(frames):
        errs = []
        for seed in range(3):
            out = render_restir(ctx, ReSTIRGI(), ReSTIRSettings(mode=mode, seed=seed, max_bounces=MAX_BOUNCES),
                                0, frames=frames, fresh=True)
            errs.append(float(((luminance(out.color) - reference.mean) ** 2).mean()))
        return float(np.mean(errs))
    short, long = mse(8), mse(32)
    print(f"{mode}: still MSE {short:.5f} (8 frames) -> {long:.5f} (32 frames)")
    assert long < 0.5 * short


def test08_settle_frames_and_still_weights():
    assert settle_frames(1) == 0 and settle_frames(16) == 4 and settle_frames(400) == 8
    assert STILL > 1e6
    w = [still_frame_weight(i) for i in range(8)]
    assert w[0] > 0 and all(a <= b for a, b in zip(w, w[1:])) and w[-1] == 1.0


def test09_accumulation_off_gives_the_frame():
    """accumulate=1: each frame is its own image (the viewport averages by itself)."""
    scene = filtered_box(8, 8)
    ctx = RenderContext.build(scene)
    try:
        a, b = ReSTIRGI(), ReSTIRGI()
        for f in range(3):
            ra = a.render_frame(ctx, ReSTIRSettings(seed=9, accumulate=1), f)
            rb = b.render_frame(ctx, ReSTIRSettings(seed=9, accumulate=16), f)
        assert a.history.accumulation is None
        assert np.allclose(b.history.accumulation.count, 3)
        assert not np.allclose(ra.color, rb.color)
        assert math.isfinite(float(rb.color.sum()))
    finally:
        ctx.close()


def glossy_box():
    """The Cornell box with rough glossy surfaces: white walls a dielectric
    with a specular layer, the left wall a metal (roughness 0.3 both)."""
    scene = filtered_box()
    mats = [{"base_color": (0.8, 0.8, 0.8), "specular": 0.5, "roughness": 0.3},
            {"base_color": (0.9, 0.3, 0.2), "metallic": 1.0, "roughness": 0.3},
            {"base_color": (0.1, 0.8, 0.1)},
            {"base_color": (0, 0, 0), "emission": (15.0,) * 3}]
    return dataclasses.replace(scene, materials=Materials.from_list(mats))


@pytest.mark.slow
def test10_glossy_unbiased_matches_path_tracing():
    """Glossy lobes take their indirect light from each frame's own sample and
    the diffuse lobe from the reservoirs: together still the path tracer's mean."""
    ctx = RenderContext.build(glossy_box())
    try:
        ref = Reference(render_frame(ctx, RenderSettings(samples=1024, max_bounces=MAX_BOUNCES, seed=0)))
        runs = []
        for r in range(40):
            out = render_restir(ctx, ReSTIRGI(), ReSTIRSettings(mode=UNBIASED, seed=4000 + r,
                                                                 max_bounces=MAX_BOUNCES), 0, frames=8, fresh=True)
            runs.append(luminance(out.color))
        assert_same_mean(np.stack(runs).astype(np.float64), ref, "glossy box, unbiased still")
    finally:
        ctx.close()


def test11_catmull_rom_history_reads():
    """The 4x4 window's weights sum to one, interpolate (t = 0 reads the pixel
    itself), reproduce a linear ramp exactly, and the read is clipped to the
    inner 2x2 taps' range (no overshoot at a sharp edge)."""
    from restir_gi.core.restir.reprojection import TAPS, _catmull_rom
    t = np.linspace(0, 0.99, 12).astype(np.float32)
    wx = np.stack(_catmull_rom(t))
    assert np.allclose(wx.sum(axis=0), 1.0, atol=1e-6)
    assert np.allclose(np.stack(_catmull_rom(np.zeros(1, np.float32)))[:, 0], [0, 1, 0, 0])
    assert np.allclose((wx * np.arange(-1, 3)[:, None]).sum(axis=0), t, atol=1e-6)
    assert TAPS[:4] == [(0, 0), (1, 0), (0, 1), (1, 1)] and len(set(TAPS)) == 16
    # A step edge read half a pixel over: the value lies between the two sides.
    n = 1
    fp = Footprint.none(n)
    xs = [dx for dx, _dy in TAPS]
    fp.taps[0] = np.array([2 + dx for dx in xs])          # a row of pixels 1..4, edge between 2 and 3
    wts = np.stack(_catmull_rom(np.array([0.5], np.float32)))[:, 0]
    fp.weights[0] = [wts[dx + 1] * (1.0 if dy == 0 else 0.0) for dx, dy in TAPS]
    img = np.zeros((6, 3), np.float32)
    img[3:] = 10.0
    prev = accumulate(None, None, FrameValues(img, img, img, img), cap=8)
    prev.count[:] = prev.data[:, LIGHT_FRAMES] = 8
    zero = np.zeros((n, 3), np.float32)
    out = accumulate(prev, fp, FrameValues(zero, zero, zero, zero), cap=8)
    hist = out.direct[0, 0] * 8 / 7                      # undo the blend with this frame's 0
    assert 0.0 <= hist <= 10.0 and abs(hist - 5.0) < 1e-4


def test12_geometric_edges():
    """Pixels whose 3x3 neighbourhood holds another object, a miss beside a
    hit, or a depth jump are edges; the inside of a surface is not."""
    from restir_gi.core.restir.reprojection import geometric_edges
    w, h = 8, 6
    oid = np.zeros((h, w), np.int32)
    oid[:, 5:] = 1                              # a second object from column 5
    depth = np.full((h, w), 2.0, np.float32)
    depth[4:, :2] = 3.0                         # a step in depth at the bottom left
    valid = np.ones((h, w), bool)
    valid[0, 0] = False                         # a miss in a corner
    e = geometric_edges(oid.ravel(), depth.ravel(), valid.ravel(), w, h).reshape(h, w)
    assert e[:, 4:6].all() and not e[1:3, 2:4].any() and not e[:, 7].any()
    assert e[0:2, 0:2].all() and e[3, 0:3].all() and e[4:6, 1:3].all() and not e[5, 0]


def test13_edges_keep_their_coverage_on_a_moving_view(monkeypatch):
    """On a moving camera, the running means of pixels on geometric edges read
    history from every tap: an edge pixel keeps the mix of the surfaces it
    covers instead of flipping to whichever side this frame's ray hit, so
    its direct light changes less from frame to frame. (The frames an edge
    keeps under fast parallax, ghosts.EDGE_SHIFT, trade some of that for less
    lag; they are left out here, and measured by the bench.)"""
    import restir_gi.core.restir.frame as restir_module
    from restir_gi.core.restir import ghosts
    monkeypatch.setattr(ghosts, "EDGE_SHIFT", np.inf)
    from restir_gi.core.restir.reprojection import geometric_edges

    def run():
        scene = filtered_box(32, 32)
        restir = ReSTIRGI()
        out = []
        for f in range(14):
            eye = np.array([0.02 * f, -3.9, 1.0])
            scene.camera = dataclasses.replace(scene.camera, to_world=look_at(eye, eye + [0, 3.9, 0]))
            ctx = RenderContext.build(scene)
            try:
                out.append(luminance(restir.render_frame(ctx, ReSTIRSettings(seed=2, max_bounces=2), f).direct))
            finally:
                ctx.close()
        h = restir.history
        edges = geometric_edges(h.object_id, h.depth, h.valid, 32, 32)
        return np.stack(out[6:]), edges

    with_edges, edges = run()
    monkeypatch.setattr(restir_module, "geometric_edges", lambda oid, *a: np.zeros(len(oid), bool))
    without, _ = run()
    assert edges.sum() > 40
    flicker = lambda frames: np.abs(np.diff(frames, axis=0))[:, edges].mean()     # noqa: E731
    assert flicker(with_edges) < 0.85 * flicker(without)     # (0.69-0.73 over seeds)


@pytest.mark.slow
def test14_depth_of_field_still_matches_path_tracing():
    """A camera with depth of field (lens rays jittered per frame, history
    carried on a still view): the unbiased still has the path tracer's blur
    and mean, block by block."""
    scene = filtered_box()
    cam = scene.camera
    scene.camera = dataclasses.replace(cam, aperture_size=0.5, focus_distance=2.0, aperture_blades=5)
    ctx = RenderContext.build(scene)
    try:
        ref = Reference(render_frame(ctx, RenderSettings(samples=1024, max_bounces=MAX_BOUNCES, seed=0)))
        sharp = RenderContext.build(filtered_box())
        try:    # the comparison tells blur apart: the pinhole image is another one
            pinhole = Reference(render_frame(sharp, RenderSettings(samples=256, max_bounces=MAX_BOUNCES, seed=1)))
        finally:
            sharp.close()
        assert np.abs(pinhole.mean - ref.mean).max() > 0.1
        runs = []
        for r in range(24):
            out = render_restir(ctx, ReSTIRGI(), ReSTIRSettings(mode=UNBIASED, seed=5000 + r,
                                                                max_bounces=MAX_BOUNCES), 0, frames=8, fresh=True)
            runs.append(luminance(out.color))
        assert_same_mean(np.stack(runs).astype(np.float64), ref, "unbiased still, depth of field")
    finally:
        ctx.close()


def test15_a_panning_view_leaves_no_wall_over_the_sky():
    """A view panning past the end of a red wall uncovers the dark sky beside
    it, at the image's edge: pixels whose centre lay outside last frame's
    image start over. Else they took the wall's history from the taps
    clamped to the border, and the sky carried it for the running mean's 16
    frames (a translucent wall trailing the motion)."""
    from restir_gi.core import Camera, Lights, make_scene
    from restir_gi.core.scene import LIGHT_POINT
    from support.scenes import Builder, quad
    b = Builder()
    b.add(*quad((-6, -6, 0), (12, 0, 0), (0, 12, 0)), 0)                 # floor
    b.add(*quad((-4, -6, 0), (0, 12, 0), (0, 0, 6)), 1)                  # red wall, ends at y = 6
    mats = Materials.from_list([{"base_color": (0.7, 0.7, 0.7)}, {"base_color": (0.8, 0.1, 0.1)}])
    lamp = Lights.from_list([{"kind": LIGHT_POINT, "position": (0, 0, 4), "power": (800.0,) * 3}])
    eye = np.array([0.0, -9.0, 3.5])

    def scene_at(yaw_deg):
        yaw = math.radians(yaw_deg)
        target = eye + np.array([-math.sin(yaw), math.cos(yaw), -0.2])
        cam = Camera(to_world=look_at(eye, target), lens=35.0, sensor_width=36.0)
        return make_scene(*b.arrays(), mats, lamp, cam, world_color=(0.01, 0.01, 0.01), width=48, height=32)

    settings = ReSTIRSettings(seed=3, max_bounces=2)
    restir = ReSTIRGI()
    yaws = np.linspace(20.0, 45.0, 16)          # turning left, toward the wall's far end
    for f, yaw in enumerate(yaws):
        ctx = RenderContext.build(scene_at(yaw))
        try:
            result = restir.render_frame(ctx, settings, f)
        finally:
            ctx.close()
    still = ReSTIRGI()
    ctx = RenderContext.build(scene_at(yaws[-1]))
    try:
        for f in range(16):
            ref = still.render_frame(ctx, settings, 100 + f)
    finally:
        ctx.close()
    img, ref_img = result.color.reshape(32, 48, 3), ref.color.reshape(32, 48, 3)
    sky = luminance(ref_img) < 0.02
    assert sky.mean() > 0.1                    # the view shows sky beside the wall
    redness = img[..., 0] - img[..., 1]
    print(f"sky pixels {sky.mean():.2f}, their redness: mean {redness[sky].mean():.4f}, "
          f"max {redness[sky].max():.4f}; frame / still {img.mean() / ref_img.mean():.3f}")
    assert redness[sky].mean() < 0.01, redness[sky].mean()
    assert abs(img.mean() / ref_img.mean() - 1.0) < 0.05
