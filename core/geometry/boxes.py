"""Ray segments against axis-aligned boxes."""

import numpy as np


def crosses_box(o, d, limit, lo, hi):
    """Rays whose segment [0, limit] may touch the box [lo, hi] (slab test, one
    axis at a time on columns; conservative: NaNs count as crossing).
    limit: (N,) in units of d."""
    near = np.zeros(len(o), np.float32)
    far = np.array(limit, np.float32)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for k in range(3):
            inv = np.float32(1.0) / d[:, k]
            a = (lo[k] - o[:, k]) * inv
            b = (hi[k] - o[:, k]) * inv
            np.maximum(near, np.minimum(a, b), out=near)
            np.minimum(far, np.maximum(a, b), out=far)
        return ~(far < near)
