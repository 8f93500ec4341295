"""More camera rays for the radiance seen directly at bright silhouettes
(core/restir/silhouettes.py) and how the running means keep it
(core/restir/accumulation.py)."""

from statistics import NormalDist

import numpy as np
import pytest

from restir_gi.core import Camera, Lights, Materials, RenderContext, make_scene
from restir_gi.core.camera.projection import PixelFilter
from restir_gi.core.restir.accumulation import COLUMNS, LIGHT_FRAMES, Accumulation, FrameValues, accumulate
from restir_gi.core.restir.reprojection import Footprint
from restir_gi.core.restir.gbuffer import trace_gbuffer
from restir_gi.core.restir.adaptive_direct import neighbourhood_range
from restir_gi.core.restir.silhouettes import MAX_EDGE_SHARE, edge_pixels, mean_seen_directly, refine_edges
from restir_gi.core.util.vectors import luminance
from support.scenes import Builder, look_at, quad

SIZE = 24
ALPHA = 1e-3


def emitter_scene():
    """A bright emissive square in front of a grey backdrop under a dim
    constant world: its outline and the backdrop's cross the image."""
    b = Builder()
    b.add(*quad((-1.0, 1.0, -0.6), (1.6, 0, 0), (0, 0, 1.6)), 0)        # backdrop, right part of the view
    b.add(*quad((-0.35, 0.0, -0.35), (0.7, 0, 0), (0, 0, 0.7)), 1)     # emitter
    mats = Materials.from_list([{"base_color": (0.5, 0.5, 0.5)},
                                {"base_color": (0, 0, 0), "emission": (20.0, 16.0, 12.0)}])
    cam = Camera(to_world=look_at((0, -4, 0), (0, 0, 0)), lens=50.0, sensor_width=36.0)
    return make_scene(*b.arrays(), mats, Lights.empty(), cam, world_color=(0.2, 0.2, 0.2),
                      width=SIZE, height=SIZE)


@pytest.fixture(scope="module")
def ctx():
    c = RenderContext.build(emitter_scene())
    yield c
    c.close()


def z_limit(tests):
    return NormalDist().inv_cdf(1.0 - 0.5 * (1.0 - (1.0 - ALPHA) ** (1.0 / tests)))


def test01_neighbourhood_without_the_pixel():
    """Max and min over the 3x3 square around each pixel, itself left out
    (as edge_pixels reads them), or kept in."""
    rng = np.random.default_rng(1)
    w, h = 7, 5
    img = rng.random((h, w)).astype(np.float32)
    for centre in (False, True):
        mx, mn = neighbourhood_range(img.ravel(), None, w, h, centre=centre)
        for y in range(h):
            for x in range(w):
                win = [img[j, i] for j in range(max(0, y - 1), min(h, y + 2))
                       for i in range(max(0, x - 1), min(w, x + 2)) if centre or (i, j) != (x, y)]
                assert mx[y * w + x] == max(win) and mn[y * w + x] == min(win)


def test02_edges_surround_bright_silhouettes():
    """A bright square on a dark image: the pixels with both kinds of
    neighbour are edges (the square's border and the ring around it), the
    flat parts are not; the edge of a sky that covers much of the image is
    mild against the image's mean; a noisy image gets at most
    MAX_EDGE_SHARE."""
    w = h = 16
    img = np.zeros((h, w), np.float32)
    img[5:10, 6:12] = 50.0
    edges, bright = edge_pixels(img.ravel(), np.zeros(w * h), w, h)
    mask = np.zeros((h, w), bool)
    mask[4:11, 5:13] = True
    mask[6:9, 7:11] = False         # the square's inside: all neighbours bright
    assert (np.flatnonzero(mask.ravel()) == edges).all()
    assert bright.all()             # 50 against a mean of 5.9
    sky = np.where(np.arange(h)[:, None] < 6, 2.0, 0.0) + np.zeros(w, np.float32)
    edges, bright = edge_pixels(sky.ravel(), np.full(w * h, 0.5), w, h)
    assert len(edges) == 2 * w and not bright.any()     # a sky over lit walls: an edge, mild
    noise = np.random.default_rng(2).exponential(1.0, w * h).astype(np.float32) ** 3
    edges, _ = edge_pixels(noise, np.zeros(w * h), w, h)
    assert 0 < len(edges) <= int(MAX_EDGE_SHARE * w * h)


def test03_choice_ignores_the_pixels_own_values():
    """Whether a pixel is an edge never depends on its own sample: its seen
    and direct light changed from nothing to very bright leave it as it was
    (where the cap does not bind)."""
    rng = np.random.default_rng(3)
    w, h = 16, 12
    seen = np.where(rng.random(w * h) < 0.04, 30.0, 0.1).astype(np.float32)
    other = rng.random(w * h).astype(np.float32)
    base, _ = edge_pixels(seen, other, w, h)
    assert 0 < len(base) < int(MAX_EDGE_SHARE * w * h)
    flips = 0
    for p in rng.choice(w * h, 40, replace=False):
        was = p in base
        for value in (0.0, 1e3):
            s, o = seen.copy(), other.copy()
            s[p], o[p] = value, value
            edges, _ = edge_pixels(s, o, w, h)
            assert (p in edges) == was
            flips += set(edges) != set(base)
    assert flips > 0    # (the pixel's values do move its neighbours)


def test04_the_first_ray_is_the_gbuffers(ctx):
    pf = PixelFilter(1.5)
    gb = trace_gbuffer(ctx, 5, 3, pf)
    one = mean_seen_directly(ctx, 5, 3, pf, np.arange(SIZE * SIZE), 1)
    np.testing.assert_allclose(one, gb.emission, rtol=1e-6, atol=1e-6)


def test05_refined_radiance_is_unbiased_and_less_noisy(ctx):
    """Per pixel, the refined radiance seen directly (over independent
    frames) has the mean of single camera rays (many frames of them), and at
    the edges a far smaller variance."""
    pf = PixelFilter(1.5)
    p = SIZE * SIZE
    single = np.stack([luminance(mean_seen_directly(ctx, 11, f, pf, np.arange(p), 1)) for f in range(512)])
    runs, refined_any = [], np.zeros(p, bool)
    for f in range(48):
        seen = trace_gbuffer(ctx, 12, f, pf).emission.copy()
        before = seen.copy()
        assert refine_edges(ctx, 12, f, pf, seen, np.zeros(p, np.float32), 32) is not None
        refined_any |= (seen != before).any(axis=1)
        runs.append(luminance(seen))
    runs = np.stack(runs).astype(np.float64)
    single = single.astype(np.float64)
    ref_var = single.var(axis=0, ddof=1)
    edges = ref_var > 1.0           # pixels the emitter's outline crosses
    assert edges.sum() >= 20 and refined_any[edges].mean() > 0.9
    se = np.sqrt(runs.var(axis=0, ddof=1) / len(runs) + ref_var / len(single))
    z = (runs.mean(axis=0) - single.mean(axis=0))[edges] / np.maximum(se[edges], 1e-9)
    assert np.abs(z).max() < z_limit(int(edges.sum())), np.round(z, 2)
    # ~24 rays in each edge pixel (1 + a cap of P / edges): well under a quarter of the variance.
    assert runs.var(axis=0)[edges].sum() < 0.25 * ref_var[edges].sum()


def test06_refinement_off():
    """One camera ray per pixel (samples 1) or no pixel filter: nothing to refine."""
    scene = emitter_scene()
    ctx = RenderContext.build(scene)
    try:
        seen = trace_gbuffer(ctx, 1, 0, PixelFilter(1.5)).emission.copy()
        assert refine_edges(ctx, 1, 0, PixelFilter(1.5), seen.copy(), np.zeros(len(seen)), 1) is None
        assert refine_edges(ctx, 1, 0, PixelFilter(0.0), seen.copy(), np.zeros(len(seen)), 32) is None
    finally:
        ctx.close()


def history(seen):
    data = np.zeros((len(seen), COLUMNS), np.float32)
    data[:, 12] = data[:, LIGHT_FRAMES] = 4.0     # four frames held
    data[:, 14:17] = seen
    return Accumulation(data)


def test07_moving_view_holds_seen_history_under_the_ceiling(ctx):
    """Off a still view the history of the radiance seen directly is held
    under this frame's brightest neighbour (a pixel that held part of a
    moving emitter under another object's id leaves no trail), and the
    brightest edges keep none; a still view keeps it all."""
    pf = PixelFilter(1.5)
    p = SIZE * SIZE
    seen = trace_gbuffer(ctx, 2, 0, pf).emission.copy()
    refined = refine_edges(ctx, 2, 0, pf, seen, np.zeros(p, np.float32), 32)
    assert refined.own.any() and not refined.own.all()
    prev = history(np.full((p, 3), 100.0, np.float32))      # a bright trail everywhere
    foot = Footprint.none(p)
    foot.taps[:, 0], foot.weights[:, 0] = np.arange(p), 1.0
    zeros = np.zeros((p, 3), np.float32)
    moving = accumulate(prev, foot, FrameValues(zeros, zeros, zeros, zeros, 1.0, seen), 16, refined)
    lum = luminance(moving.seen)
    # 4 frames of history and this one: at most the ceiling throughout.
    assert (lum <= refined.ceiling * (1 + 1e-4) + 1e-5).all()
    np.testing.assert_allclose(moving.seen[refined.own], seen[refined.own], rtol=1e-5)
    foot.exact = True
    still = accumulate(prev, foot, FrameValues(zeros, zeros, zeros, zeros, 1.0, seen), 16, refined)
    np.testing.assert_allclose(still.seen, (4 * 100.0 + seen) / 5, rtol=1e-5)


def test08_emission_that_varies_over_the_surface():
    """An emitter whose emission comes from a texture (a screen's image) is
    evaluated at each ray's own hit: the refinement's rays see what the
    G-buffer's do, and many rays per edge pixel work (they took the sparse
    hit record that such graphs cannot read, and every real file with a
    textured emitter failed)."""
    from restir_gi.core.materials.shader.graph import Link, Node, ShaderGraph
    scene = emitter_scene()
    screen = ShaderGraph(nodes=[
        Node("TEX_COORD"),
        Node("TEX_CHECKER", {"Vector": Link(0, "Object"), "Color1": (20.0, 16.0, 12.0),
                             "Color2": (2.0, 4.0, 8.0), "Scale": 3.0}),
        Node("EMISSION", {"Color": Link(1, "Color"), "Strength": 1.0})], output=Link(2, "Emission"), name="Screen")
    scene.shaders = [None, screen]
    scene.object_matrices = np.eye(4, dtype=np.float32)[None]
    c = RenderContext.build(scene)
    try:
        pf = PixelFilter(1.5)
        gb = trace_gbuffer(c, 5, 3, pf)
        one = mean_seen_directly(c, 5, 3, pf, np.arange(SIZE * SIZE), 1)
        np.testing.assert_allclose(one, gb.emission, rtol=1e-6, atol=1e-6)
        assert len(np.unique(luminance(gb.emission[luminance(gb.emission) > 1]).round(3))) > 1   # it varies
        seen = gb.emission.copy()
        assert refine_edges(c, 5, 3, pf, seen, np.zeros(SIZE * SIZE, np.float32), 8) is not None
        assert np.isfinite(seen).all() and (seen != gb.emission).any()
    finally:
        c.close()
