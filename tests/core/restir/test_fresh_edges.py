"""The direct light of fresh edge pixels (core/restir/fresh_edges.py): only
pixels whose direct light's history just restarted, at a sharp edge of
light, are filtered over their 3x3 pixels, and a range of rows gives what
the whole image gives."""

import numpy as np

from restir_gi.core.restir.accumulation import COLUMNS, LIGHT_FRAMES
from restir_gi.core.restir.fresh_edges import fresh_edge_direct

W, H = 12, 8


def means(frames):
    """Running means of a W x H image whose direct light is 10 left of
    column 6 and 0 from it on (a sunlit patch's edge), every pixel holding
    ``frames`` frames of it."""
    data = np.zeros((W * H, COLUMNS), np.float32)
    x = np.arange(W * H) % W
    data[x < 6, 0:3] = 10.0
    data[:, LIGHT_FRAMES] = frames
    return data


def test_only_fresh_pixels_at_an_edge_are_filtered():
    valid = np.ones(W * H, bool)
    old = means(16.0)
    np.testing.assert_array_equal(fresh_edge_direct(old, valid, W, H, 0, H), old[:, 0:3])
    new = fresh_edge_direct(means(1.0), valid, W, H, 0, H).reshape(H, W, 3)[..., 0]
    # The tent puts a quarter of the other side into each edge pixel.
    np.testing.assert_allclose(new[:, 5], 7.5, rtol=1e-6)
    np.testing.assert_allclose(new[:, 6], 2.5, rtol=1e-6)
    # Away from the edge, nothing to filter: the same values.
    np.testing.assert_array_equal(new[:, :5], 10.0)
    np.testing.assert_array_equal(new[:, 7:], 0.0)
    # The mean over a row is kept.
    np.testing.assert_allclose(new.sum(axis=1), 60.0, rtol=1e-6)


def test_pixels_that_see_nothing_are_neither_filtered_nor_read():
    data = means(1.0)
    valid = np.ones(W * H, bool)
    x = np.arange(W * H) % W
    valid[x == 6] = False           # a column of misses beside the edge
    data[~valid, 0:3] = 1e6         # (never read)
    new = fresh_edge_direct(data, valid, W, H, 0, H).reshape(H, W, 3)[..., 0]
    assert (new[:, :6] <= 10.0).all() and np.isfinite(new).all()
    np.testing.assert_array_equal(new[:, 6], 1e6)      # left as they are


def test_ranges_of_rows_give_the_whole_image():
    rng = np.random.default_rng(0)
    data = means(1.0)
    data[:, 0:3] *= rng.uniform(0.5, 1.5, (W * H, 1)).astype(np.float32)
    data[rng.random(W * H) < 0.3, LIGHT_FRAMES] = 16.0
    valid = rng.random(W * H) > 0.1
    whole = fresh_edge_direct(data, valid, W, H, 0, H)
    parts = np.concatenate([fresh_edge_direct(data, valid, W, H, a, b) for a, b in ((0, 3), (3, 4), (4, H))])
    np.testing.assert_array_equal(parts, whole)
