"""A sun's own light sample at the visible points (LightSet.nee_sets): the
sets' structure, and the direct light's mean and variance against choosing
the sun among the other emitters by power."""

import dataclasses

import numpy as np
import pytest

from restir_gi.core import RenderContext
from restir_gi.core.camera.projection import PixelFilter
from restir_gi.core.lights.light_set import SUNS_APART, LightSet
from restir_gi.core.restir.gbuffer import trace_gbuffer
from restir_gi.core.restir.initial import InitialSampling, initial_samples
from restir_gi.core.scene import LIGHT_AREA, LIGHT_SUN, Lights
from restir_gi.core.util.vectors import luminance
from support.scenes import cornell_box, path_samples

AREA = {"kind": LIGHT_AREA, "position": (0, 0, 1.98), "direction": (0, 0, -1), "power": (60.0,) * 3,
        "size_u": 0.5, "size_v": 0.5}


def sun(direction=(0.0, 0.6, -0.8), power=4.0, angle=0.5):
    d = np.asarray(direction, np.float64)
    return {"kind": LIGHT_SUN, "direction": tuple(d / np.linalg.norm(d)), "power": (power,) * 3, "angle": angle}


def box(rows, world=None, size=16):
    """The Cornell box (open toward the camera, which the sun shines in
    through) lit by ``rows``."""
    scene = cornell_box("area", size, size)
    scene = dataclasses.replace(scene, lights=Lights.from_list(rows))
    if world is not None:
        scene = dataclasses.replace(scene, world_color=world)
    scene.filter_width = 0.0
    return scene


def test01_sets_take_the_suns_apart():
    ls = LightSet(box([AREA, sun(), AREA | {"position": (0.5, 0.5, 1.98)}]))
    others, alone = ls.nee_sets()
    assert len(ls.nee_sets()) == 2
    pmf = others.distribution.pmf
    assert pmf[1] == 0 and np.isclose(pmf.sum(), 1.0)
    assert np.isclose(alone.distribution.pmf[1], 1.0) and np.isclose(alone.distribution.pmf.sum(), 1.0)
    # Sampling one set never picks another's emitter.
    rng = np.random.default_rng(1)
    p = rng.uniform(-0.9, 0.9, (4096, 3)).astype(np.float32)
    p[:, 2] = 0.5
    u = rng.random((4096, 2)).astype(np.float32)
    assert set(np.unique(others.sample(p, rng.random(4096).astype(np.float32), u).index)) <= {0, 2}
    assert set(np.unique(alone.sample(p, rng.random(4096).astype(np.float32), u).index)) == {1}


@pytest.mark.parametrize("rows", [[sun()], [sun()] * (SUNS_APART + 1) + [AREA], [AREA]])
def test02_a_sun_alone_or_many_suns_keep_one_set(rows):
    ls = LightSet(box(rows))
    assert ls.nee_sets() == [ls]


def runs(scene, count, apart):
    """Luminance of the direct light of the visible points over ``count``
    independent frames, (count, points)."""
    how = InitialSampling(0, light_samples=1)
    ctx = RenderContext.build(scene)
    patch = pytest.MonkeyPatch()
    try:
        if not apart:       # the sun chosen among the lamps by power
            patch.setattr(LightSet, "nee_sets", lambda self: [self])
        gb = trace_gbuffer(ctx, 0, 0, PixelFilter(0.0), jitter=False)
        return np.stack([luminance(initial_samples(ctx, gb, 5, f, 0, how)[1])[gb.index]
                         for f in range(count)]).astype(np.float64)
    finally:
        patch.undo()
        ctx.close()


@pytest.mark.slow
def test03_direct_light_keeps_its_mean_and_loses_the_suns_noise():
    """A box lit by a lamp and by a sun through its open side: the sum of
    one sample of each set has the mean of one sample chosen among all, and
    far less variance where the sun does not reach. Measured (16x16, 384
    frames): z = -0.51, variance where the sun is hidden 0.106 of the
    choice's (47 % of the pixels)."""
    apart, chosen = (runs(box([AREA, sun()]), 384, way) for way in (True, False))
    hidden = runs(box([sun()]), 64, False).max(axis=0) == 0     # no sample of the sun alone lit them
    a, b = apart.sum(axis=1), chosen.sum(axis=1)
    z = (a.mean() - b.mean()) / np.sqrt(a.var(ddof=1) / len(a) + b.var(ddof=1) / len(b))
    ratio = apart.var(axis=0, ddof=1)[hidden].sum() / chosen.var(axis=0, ddof=1)[hidden].sum()
    print(f"suns apart: z = {z:.2f}, variance where the sun is hidden {ratio:.3f} of the choice's "
          f"({hidden.mean():.0%} of the pixels)")
    assert abs(z) < 3.3
    assert 0.2 < hidden.mean() < 0.9
    assert ratio < 0.3


@pytest.mark.slow
def test04_path_tracing_keeps_its_mean_and_loses_the_suns_noise(monkeypatch):
    """Paths (camera_pass: every bounce's NEE) with suns apart against the
    sun chosen among the lamps: the image's mean agrees, and the variance of
    the pixels' paths falls. Measured (16x16, 3 bounces, 96 samples): z =
    0.24, variance per pixel 0.49 of the choice's."""
    scene = box([AREA, sun()])
    apart = path_samples(scene, 96, 3)
    monkeypatch.setattr(LightSet, "nee_sets", lambda self: [self])
    chosen = path_samples(scene, 96, 3)
    apart, chosen = (x.mean(axis=1).reshape(96, -1) for x in (apart, chosen))    # (sample, pixel)
    a, b = apart.mean(axis=1), chosen.mean(axis=1)      # one image mean per sample
    z = (a.mean() - b.mean()) / np.sqrt(a.var(ddof=1) / len(a) + b.var(ddof=1) / len(b))
    ratio = apart.var(axis=0).sum() / chosen.var(axis=0).sum()
    print(f"paths with suns apart: z = {z:.2f}, variance {ratio:.2f} of the choice's")
    assert abs(z) < 3.3
    assert ratio < 0.8


@pytest.mark.slow
def test05_paths_through_fog_keep_their_mean(monkeypatch):
    """The same through a world volume (core/integrators/media_path.py: NEE
    at surface and medium points): the image's mean agrees with the sun
    chosen among the lamps, and the variance falls less than on surfaces
    (the fog's own scattering is most of it). Measured (16x16, 3 bounces,
    96 samples): z = 0.47, variance per pixel 0.87 of the choice's."""
    scene = box([AREA, sun()])
    scene.world_volume = {"sigma_a": (0.05,) * 3, "sigma_s": (0.3,) * 3, "emission": (0.0,) * 3, "g": 0.3}
    apart = path_samples(scene, 96, 3)
    monkeypatch.setattr(LightSet, "nee_sets", lambda self: [self])
    chosen = path_samples(scene, 96, 3)
    apart, chosen = (x.mean(axis=1).reshape(96, -1) for x in (apart, chosen))
    a, b = apart.mean(axis=1), chosen.mean(axis=1)
    z = (a.mean() - b.mean()) / np.sqrt(a.var(ddof=1) / len(a) + b.var(ddof=1) / len(b))
    ratio = apart.var(axis=0).sum() / chosen.var(axis=0).sum()
    print(f"fog with suns apart: z = {z:.2f}, variance {ratio:.2f} of the choice's")
    assert abs(z) < 3.3
    assert ratio < 0.95
