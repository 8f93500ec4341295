"""Spatial reuse (core/restir/spatial.py): which neighbours a pixel may reuse,
how far samples travel, that a worker's share of the rows resamples as the
whole image does, that the unbiased mode's pairwise MIS keeps the path
tracer's mean where neighbours' samples are hidden from the pixel (while the
same weights without visibility do not), the biased mode's Z, and the
smaller radius of a still view.

The first tests build G-buffers and temporal reservoirs by hand: visible
points on the plane z = 0 (1 cm a pixel, 5 m from the camera) whose samples
lie 1 m above them, the samples of the image's two halves told apart by
their radiance.
"""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from restir_gi.core import Camera, Lights, Materials, RenderContext, RenderSettings, make_scene, render_frame
from restir_gi.core.sampling import samplers
from restir_gi.core.restir import UNBIASED, ReSTIRGI, ReSTIRSettings
from restir_gi.core.restir import frame as frame_module
from restir_gi.core.restir import spatial as spatial_module
from restir_gi.core.restir.gbuffer import FrameImage
from restir_gi.core.restir.spatial import SpatialReuse, shared_terms, spatial_resample
from restir_gi.core.restir.reservoirs import Reservoirs
from restir_gi.core.restir.shift import target_at
from restir_gi.core.scene import LIGHT_POINT
from support.scenes import Builder, cornell_box, look_at, quad
from support.restir_reference import Reference, assert_same_mean, restir_runs

W, H = 48, 32
DIM, BRIGHT = 1.0, 100.0    # radiance of the left and the right half's samples


def plane_image(tilt_right=0.0, depth_right=1.0):
    """Visible points on z = 0; the right half's shading normals tilted by
    ``tilt_right`` radians about the y axis and its depths scaled."""
    pix = np.arange(W * H)
    x, y = pix % W, pix // W
    p = np.stack([x * 0.01, y * 0.01, np.zeros(len(pix))], axis=1).astype(np.float32)
    right = x >= W // 2
    n = np.tile(np.float32([0, 0, 1]), (len(pix), 1))
    n[right] = (np.sin(tilt_right), 0.0, np.cos(tilt_right))
    depth = np.where(right, 5.0 * depth_right, 5.0).astype(np.float32)
    return FrameImage(valid=np.ones(len(pix), bool), depth=depth, object_id=np.zeros(len(pix), np.int32),
                      p=p, n=n, ng=np.tile(np.float32([0, 0, 1]), (len(pix), 1)), width=W, height=H)


def samples_above(img, radiance, holders=None, height=1.0):
    """Temporal reservoirs (M 1) holding, for the pixels ``holders`` (all by
    default), a sample ``height`` m above the visible point with the given radiance
    (one per pixel), at its target (luminance x cosine 1): W = 1 / p_hat."""
    n = len(img.valid)
    res = Reservoirs.empty(n)
    rows = np.arange(n) if holders is None else np.asarray(holders)
    res.x2[rows] = img.p[rows] + np.float32([0, 0, height])
    res.ng2[rows] = res.n2[rows] = res.wo2[rows] = (0.0, 0.0, -1.0)
    res.prim2[rows] = 0
    res.lo[rows] = np.asarray(radiance, np.float32)[rows, None]
    res.seed[rows] = rows.astype(np.uint64)
    res.M[:] = 1.0
    res.W[rows] = 1.0 / res.lo[rows, 0]
    res.w_sum[rows] = 1.0
    return res


def two_halves(img):
    return samples_above(img, np.where(np.arange(W * H) % W >= W // 2, BRIGHT, DIM))


NO_RAYS = SimpleNamespace(accel=SimpleNamespace(poll=lambda: None))     # the biased pass traces none


def resample(ctx, img, temporal, biased=True, k=4, radius=16.0, rows=None, seed=3):
    seeds = samplers.path_seeds(seed, 0, np.arange(W * H), 0)
    return spatial_resample(ctx, img, temporal, seeds, SpatialReuse(k, radius, biased), rows=rows,
                            shared=shared_terms(temporal, biased))


def left_pixels_reusing_the_right(res):
    x = np.arange(W * H) % W
    return int(((x < W // 2) & (res.lo[:, 0] == BRIGHT)).sum())


def test01_neighbours_across_a_crease_are_not_reused():
    """A neighbour whose shading normal is over 25 degrees from the pixel's
    is no candidate: the left half's pixels never take the right half's
    (100x brighter) samples across a 60-degree crease, and do when the
    surface is flat (the same seeds)."""
    flat, _, _ = resample(NO_RAYS, plane_image(), two_halves(plane_image()))
    img = plane_image(tilt_right=np.radians(60.0))
    creased, _, _ = resample(NO_RAYS, img, two_halves(img))
    print(f"left pixels reusing the right half's samples: flat {left_pixels_reusing_the_right(flat)}, "
          f"creased {left_pixels_reusing_the_right(creased)}")
    assert left_pixels_reusing_the_right(flat) > 50
    assert left_pixels_reusing_the_right(creased) == 0


def test02_neighbours_across_a_depth_step_are_not_reused():
    """A neighbour whose depth differs by over 10 % of the pixel's is no
    candidate (one 5 % away still is)."""
    counts = {}
    for step in (1.05, 1.2):
        img = plane_image(depth_right=step)
        res, _, _ = resample(NO_RAYS, img, two_halves(img))
        counts[step] = left_pixels_reusing_the_right(res)
    print(f"left pixels reusing the right half's samples: {counts}")
    assert counts[1.05] > 50
    assert counts[1.2] == 0


@pytest.mark.parametrize("radius", [3.0, 6.0])
def test03_samples_travel_at_most_the_radius(radius):
    """One pixel alone holds a sample: the pixels that end up with it lie
    within the radius of it (neighbours are drawn in a disk and rounded to
    the nearest pixel centre), and with 8 neighbours several do."""
    img = plane_image()
    src = (H // 2) * W + W // 2
    res, _, _ = resample(NO_RAYS, img, samples_above(img, np.full(W * H, DIM), holders=[src]), k=8,
                         radius=radius)
    got = np.flatnonzero(res.prim2 >= 0)
    got = got[got != src]
    dist = np.hypot(got % W - src % W, got // W - src // W)
    print(f"radius {radius}: {len(got)} pixels took the sample, farthest {dist.max():.2f} px away")
    assert len(got) >= 3
    assert dist.max() <= radius + 0.5 * np.sqrt(2)
    assert np.allclose(res.x2[got], img.p[src] + np.float32([0, 0, 1]))


def far_away_ctx():
    """A RenderContext whose scene occludes nothing near the plane (one small
    triangle far below it): the unbiased pass's visibility rays all pass."""
    b = Builder()
    b.add(*quad((0, 0, -100), (0.1, 0, 0), (0, 0.1, 0)), 0)
    cam = Camera(to_world=look_at((0.2, 0.15, 5), (0.2, 0.15, 0), up=(0, 1, 0)), lens=50.0)
    return RenderContext.build(make_scene(*b.arrays(), Materials.from_list([{"base_color": (0.5,) * 3}]),
                                          Lights.empty(), cam, width=W, height=H))


@pytest.mark.parametrize("biased", [True, False])
def test04_a_share_of_the_rows_resamples_as_the_whole_image(biased):
    """Workers resample ranges of rows with neighbours from the whole image:
    two ranges give the reservoirs of one pass over the image, bit for bit."""
    ctx = far_away_ctx() if not biased else NO_RAYS
    try:
        img = plane_image(tilt_right=np.radians(10.0))
        x = np.arange(W * H) % W
        temporal = samples_above(img, 1.0 + (x * 7 % 11))
        whole, vis, _ = resample(ctx, img, temporal, biased=biased)
        m = W * H // 2 - 7
        parts = [resample(ctx, img, temporal, biased=biased, rows=r) for r in ((0, m), (m, W * H))]
    finally:
        if not biased:
            ctx.close()
    for name in Reservoirs.SAMPLE_FIELDS + ("w_sum", "M", "W"):
        joined = np.concatenate([getattr(p[0], name) for p in parts])
        assert np.array_equal(getattr(whole, name), joined), name
    if not biased:
        assert np.array_equal(vis, np.concatenate([p[1] for p in parts]))
        assert vis.mean() > 0.99      # nothing hides a sample here


def fence_scene():
    """A floor split by a thin wall 1 m high, seen from above; on the right a
    point lamp between the wall and a white panel facing it. The left
    floor's pixels reuse their right neighbours' samples on the panel
    (same normal, same depth, the panel faces them), which the wall hides
    from them: the left floor is lit only by what comes over the wall."""
    b = Builder()
    b.add(*quad((-1.5, -1.5, 0), (3, 0, 0), (0, 3, 0)), 0)                # floor
    b.add_box((-0.02, -1.5, 0), (0.02, 1.5, 1.0), 0)                      # the wall
    b.add(*quad((1.0, -1.5, 0), (0, 3, 0), (0, 0, 1.2)), 0)               # the panel, facing -x
    lamp = Lights.from_list([{"kind": LIGHT_POINT, "position": (0.5, 0, 0.6), "power": (60.0,) * 3,
                              "radius": 0.05}])
    cam = Camera(to_world=look_at((0, 0, 5), (0, 0, 0), up=(0, 1, 0)), lens=50.0, sensor_width=36.0)
    scene = make_scene(*b.arrays(), Materials.from_list([{"base_color": (0.8, 0.8, 0.8)}]), lamp, cam,
                       width=16, height=16)
    scene.filter_width = 0.0
    return scene


@pytest.fixture(scope="module")
def fence():
    ctx = RenderContext.build(fence_scene())
    ref = Reference(render_frame(ctx, RenderSettings(samples=1024, max_bounces=4, seed=0)))
    yield ctx, ref
    ctx.close()


@pytest.mark.slow
def test05_unbiased_spatial_reuse_alone_keeps_the_mean(fence):
    """Spatial reuse without temporal reuse, unbiased, where neighbours'
    samples are often hidden from the pixel: the mean of independent runs
    is the path tracer's, on the image and on blocks of pixels
    (test_restir_vs_path's z-tests)."""
    ctx, ref = fence
    runs = restir_runs(ctx, 64, mode=UNBIASED, temporal=False)
    assert_same_mean(runs, ref, "unbiased, spatial reuse alone")


@pytest.mark.slow
def test06_without_visibility_in_the_targets_the_mean_is_off(fence, monkeypatch):
    """The power of test05: with the pairwise MIS targets' visibility rays
    answered 'visible' (and so the chosen sample taken as seen), hidden
    samples light the left floor, and the same z-tests find it."""
    ctx, ref = fence

    def all_seen(self):
        return [np.ones(n, bool) for n, *_rest in self.sets]

    monkeypatch.setattr(spatial_module._RayBatch, "trace", all_seen)
    runs = restir_runs(ctx, 64, mode=UNBIASED, temporal=False)
    with pytest.raises(AssertionError):
        assert_same_mean(runs, ref, "unbiased, spatial reuse alone, no visibility")


def test07_biased_weights_count_only_neighbours_that_could_hold_the_sample():
    """The biased mode's W = w_sum / (Z p_hat): with samples 1 mm above their
    points (as close as near a concave corner), no neighbour's point could
    have produced a pixel's sample (every shift's Jacobian is beyond
    J_MAX), so each pixel keeps its own sample at its own weight where 1/M
    would divide it by the k + 1 candidates' M; with samples 1 m above every
    neighbour could, and Z is M."""
    img = plane_image()
    close = samples_above(img, np.full(W * H, DIM), height=0.001)
    res, _, _ = resample(NO_RAYS, img, close)
    reused = res.M > 1
    print(f"1 mm: {reused.mean():.2f} of the pixels had neighbours; W / own W "
          f"{np.min(res.W / close.W):.3f}-{np.max(res.W / close.W):.3f}")
    assert reused.mean() > 0.9
    assert np.allclose(res.x2, close.x2)
    assert np.allclose(res.W, close.W, rtol=1e-5)

    far = samples_above(img, np.full(W * H, DIM))
    res, _, _ = resample(NO_RAYS, img, far)
    p_hat = target_at(res, img.p, img.ng, img.n)
    assert (res.M > 1).mean() > 0.9
    assert np.allclose(res.W * res.M * p_hat, res.w_sum, rtol=1e-5)


def test08_a_still_view_reuses_nearer_neighbours(monkeypatch):
    """Spatial reuse draws neighbours within the full radius on a view's
    first frame and while the camera moves, and within still_radius_scale
    of it while nothing moves."""
    radii = []

    def record(ctx, gb, temporal, seeds, reuse, *args, **kwargs):
        radii.append(reuse.radius)
        return spatial_resample(ctx, gb, temporal, seeds, reuse, *args, **kwargs)

    monkeypatch.setattr(frame_module, "spatial_resample", record)
    restir = ReSTIRGI()
    scene = cornell_box("area", 24, 24)
    settings = ReSTIRSettings(seed=1, max_bounces=1, spatial_radius=12.0)
    poses = []
    for f, x in enumerate([0.0, 0.0, 0.0, 0.1, 0.1]):
        eye = np.array([x, -3.9, 1.0])
        scene.camera = dataclasses.replace(scene.camera, to_world=look_at(eye, eye + [0, 3.9, 0]))
        ctx = RenderContext.build(scene)
        try:
            start = len(radii)
            restir.render_frame(ctx, settings, f)
            poses.append(set(radii[start:]))
        finally:
            ctx.close()
    print(f"radii per frame: {poses}")
    assert poses == [{12.0}, {6.0}, {6.0}, {12.0}, {6.0}]


def test09_flagged_pixels_draw_more_neighbours():
    """SpatialReuse.more: the pixels ``more`` flags (those on objects that
    moved, in the frame) take that many neighbours more, the first k being
    the unflagged draw's own; the others' reservoirs are the same bits; the
    unbiased mode draws no more."""
    img = plane_image()
    x = np.arange(W * H) % W
    temporal = samples_above(img, 1.0 + (x * 7 % 11))
    seeds = samplers.path_seeds(3, 0, np.arange(W * H), 0)
    flagged = (np.arange(W * H) // W) % 2 == 0

    def run(more, extra, biased=True):
        reuse = SpatialReuse(4, 16.0, biased, extra)
        return spatial_resample(NO_RAYS if biased else far, img, temporal, seeds, reuse, more=more,
                                shared=shared_terms(temporal, biased))[0]

    base, wide = run(None, 0), run(flagged, 4)
    for name in Reservoirs.SAMPLE_FIELDS + ("w_sum", "M", "W"):
        assert np.array_equal(getattr(base, name)[~flagged], getattr(wide, name)[~flagged]), name
    # Every neighbour on the plane is accepted but the pixel itself (drawn
    # now and then near the centre of the disk): M 1 + 4, or 1 + 8.
    assert base.M.mean() > 4.9 and wide.M[flagged].mean() > 8.8
    assert (wide.M[flagged] >= base.M[flagged] + 3).all()
    far = far_away_ctx()
    try:
        assert np.array_equal(run(flagged, 4, False).M, run(None, 0, False).M)
    finally:
        far.close()
