"""The engine's denoiser (core/restir/denoise.py): an SVGF-style filter of the
running means.

On synthetic running means: a constant image stays constant; depth, normal
and albedo edges stay edges while the flat sides are smoothed; any input,
however wrong, gives a finite non-negative image; the image does not depend
on how the pixels are split into ranges. On renders: the temporal part (the
running means with the moments carried) is the image without the denoiser
bit for bit, keeps the unbiased mode's mean, and the filtered image keeps
the mean too. Through Blender: the settings reach the renderer, and the
passes (Noisy Image, Denoising Normal) are in the multilayer EXR.
"""

import dataclasses

import numpy as np
import pytest

from restir_gi.core import RenderContext, RenderSettings, render_frame
from restir_gi.core.workers.parallel import Workers
from restir_gi.core.render import render_restir
from restir_gi.core.restir import BIASED, UNBIASED, ReSTIRGI, ReSTIRSettings
from restir_gi.core.restir.accumulation import COLUMNS, LIGHT_FRAMES
from restir_gi.core.restir.denoise import MOMENTS, denoise, frame_moments
from restir_gi.core.util.vectors import luminance
from support.scenes import cornell_box
from support.restir_reference import Reference, assert_same_mean, z_limit

W, H = 64, 48


def means(light, albedo, count=8.0, normal=(0.0, 0.0, 1.0), seen=0.0, moments=None, direct=0.0):
    """Running means (P, COLUMNS + MOMENTS) of indirect light (P, 3), with the
    given albedo, normals, frames, direct light, radiance seen directly and
    moments (default: each pixel's own light, no spread over its history)."""
    n = len(light)
    data = np.zeros((n, COLUMNS + MOMENTS), np.float32)
    data[:, 0:3] = direct
    data[:, 3:6] = light
    data[:, 6:9] = albedo
    data[:, 9:12] = normal
    data[:, 12] = count
    data[:, 13] = 1.0
    data[:, 14:17] = seen
    data[:, LIGHT_FRAMES] = count
    data[:, COLUMNS:] = frame_moments(data[:, 3:6], data[:, 6:9]) if moments is None else moments
    return data


def noisy_moments(lum, sigma):
    """Moments of a history whose luminance had mean lum (P,) and spread sigma."""
    return np.stack([lum, lum * lum + sigma * sigma], axis=1).astype(np.float32)


def run(data, depth, valid=None, workers=None, **kw):
    own = workers is None
    workers = workers or Workers(1)
    try:
        valid = np.ones(len(depth), bool) if valid is None else valid
        return denoise(workers, data, np.asarray(depth, np.float32), valid, W, H, **kw)
    finally:
        if own:
            workers.close()


def image(x):
    return np.asarray(x).reshape(H, W, -1)


def sloped_depth():
    """A plane seen at an angle: depth growing along y."""
    return np.repeat(np.linspace(3.0, 6.0, H, dtype=np.float32), W)


# --------------------------------------------------------------- synthetic

@pytest.mark.parametrize("count", [1.0, 8.0])
def test01_a_constant_image_stays_constant(count):
    """With short (spatial variance) and long histories (temporal), a spread
    in the moments and a sloped plane: every pixel keeps the colour."""
    n = W * H
    light = np.tile(np.float32([0.6, 0.4, 0.2]), (n, 1))
    albedo = np.tile(np.float32([0.5, 0.8, 0.3]), (n, 1))
    lum = luminance(light / albedo).astype(np.float32)
    data = means(light, albedo, count, seen=np.float32([0.1, 0.0, 0.0]), moments=noisy_moments(lum, 0.3),
                 direct=np.float32([0.0, 0.2, 0.0]))
    out = run(data, sloped_depth())
    expect = light + np.float32([0.1, 0.2, 0.0])
    np.testing.assert_allclose(out, expect, rtol=1e-5)


def edge_case(kind, rng):
    """Two halves (left x < W / 2, right) that differ by ``kind``, each with
    noisy light around its own level: levels closer than the noise's spread,
    so that luminance alone would not keep them apart. Returns data, depth,
    the noise-free colour image and the right half."""
    n = W * H
    x = np.tile(np.arange(W), H)
    right = x >= W // 2
    level = np.where(right, 1.6, 1.0).astype(np.float32)
    albedo = np.full((n, 3), 0.5, np.float32)
    normal = np.tile(np.float32([0, 0, 1]), (n, 1))
    depth = np.full(n, 4.0, np.float32)
    if kind == "depth":
        depth[right] = 8.0
    elif kind == "normal":
        normal[right] = [1, 0, 0]
    elif kind == "albedo":
        level[:] = 2.0          # the same light on both sides; the albedo differs
        albedo[right] = 0.9
        albedo[~right] = 0.1
    noise = rng.gamma(4.0, 0.25, n).astype(np.float32)      # mean 1, spread 0.5
    light = (level * noise)[:, None] * albedo
    sigma = 0.5 * level
    data = means(light, albedo, 4.0, normal=normal, moments=noisy_moments(level, sigma))
    clean = level[:, None] * albedo
    return data, depth, clean, right


@pytest.mark.parametrize("kind", ["depth", "normal", "albedo"])
def test02_an_edge_stays_an_edge(kind, rng):
    """Each side is smoothed and keeps its mean, and the columns on either
    side of the edge stay at their side's level (no light bleeds across)."""
    data, depth, clean, right = edge_case(kind, rng)
    out = run(data, depth)
    noisy = data[:, 3:6]
    lum_out, lum_in, lum_clean = (luminance(image(v)) for v in (out, noisy, clean))
    err_in = np.abs(lum_in - lum_clean).mean()
    err_out = np.abs(lum_out - lum_clean).mean()
    assert err_out < 0.5 * err_in, (err_out, err_in)
    step = abs(float(lum_clean[:, W // 2].mean() - lum_clean[:, W // 2 - 1].mean()))
    for side, cols, edge in ((0, np.s_[:W // 2 - 6], W // 2 - 1), (1, np.s_[W // 2 + 6:], W // 2)):
        inner = float(lum_out[:, cols].mean())
        assert abs(inner / float(lum_in[:, cols].mean()) - 1) < 0.03, (side, inner)
        # The columns at the edge: within 10 % of the step of their side's inner mean.
        for col in (edge, edge + (1 if side == 0 else -1) * -1):
            bleed = abs(float(lum_out[:, col].mean()) - inner)
            assert bleed < 0.1 * step, (side, col, bleed, step)
    if kind == "albedo":
        # The light is the same on both sides: what differs is the albedo alone.
        ratio = lum_out[:, W // 2] / np.maximum(lum_out[:, W // 2 - 1], 1e-6)
        assert abs(float(np.median(ratio)) - 9.0) < 1.0


def test03_never_nan_inf_or_negative(rng):
    n = W * H
    cases = {
        "zeros": np.zeros((n, COLUMNS + MOMENTS), np.float32),
        "random": rng.normal(0, 10, (n, COLUMNS + MOMENTS)).astype(np.float32),
        "huge": np.full((n, COLUMNS + MOMENTS), 3e38, np.float32),
    }
    wild = rng.normal(0, 1, (n, COLUMNS + MOMENTS)).astype(np.float32)
    for value in (np.nan, np.inf, -np.inf, 1e30, -1e30, 0.0):
        wild[rng.random(wild.shape) < 0.05] = value
    cases["nan, inf and extremes"] = wild
    depths = {"plane": np.full(n, 4.0, np.float32),
              "wild": np.where(rng.random(n) < 0.1, np.nan,
                               np.where(rng.random(n) < 0.1, 1e10, rng.random(n) * 1e3)).astype(np.float32),
              "zero": np.zeros(n, np.float32)}
    for name, data in cases.items():
        for dname, depth in depths.items():
            for valid in (np.ones(n, bool), rng.random(n) < 0.7):
                out = run(data, depth, valid)
                assert out.shape == (n, 3) and out.dtype == np.float32
                assert np.isfinite(out).all(), (name, dname)
                assert (out >= 0).all(), (name, dname)


def test04_any_split_gives_the_same_image(rng):
    """One range, ranges that end mid-row, two threads: the same bits."""
    data, depth, _, _ = edge_case("depth", rng)
    data[:, 12] = np.where(rng.random(W * H) < 0.2, 1.0, 8.0)     # some short histories
    one = run(data, depth)
    for workers in (Workers(1, max_range=997, processes=False), Workers(2, max_range=1500, processes=False),
                    Workers(2, processes=False)):
        try:
            assert len(workers.ranges(W * H)) > 1 or workers.threads == 2
            assert np.array_equal(run(data, depth, workers=workers), one)
        finally:
            workers.close()


def test05_no_iterations_give_the_means_back(rng):
    n = W * H
    light = rng.random((n, 3)).astype(np.float32)
    albedo = rng.uniform(0.05, 1.0, (n, 3)).astype(np.float32)
    data = means(light, albedo, seen=0.25, direct=0.5)
    out = run(data, np.full(n, 4.0, np.float32), iterations=0)
    np.testing.assert_allclose(out, light + 0.75, rtol=1e-5, atol=1e-7)


def test06_direct_light_and_what_is_seen_directly_stay_sharp(rng):
    """Only the indirect light is filtered: noise in the direct light and
    in the radiance seen directly comes out as it went in."""
    n = W * H
    direct = rng.exponential(1.0, (n, 3)).astype(np.float32)
    seen = rng.exponential(0.5, (n, 3)).astype(np.float32)
    indirect = rng.gamma(4.0, 0.25, (n, 1)).astype(np.float32) * np.ones(3, np.float32)
    albedo = np.full((n, 3), 0.5, np.float32)
    data = means(indirect * albedo, albedo, 4.0, seen=seen, direct=direct,
                 moments=noisy_moments(np.ones(n, np.float32), 1.0))
    out = run(data, sloped_depth())
    rest = out - direct - seen
    np.testing.assert_allclose(rest.mean(), (indirect * albedo).mean(), rtol=0.03)
    assert rest.std() < 0.5 * (indirect * albedo).std()
    assert np.abs(rest - (indirect * albedo).mean()).max() < 0.5


# --------------------------------------------------------------- renders

SIZE = 16
MAX_BOUNCES = 4


@pytest.fixture(scope="module")
def ctx():
    scene = cornell_box("area", SIZE, SIZE)
    scene.filter_width = 1.5
    c = RenderContext.build(scene)
    yield c
    c.close()


@pytest.fixture(scope="module")
def reference(ctx):
    return Reference(render_frame(ctx, RenderSettings(samples=1024, max_bounces=MAX_BOUNCES, seed=0)))


@pytest.mark.parametrize("mode", [BIASED, UNBIASED])
def test07_the_running_means_are_the_same_bits_with_the_denoiser(ctx, mode):
    """The moments ride along: what the frame was before the denoiser (Noisy
    Image) is the image without it, over frames, in both modes."""
    off, on = ReSTIRGI(), ReSTIRGI()
    settings = ReSTIRSettings(mode=mode, seed=5, max_bounces=2)
    for f in range(5):
        a = off.render_frame(ctx, settings, f)
        b = on.render_frame(ctx, dataclasses.replace(settings, denoise=True), f)
        assert a.noisy is None and b.noisy is not None
        assert np.array_equal(a.color, b.noisy)
        for name in ("direct", "indirect", "albedo", "normal", "depth", "alpha"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert np.isfinite(b.color).all() and (b.color >= 0).all()


def test08_holdouts_stay_cut_out():
    """Half of the back wall (one of its two triangles) is a holdout object:
    its pixels stay black, the filter blurs none of the other half's light
    into them."""
    scene = cornell_box("area", 48, 48)
    scene.object_ids = np.asarray(scene.object_ids).copy()
    scene.object_ids[4] = 1
    scene.object_holdout = np.array([False, True])
    ctx = RenderContext.build(scene)
    try:
        restir = ReSTIRGI()
        settings = ReSTIRSettings(seed=2, max_bounces=2, denoise=True)
        for f in range(4):
            out = restir.render_frame(ctx, settings, f)
    finally:
        ctx.close()
    hole = out.alpha == 0         # (alpha: coverage less holdouts, over the frames)
    assert 0.05 < hole.mean() < 0.5 and (out.noisy[hole] == 0).all()
    assert (out.color[hole] == 0).all()
    assert (out.color[~hole].max(axis=1) > 0).mean() > 0.9


@pytest.mark.slow
def test09_unbiased_mean_is_kept(ctx, reference):
    """Unbiased stills on a static scene, over seeds: the temporal part (the
    image before the filter) has the path tracer's mean, per image and per
    block; the filtered image's mean is within the confidence interval of
    the reference's too (the filter blurs, so blocks are not compared)."""
    noisy, filtered = [], []
    for r in range(40):
        out = render_restir(ctx, ReSTIRGI(), ReSTIRSettings(mode=UNBIASED, seed=4000 + r, max_bounces=MAX_BOUNCES,
                                                            denoise=True), 0, frames=8, fresh=True)
        noisy.append(luminance(out.noisy))
        filtered.append(luminance(out.color))
    noisy, filtered = np.stack(noisy).astype(np.float64), np.stack(filtered).astype(np.float64)
    assert_same_mean(noisy, reference, "unbiased still, 8 frames, before the denoiser")
    totals = filtered.sum(axis=1)
    se = np.sqrt(totals.var(ddof=1) / len(totals) + reference.var_of_mean.sum())
    z = (totals.mean() - reference.mean.sum()) / se
    print(f"denoised: image mean {totals.mean() / SIZE ** 2:.5f} vs reference {reference.mean.mean():.5f}, "
          f"z = {z:.2f}; before the denoiser {noisy.sum(axis=1).mean() / SIZE ** 2:.5f}")
    assert abs(z) < z_limit(1)
    # ... and it is smoother: the spread over seeds falls.
    assert filtered.var(axis=0).mean() < noisy.var(axis=0).mean()


# --------------------------------------------------------------- through Blender

def test10_settings_reach_the_renderer(addon):
    from support.addon_util import fresh
    final, draw, vp = addon.restir_addon.final, addon.restir_addon.viewport.draw, addon.restir_addon.viewport.session
    defaults = addon.restir_addon.defaults
    scene = fresh(mode="RESTIR_BIASED")
    s = scene.restir_gi
    assert s.use_denoising and s.use_preview_denoising      # on by default in both
    assert final.restir_settings(scene).denoise
    assert draw.session_settings(scene)["restir"].denoise
    s.use_denoising, s.use_preview_denoising = False, True
    assert not final.restir_settings(scene).denoise
    assert draw.session_settings(scene)["restir"].denoise     # each toggle on its own
    s.use_denoising, s.use_preview_denoising = True, False
    assert final.restir_settings(scene).denoise
    assert not draw.session_settings(scene)["restir"].denoise
    for kwargs, expect in ((draw.session_settings(scene), False), ({}, defaults.VIEWPORT_DENOISE)):
        session = vp.ViewportSession(**kwargs)
        try:
            assert session.restir_settings.denoise == expect
        finally:
            session.close()


@pytest.mark.parametrize("mode,denoise", [("RESTIR_BIASED", True), ("RESTIR_UNBIASED", True),
                                          ("RESTIR_BIASED", False), ("PATH", True)])
def test11_passes_in_the_multilayer_exr(addon, tmp_path, mode, denoise):
    """Noisy Image when denoised (ReSTIR GI modes), Denoising Normal always:
    camera space as Cycles writes it (a plane facing the camera: 0, 0, -1)."""
    from support.addon_util import add_mesh, camera, fresh, read_passes, rect, render_exr, world
    from support.blender_util import diffuse_material
    scene = fresh(32, 32, samples=4, mode=mode)
    scene.restir_gi.warmup_frames = 4
    scene.restir_gi.use_denoising = denoise
    camera(location=(0, 0, 5))
    world((0.5, 0.5, 0.5))
    add_mesh("Plane", *rect(-5, 0, -5, 5, z=1.0), mat=diffuse_material("Orange", (0.6, 0.3, 0.1)))
    # A wall standing on the plane (seen edge-on) lights it indirectly.
    add_mesh("Wall", np.array([[-2.5, -5, 1], [-2.5, 5, 1], [-2.5, 5, 3], [-2.5, -5, 3]], float), [[0, 1, 2, 3]],
             mat=diffuse_material("White", (0.8, 0.8, 0.8)))
    path = tmp_path / "passes.exr"
    render_exr(scene, path, multilayer=True)
    p = read_passes(path)
    noisy_pass = denoise and mode != "PATH"
    assert ("Noisy Image" in p) == noisy_pass, sorted(p)
    assert {"Combined", "Normal", "Denoising Normal", "Denoising Albedo"} <= set(p)
    for name, img in p.items():
        assert np.isfinite(img).all(), name
    left, right = np.s_[:, 2:13], np.s_[:, 19:30]
    np.testing.assert_allclose(p["Denoising Normal"][left],
                               np.broadcast_to([0, 0, -1], p["Denoising Normal"][left].shape), atol=1e-5)
    np.testing.assert_allclose(p["Denoising Normal"][right], 0)
    if noisy_pass:
        noisy, combined = p["Noisy Image"], p["Combined"]
        assert noisy.shape == combined.shape == (32, 32, 4)
        np.testing.assert_allclose(noisy[..., 3], combined[..., 3])
        # The world seen directly is not filtered; the plane's indirect light
        # is, and the plane keeps its mean.
        np.testing.assert_allclose(combined[right][..., :3], noisy[right][..., :3], rtol=1e-6)
        np.testing.assert_allclose(combined[left][..., :3].reshape(-1, 3).mean(axis=0),
                                   noisy[left][..., :3].reshape(-1, 3).mean(axis=0), rtol=0.03)
        assert not np.array_equal(combined[left], noisy[left])


def test_short_histories_get_the_energy_the_filter_lost_back():
    """kept_energy: where a pixel's history is short, the filtered light's
    window mean is brought back to the unfiltered one's (within
    ENERGY_RANGE); long histories and pixels that see nothing keep 1."""
    from restir_gi.core.restir.denoise import ENERGY_RANGE, SHORT_HISTORY_ENERGY, kept_energy
    w, h = 24, 16
    n = w * h
    raw = np.full(n, 2.0, np.float32)
    lost = np.full(n, 1.8, np.float32)           # the filter kept 90 %
    frames = np.where(np.arange(n) % w < 12, 1.0, 2 * SHORT_HISTORY_ENERGY).astype(np.float32)
    valid = np.ones(n, bool)
    valid[5] = False
    factor = np.concatenate([kept_energy(raw, (lost, lost, lost), frames, valid, w, h, a, b)
                             for a, b in ((0, 5), (5, 6), (6, h))])      # (ranges of rows)
    short = valid & (frames < SHORT_HISTORY_ENERGY)
    np.testing.assert_allclose(factor[short], 2.0 / 1.8, rtol=1e-5)
    np.testing.assert_array_equal(factor[~short], 1.0)
    far = kept_energy(raw, (raw * 0.1,) * 3, frames, valid, w, h, 0, h)
    assert far[short].max() == np.float32(ENERGY_RANGE[1])


def test_a_lone_bright_pixel_is_spread_not_kept():
    """firefly_factor: a pixel brighter than FIREFLY_RATIO x its brightest
    neighbour is brought down to that, at any history length (whatever the
    split into rows); milder pixels and a bright pair keep 1. Through the
    denoiser, a short history's energy stays in its window (kept_energy)."""
    from restir_gi.core.restir.denoise import FIREFLY_RATIO, firefly_factor
    n = W * H
    lum = np.full(n, 1.0, np.float32)
    hot, mild, old = 20 * W + 30, 10 * W + 10, 30 * W + 40
    pair = [5 * W + 50, 5 * W + 51]
    lum[[hot, old]] = 50.0
    lum[pair] = 50.0
    lum[mild] = 0.9 * FIREFLY_RATIO
    valid = np.ones(n, bool)
    factor = np.concatenate([firefly_factor(lum, valid, W, H, a, b) for a, b in ((0, 20), (20, 21), (21, H))])
    assert factor[hot] == pytest.approx(FIREFLY_RATIO / 50.0)
    assert factor[old] == pytest.approx(FIREFLY_RATIO / 50.0)
    factor[[hot, old]] = 1.0
    np.testing.assert_array_equal(factor, 1.0)
    # Through the denoiser: a grey plane of one-frame histories, one pixel
    # 50x brighter. The pixel comes out near the plane's 0.5 (0.77 without
    # the clamp); the image keeps its energy.
    light = np.full((n, 3), 0.5, np.float32)
    light[hot] = 25.0
    data = means(light, np.full((n, 3), 1.0, np.float32), count=1.0)
    out = run(data, np.full(n, 4.0, np.float32))
    assert out[hot].mean() < 0.65
    assert out.mean() == pytest.approx(light.mean(), rel=0.05)


def test_a_pixel_that_mixes_two_surfaces_is_filtered_with_both(rng):
    """A column on a right-angled edge whose frames saw both surfaces, in a
    share that changes from row to row: its mean normals lie between the
    two sides' and are shorter than 1. It is filtered with both sides
    (edge_filter.MIXED_LENGTH) instead of being left noisy and keeps its
    mean; the columns beside it keep theirs."""
    from restir_gi.core.restir import edge_filter
    n = W * H
    x = np.tile(np.arange(W), H)
    edge, right = x == W // 2, x > W // 2
    # The right surface's share of each edge pixel, as along a jagged edge.
    share = np.repeat(rng.uniform(0.2, 0.8, H), W).astype(np.float32)
    level = np.where(right, 1.6, np.where(edge, 1.0 + 0.6 * share, 1.0)).astype(np.float32)
    normal = np.tile(np.float32([0, 0, 1]), (n, 1))
    normal[right] = [1, 0, 0]
    normal[edge] = np.stack([share, 0 * share, 1 - share], 1)[edge]     # the running mean of the two
    albedo = np.full((n, 3), 0.5, np.float32)
    noise = rng.gamma(4.0, 0.25, n).astype(np.float32)
    # (16 frames: a still's long histories, which kept_energy leaves alone)
    data = means((level * noise)[:, None] * albedo, albedo, 16.0, normal=normal,
                 moments=noisy_moments(level, 0.5 * level))
    clean = luminance(image(level[:, None] * albedo))
    depth = np.full(n, 4.0, np.float32)
    before = edge_filter.MIXED_LENGTH
    try:
        edge_filter.MIXED_LENGTH = 0.0
        kept = luminance(image(run(data, depth)))
    finally:
        edge_filter.MIXED_LENGTH = before
    out = luminance(image(run(data, depth)))
    col = W // 2
    err_kept = np.abs(kept[:, col] - clean[:, col]).mean()
    err = np.abs(out[:, col] - clean[:, col]).mean()
    assert err < 0.7 * err_kept, (err, err_kept)
    assert abs(float(out[:, col].mean()) / float(clean[:, col].mean()) - 1) < 0.05
    # The columns beside it do not take its light: they move by less than
    # 15 % of the step between the sides (they do move, 2-5 % here: the
    # edge's filtered variance, lower now, narrows their luminance weights
    # through the variance's 3x3 blur, and this noise is skewed).
    step = 0.6 * 0.5
    for side in (col - 1, col + 1):
        assert abs(float(out[:, side].mean()) - float(kept[:, side].mean())) < 0.15 * step, side
