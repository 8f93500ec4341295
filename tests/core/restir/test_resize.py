"""core/restir/resize.py: images carried to another resolution of the same view."""

import numpy as np

from restir_gi.core.restir.resize import nearest_rows, resize_image, upscale_bilinear


def test01_bilinear_keeps_constants_and_ramps():
    """A constant stays exact; a linear ramp across pixel centres is
    reproduced wherever the new pixel centres lie between the old ones
    (the clamped border pixels hold the edge values)."""
    const = np.full((5, 7, 4), 0.25, np.float32)
    out = upscale_bilinear(const, 14, 10)
    assert out.shape == (10, 14, 4) and out.dtype == np.float32
    np.testing.assert_array_equal(out, 0.25)
    x = np.arange(7, dtype=np.float32)
    ramp = np.broadcast_to(x[None, :, None], (5, 7, 1)).copy()
    out = upscale_bilinear(ramp, 28, 5)[..., 0]
    centres = (np.arange(28) + 0.5) * 7 / 28 - 0.5         # new centres in old pixel units
    inside = (centres >= 0) & (centres <= 6)
    np.testing.assert_allclose(out[:, inside], np.broadcast_to(centres[inside], (5, inside.sum())), atol=1e-5)
    np.testing.assert_allclose(out[:, ~inside], np.where(centres[~inside] < 0, 0.0, 6.0)[None, :].repeat(5, 0))


def test02_bilinear_same_size_is_a_copy_and_mean_is_kept():
    rng = np.random.default_rng(3)
    img = rng.random((16, 24, 3)).astype(np.float32)
    same = upscale_bilinear(img, 24, 16)
    np.testing.assert_array_equal(same, img)
    assert same is not img
    big = upscale_bilinear(img, 48, 32)
    # Twice the size: every old pixel's weight sums to 4 new pixels but for
    # the clamped border, so the mean moves only by the border's share.
    assert abs(big.mean() / img.mean() - 1) < 0.02


def test03_nearest_matches_resize_image():
    img = np.arange(6 * 4, dtype=np.float32).reshape(4, 6)
    out = resize_image(img, 12, 8)
    np.testing.assert_array_equal(out, img.ravel()[nearest_rows(6, 4, 12, 8)].reshape(8, 12))
    np.testing.assert_array_equal(out[::2, ::2], img)
