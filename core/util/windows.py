"""Sums over square windows of an image, for every pixel at once."""

import numpy as np


def window_sums(values, width, height, radius, mode="constant"):
    """(height, width) float64 sums of ``values`` (P,) over the (2 radius +
    1)^2 pixels around each pixel of a width x height image (cumulative
    sums); past the border the image is padded as np.pad's ``mode`` does
    ("constant": zeros, "edge": the border pixel)."""
    a = np.pad(np.asarray(values).reshape(height, width).astype(np.float64), radius, mode=mode)
    c = np.cumsum(np.cumsum(np.pad(a, ((1, 0), (1, 0))), axis=0), axis=1)
    k = 2 * radius + 1
    return c[k:, k:] - c[:-k, k:] - c[k:, :-k] + c[:-k, :-k]
