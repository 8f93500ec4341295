"""Boiling filter: drop reservoirs whose weight towers over their neighbourhood.

Reuse spreads a rare bright sample (a path that found a small bright light) to
every pixel that accepts it, and temporal reuse keeps it for many frames: a
growing blotch that "boils" instead of averaging out. As in RTXDI, a reservoir
whose weight luminance(Lo) W exceeds a multiple of the mean nonzero weight of
its 16x16 pixel tile is emptied; the multiple is 10 / strength - 9 (41 at the
default strength 0.2; strength 0 turns the filter off).
"""

import numpy as np

from .reservoirs import target

TILE = 16


def boiling_threshold_multiple(strength):
    return 10.0 / min(max(strength, 1e-6), 1.0) - 9.0


def boiling_filter(res, width, height, strength):
    """Empty, in place, the reservoirs of a whole image (row-major pixels) that
    boil at this strength; returns the mask of those emptied."""
    n = width * height
    if strength <= 0 or n == 0 or len(res) != n:
        return np.zeros(len(res), bool)
    weight = np.where(res.has_sample, target(res.lo) * res.W, 0.0).astype(np.float32)
    weight[~np.isfinite(weight)] = 0
    # Sums and counts of nonzero weights per 16x16 tile (edge tiles are smaller).
    ty, tx = -(-height // TILE), -(-width // TILE)
    tile = (np.arange(height) // TILE)[:, None] * tx + (np.arange(width) // TILE)[None, :]
    tile = tile.ravel()
    sums = np.bincount(tile, weights=weight, minlength=ty * tx)
    counts = np.bincount(tile, weights=(weight > 0).astype(np.float64), minlength=ty * tx)
    mean = sums / np.maximum(counts, 1.0)
    boil = weight > boiling_threshold_multiple(strength) * np.take(mean, tile)
    if boil.any():
        res.clear(boil)
    return boil
