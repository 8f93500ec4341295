"""Sky rays (core/restir/sky.py): the world's light on visible points'
diffuse lobe from cosine-weighted occlusion rays.

Checked against a brute-force integral of another sampler (uniform
directions over the hemisphere, cosine-weighted by hand, 200,000 rays a
point), exactly on open ground, by z-tests beside a wall, with an HDRI's
NEE share left out, and the Sobol points over a stream's frames against
hashed uniforms. ReSTIR's means with and without sky rays are checked
against path tracing in test_restir_world.py."""

from types import SimpleNamespace

import numpy as np

from restir_gi.core import Camera, Materials, RenderContext, make_scene
from restir_gi.core.lights.environment import Environment
from restir_gi.core.integrators.base import ShadingFrame
from restir_gi.core.geometry.interaction import surface_hits
from restir_gi.core.restir.initial import world_share
from restir_gi.core.restir.sky import SKY_KEEP_MIN, pixel_shares, point_plan, sky_light, visible_sky_light
from restir_gi.core.sampling.samplers import hash_keys
from restir_gi.core.sampling.warps import square_to_uniform_hemisphere
from support.scenes import Builder, look_at, quad

WORLD = (0.6, 0.7, 0.9)
# Floor points: away from the wall, and two beside it (x = 0.05, 0.4 from it).
POINTS = np.float32([[-3.0, 0.0], [0.05, 0.0], [0.4, 0.5]])


def sun_sky(d):
    d = np.asarray(d, np.float64)
    sun = np.array([0.5, 0.2, 0.84]) / np.linalg.norm([0.5, 0.2, 0.84])
    base = np.array([0.3, 0.45, 0.8]) * (0.3 + 0.5 * d[:, 2:3])
    return (base + 80.0 * np.exp((d @ sun - 1.0) / 0.1 ** 2)[:, None]).astype(np.float32)


def scene_and_points(environment=None, wall=True):
    """A floor, a tall wall at x in [-0.2, 0] and the surface records of
    POINTS on the floor (rays straight down)."""
    b = Builder()
    b.add(*quad((-8, -8, 0), (16, 0, 0), (0, 16, 0)), 0)
    if wall:
        b.add_box((-0.2, -1.5, 0), (0.0, 1.5, 3.0), 0)
    v, t, m = b.arrays()
    scene = make_scene(v, t, m, Materials.from_list([{"base_color": (0.5, 0.6, 0.7), "specular": 0.5,
                                                      "roughness": 0.5}]),
                       camera=Camera(to_world=look_at((4, -4, 3), (0, 0, 0)), lens=30.0), width=8, height=8)
    scene.environment = environment or Environment.constant_color(WORLD)
    ctx = RenderContext.build(scene, threads=1)
    o = np.concatenate([POINTS, np.full((len(POINTS), 1), 5.0, np.float32)], axis=1)
    d = np.tile(np.float32([0, 0, -1]), (len(POINTS), 1))
    surf, _ = surface_hits(scene, o, d, ctx.accel.intersect_closest(o, d))
    return ctx, surf, ShadingFrame.at(scene, surf)


def brute_force(ctx, surf, frame, rays=200_000):
    """(N, 3) diffuse x the integral of (1 - NEE's share) L V cos / pi over
    the hemisphere, from uniform directions (a sampler sky.py does not use)."""
    rng = np.random.default_rng(3)
    out = []
    for i in range(len(surf)):
        local = square_to_uniform_hemisphere(rng.random((rays, 2), np.float32))
        wi = local.astype(np.float32)       # the floor's frame is the world's (normal +z)
        o = np.repeat(surf.p[i:i + 1] + np.float32([0, 0, 1e-3]), rays, axis=0)
        open_ = ~ctx.accel.occluded(o, wi, np.full(rays, np.inf, np.float32))
        li = ctx.lights.world_radiance(wi) * (1.0 - world_share(ctx.lights, wi))[:, None]
        # uniform pdf 1 / (2 pi); Lambert f = diffuse / pi: 2 cos L V on average
        out.append((2.0 * (li * (open_ * local[:, 2])[:, None])).mean(axis=0))
    return np.stack(out) * frame.params.diffuse


def test01_open_ground_is_the_world_times_the_diffuse_colour():
    """Every direction open: each estimate is exactly diffuse x L, whatever
    the seed (the cosine sampler's weight is the diffuse colour)."""
    ctx, surf, frame = scene_and_points(wall=False)
    for seed in range(3):
        out = sky_light(ctx, surf.subset([0]), frame.subset([0]), 4, seeds=hash_keys(seed, [0]))
        np.testing.assert_allclose(out[0], frame.params.diffuse[0] * np.float32(WORLD), rtol=1e-5)
    assert (frame.params.diffuse[0] > 0.2).all()
    ctx.close()


def test02_beside_a_wall_the_mean_is_the_integral():
    ctx, surf, frame = scene_and_points()
    ref = brute_force(ctx, surf, frame)
    runs = np.stack([sky_light(ctx, surf, frame, 4, seeds=hash_keys(s, np.arange(len(surf))))
                     for s in range(400)])
    mean, se = runs.mean(axis=0), runs.std(axis=0, ddof=1) / np.sqrt(len(runs))
    z = (mean - ref) / np.sqrt(se ** 2 + 1e-12)
    # The wall takes a good part of the sky from the points beside it.
    assert ref[1, 2] < 0.7 * ref[0, 2] and ref[2, 2] < 0.85 * ref[0, 2]
    assert np.abs(z).max() < 4.0, (mean, ref, z)
    ctx.close()


def test03_counts_per_point_keep_the_mean():
    """Points may take different numbers of rays (ReSTIR gives all of them
    where its sample ray escaped, one elsewhere): each count's mean is the
    integral."""
    ctx, surf, frame = scene_and_points()
    ref = brute_force(ctx, surf, frame)
    counts = np.array([1, 4, 2])
    runs = np.stack([sky_light(ctx, surf, frame, counts, seeds=hash_keys(s, np.arange(len(surf))))
                     for s in range(600)])
    mean, se = runs.mean(axis=0), runs.std(axis=0, ddof=1) / np.sqrt(len(runs))
    z = (mean - ref) / np.sqrt(se ** 2 + 1e-12)
    assert np.abs(z).max() < 4.0, (mean, ref, z)
    keys = hash_keys(1, np.arange(len(surf)))
    one = np.stack([sky_light(ctx, surf, frame, counts, keys=keys, stream_index=s) for s in range(64)])
    assert np.abs((one.mean(axis=0) - ref) / (one.std(axis=0, ddof=1) / 8 + 1e-6)).max() < 5.0
    ctx.close()


def test04_an_hdri_leaves_its_bright_directions_to_nee():
    """With a map, NEE takes the sun's directions (world_share); the sky rays
    the rest: the mean matches the brute-force integral of (1 - share) L."""
    ctx, surf, frame = scene_and_points(Environment(sun_sky, resolution=128))
    assert ctx.lights.world_pmf > 0
    ref = brute_force(ctx, surf, frame)
    full = ctx.lights.world_radiance(np.float32([[0.5, 0.2, 0.84]]) / np.float32(np.linalg.norm([0.5, 0.2, 0.84])))
    assert full.max() > 20      # the sun is in the map, and not in the sky rays' part
    runs = np.stack([sky_light(ctx, surf, frame, 4, seeds=hash_keys(s, np.arange(len(surf))))
                     for s in range(400)])
    mean, se = runs.mean(axis=0), runs.std(axis=0, ddof=1) / np.sqrt(len(runs))
    z = (mean - ref) / np.sqrt(se ** 2 + 1e-12)
    assert np.abs(z).max() < 4.0, (mean, ref, z)
    ctx.close()


def test05_sobol_points_over_a_stream_cover_the_hemisphere():
    """A pixel's rays over 16 frames of its stream (4 a frame) are one
    scrambled Sobol net: the mean of the 16 frames beside the wall is
    unbiased and far less noisy than 16 frames of hashed rays."""
    ctx, surf, frame = scene_and_points()
    ref = brute_force(ctx, surf, frame)[1:2]
    one, f1 = surf.subset([1]), frame.subset([1])
    sobol, hashed = [], []
    for key in range(160):
        keys = hash_keys(key, [1])
        sobol.append(np.mean([sky_light(ctx, one, f1, 4, keys=keys, stream_index=s) for s in range(16)], axis=0))
        hashed.append(np.mean([sky_light(ctx, one, f1, 4, seeds=hash_keys(key, s, [1])) for s in range(16)],
                              axis=0))
    sobol, hashed = np.stack(sobol)[:, 0], np.stack(hashed)[:, 0]
    z = (sobol.mean(axis=0) - ref[0]) / (sobol.std(axis=0, ddof=1) / np.sqrt(len(sobol)) + 1e-6)
    assert np.abs(z).max() < 4.0, (sobol.mean(axis=0), ref, z)
    ratio = sobol.var(axis=0).mean() / hashed.var(axis=0).mean()
    assert ratio < 0.3, ratio
    ctx.close()


def test06_a_share_of_frames_casting_keeps_the_mean():
    """Where the sky gave little of a point's direct light, it casts one ray
    in a share of the frames, weighted by its inverse (point_plan): per
    point the mean over frames is the integral, and about that share of
    the points cast rays in a frame."""
    counts, keep = point_plan(4, [np.nan, 0.5, 0.05, 0.0])
    assert list(counts) == [4, 4, 1, 1]
    np.testing.assert_allclose(keep, [1.0, 1.0, 0.5, SKY_KEEP_MIN])
    assert (point_plan(0, [0.5])[0] == 0).all()
    ctx, surf, frame = scene_and_points()
    ref = brute_force(ctx, surf, frame)
    idx = np.tile(np.arange(len(surf)), 200)
    gb = SimpleNamespace(index=np.arange(len(idx)), offset=0, ids=lambda rows: rows, surf=surf.subset(idx), frame=frame.subset(idx))
    plan = (np.tile([1, 4, 1], 200), np.tile(np.float32([0.25, 1.0, 0.5]), 200))

    def frame_of(f):        # (reads ctx and gb when called: the second scene's below)
        return visible_sky_light(ctx, gb, 3, f, hash_keys(3, f, np.arange(len(idx))), plan, 4, [None])

    runs = np.stack([frame_of(f) for f in range(120)])
    per_point = runs.reshape(-1, 200, len(surf), 3).mean(axis=(0, 1))
    se = runs.reshape(-1, len(surf), 3).std(axis=0, ddof=1) / np.sqrt(runs.shape[0] * 200)
    z = (per_point - ref) / (se + 1e-9)
    assert np.abs(z).max() < 4.0, (per_point, ref, z)
    ctx.close()
    ctx, surf, frame = scene_and_points(wall=False)     # every ray open: nonzero = cast
    gb = SimpleNamespace(index=np.arange(len(idx)), offset=0, ids=lambda rows: rows, surf=surf.subset(idx), frame=frame.subset(idx))
    cast = np.mean([(frame_of(f)[:, 2] > 0).reshape(200, 3).mean(axis=0) for f in range(20)], axis=0)
    np.testing.assert_allclose(cast, [0.25, 1.0, 0.5], atol=0.015)
    ctx.close()


def test07_shares_are_taken_over_the_pixels_around():
    """A pixel's share is the sky's part of the light of the 9x9 pixels
    around it: one pixel whose rays were all blocked keeps its neighbours'
    share (and all its rays), a region without sky gets none."""
    w, h = 40, 20
    light = np.ones(w * h, np.float32)
    sky = np.zeros((h, w), np.float32)
    sky[:, :20] = 0.5                   # the left half: half of its light from the sky
    sky[10, 10] = 0.0                   # one pixel's rays all blocked
    stored = pixel_shares(sky.reshape(-1), light, w, h)
    assert stored.dtype == np.float16 and stored.shape == (w * h,)      # kept with the history
    share = stored.astype(np.float32).reshape(h, w)
    assert abs(share[10, 10] - 0.5 * 80 / 81) < 1e-3
    assert abs(share[5, 3] - 0.5) < 1e-3 and share[5, 35] == 0
    assert 0.2 < share[5, 19] < 0.3      # 5 of 9 columns lit
    counts, keep = point_plan(4, share.reshape(-1))
    assert counts.reshape(h, w)[10, 10] == 4 and keep.reshape(h, w)[5, 35] == SKY_KEEP_MIN
    assert (pixel_shares(sky.reshape(-1), np.zeros(w * h, np.float32), w, h) == 0).all()
