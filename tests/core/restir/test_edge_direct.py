"""More camera rays for the direct light at its edges where its history is
short (core/restir/edge_direct.py).

- The pixels chosen: edges of the direct light (by their neighbours, never
  by their own value) whose history is short.
- E(x_0) is the initial samples' own next-event estimate, to the rounding:
  the control variate cancels what it should.
- The refined direct light has the unrefined one's mean (z-test over
  frames, lamps that the sample rays find too) and far less variance at
  silhouettes.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from restir_gi.core import RenderContext
from restir_gi.core.camera.projection import PixelFilter
from restir_gi.core.restir.accumulation import COLUMNS, LIGHT_FRAMES
from restir_gi.core.restir.adaptive_direct import neighbourhood_range
from restir_gi.core.restir import edge_direct
from restir_gi.core.restir.edge_direct import (SHORT_FRAMES, edge_pixels, history_frames, own_nee,
                                               refine_direct_edges)
from restir_gi.core.restir.gbuffer import trace_gbuffer
from restir_gi.core.restir.initial import COSINE, InitialSampling, initial_samples
from restir_gi.core.util.vectors import luminance
from support.scenes import cornell_box

W = H = 24
FILTER = PixelFilter(1.5)


def test01_edges_are_chosen_by_neighbours_and_short_history():
    w, h = 12, 6
    lum = np.where(np.arange(w * h) % w < 6, 4.0, 0.0).astype(np.float32)     # lit left half
    short = np.zeros(w * h, np.float32)
    col = np.arange(w * h) % w
    edges = edge_pixels(lum, short, w, h)
    assert set(col[edges]) == {5, 6}
    assert len(edge_pixels(lum, np.full(w * h, SHORT_FRAMES + 1, np.float32), w, h)) == 0
    # A pixel's own value does not decide whether it is refined.
    for p in (5, 6, 20, 2):
        bent = lum.copy()
        bent[p] = 100.0 - bent[p]
        assert (p in edge_pixels(bent, short, w, h)) == (p in edges)
    # The history's frames are read at last frame's pixel.
    data = np.zeros((4, COLUMNS), np.float32)
    data[:, LIGHT_FRAMES] = [1, 2, 3, 16]
    np.testing.assert_array_equal(history_frames(np.array([3, -1, 0, 2]), data), [16, 0, 1, 3])


@pytest.fixture(scope="module")
def point_box():
    scene = cornell_box("point", W, H, radius=0.0)     # a point lamp: no sample ray finds it
    ctx = RenderContext.build(scene)
    yield ctx
    ctx.close()


@pytest.mark.parametrize("stream", [None, 5])
def test02_own_estimate_is_the_initial_samples_next_event_part(point_box, stream):
    ctx = point_box
    seed, frame = 7, 3
    gb = trace_gbuffer(ctx, seed, frame, FILTER, jitter=True, stream_index=stream if stream is not None else 0)
    n = W * H
    counts = np.where(np.arange(n) % 3 == 0, 4, 1)
    direct = initial_samples(ctx, gb, seed, frame, 0, InitialSampling(0, light_samples=counts[gb.index]),
                             stream_index=stream)[1]
    pixels = np.arange(n)
    own = own_nee(ctx, seed, frame, FILTER, pixels, stream if stream is not None else 0, stream is not None,
                  lambda rows: counts[rows], COSINE)
    assert luminance(direct).sum() > 0
    np.testing.assert_allclose(own, direct, rtol=2e-4, atol=1e-6)


@pytest.fixture(scope="module")
def area_box():
    ctx = RenderContext.build(cornell_box("area", W, H))    # sample rays find the lamp: MIS
    yield ctx
    ctx.close()


def test03_refined_direct_light_keeps_its_mean_with_less_variance(area_box, monkeypatch):
    monkeypatch.setattr(edge_direct, "MAX_SHARE", 1.0)    # a small image: every edge
    ctx = area_box
    seed, n, frames = 11, W * H, 48
    how = InitialSampling(0, light_samples=1)
    plain, refined, chosen = [], [], None
    for f in range(frames):
        gb = trace_gbuffer(ctx, seed, f, FILTER, jitter=True, stream_index=f)
        direct = initial_samples(ctx, gb, seed, f, 0, how, stream_index=f)[1]
        first = SimpleNamespace(direct=direct.copy(), lum_direct=luminance(direct).astype(np.float32),
                                prev_pix=np.full(n, -1, np.int32), hold=None)
        if chosen is None:
            # Refine a fixed set of pixels every frame: the silhouettes
            # that frame 0's light shows (edge_pixels would choose anew).
            mx, mn = neighbourhood_range(first.lum_direct, None, W, H, centre=False)
            chosen = np.flatnonzero(mx - mn > 0.3 * mx)
        done = refine_direct_edges(ctx, seed, f, FILTER, first, SimpleNamespace(data=np.zeros((n, COLUMNS))),
                                   f, True, how)
        assert np.isfinite(first.direct).all() and (first.direct >= 0).all()
        untouched = np.setdiff1d(np.arange(n), done)
        np.testing.assert_array_equal(first.direct[untouched], direct[untouched])
        plain.append(luminance(direct)[chosen])
        refined.append(np.where(np.isin(chosen, done), luminance(first.direct)[chosen], np.nan))
    plain, refined = np.array(plain), np.array(refined)
    both = ~np.isnan(refined).any(axis=0)
    assert both.sum() > 20
    plain, refined = plain[:, both], refined[:, both]
    diff = (refined - plain).mean(axis=1)           # per frame: expectation zero
    z = diff.mean() / (diff.std(ddof=1) / np.sqrt(frames))
    assert abs(z) < 4.0, (diff.mean(), z)
    assert abs(refined.mean() / plain.mean() - 1.0) < 0.03
    assert refined.var(axis=0).mean() < 0.3 * plain.var(axis=0).mean()
