"""The boiling filter (core/restir/boiling.py): a reservoir far brighter than
its 16x16 tile is emptied; ordinary variation is left alone."""

import numpy as np

from restir_gi.core.restir.reservoirs import Reservoirs
from restir_gi.core.restir.boiling import boiling_filter, boiling_threshold_multiple


def image_reservoirs(weights):
    """Reservoirs with white radiance, W = weight (luminance(Lo) W = weight)."""
    n = weights.size
    res = Reservoirs.empty(n)
    res.lo[:] = 1.0
    res.W[:] = weights.ravel()
    res.M[:] = 1.0
    res.w_sum[:] = weights.ravel()
    res.prim2[:] = 0
    return res


def test01_threshold_is_rtxdi_multiple():
    assert np.isclose(boiling_threshold_multiple(0.2), 41.0)
    assert np.isclose(boiling_threshold_multiple(1.0), 1.0)


def test02_a_lone_bright_reservoir_is_emptied():
    rng = np.random.default_rng(1)
    w = rng.uniform(0.5, 1.5, (40, 50)).astype(np.float32)     # several tiles, partial edge tiles
    w[20, 37] = 500.0
    w[3, 3] = 0.0                                              # empty pixels do not lower the mean
    res = image_reservoirs(w)
    boil = boiling_filter(res, 50, 40, 0.2)
    assert np.nonzero(boil)[0].tolist() == [20 * 50 + 37]
    assert not res.has_sample[20 * 50 + 37] and res.M[20 * 50 + 37] == 0
    assert res.has_sample.sum() == w.size - 1


def test03_ordinary_noise_and_strength_zero_keep_everything():
    rng = np.random.default_rng(2)
    w = rng.exponential(1.0, (32, 32)).astype(np.float32)      # heavy-ish tail, within 41x of the mean
    w = np.minimum(w, 30.0)
    assert not boiling_filter(image_reservoirs(w), 32, 32, 0.2).any()
    w[5, 5] = 1e4
    assert not boiling_filter(image_reservoirs(w), 32, 32, 0.0).any()
    assert boiling_filter(image_reservoirs(w), 32, 32, 0.2)[5 * 32 + 5]


def test04_tiles_are_local():
    """A value bright for a dim tile is emptied there, but the same value in a
    bright tile is not."""
    w = np.full((16, 32), 0.1, np.float32)
    w[:, 16:] = 10.0
    w[8, 8] = 50.0      # 500x its tile's mean
    w[8, 24] = 50.0     # 5x its tile's mean
    boil = boiling_filter(image_reservoirs(w), 32, 16, 0.2)
    assert np.nonzero(boil)[0].tolist() == [8 * 32 + 8]
