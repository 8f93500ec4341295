"""Row-wise vector helpers on (N, 3) float32 arrays: dot products,
normalisation, luminance, orthonormal frames and the changes of frame.

Spelled for numpy's speed on (N, 3) rows (see rows.py): whole-array
products, then the three strided columns; column-by-column scaling instead
of ``a * s[:, None]``.
"""

import numpy as np

from .rows import divide, scale


def dot(a, b):
    """Row-wise dot product of (N, 3) arrays."""
    ab = a * b          # one pass over the rows, then ((x + y) + z) as before
    return ab[:, 0] + ab[:, 1] + ab[:, 2]


def normalize(v):
    """Row-wise normalisation; zero vectors stay zero instead of turning NaN."""
    n = np.sqrt(dot(v, v))
    return divide(v, np.where(n > 0, n, 1).astype(v.dtype, copy=False))


def luminance(rgb):
    """Rec.709 luminance of (..., 3) linear RGB (Blender's default working space)."""
    # Column sums rather than a matrix product: BLAS stalls on a loaded machine.
    rgb = np.asarray(rgb)
    return (np.float32(0.2126) * rgb[..., 0] + np.float32(0.7152) * rgb[..., 1]
            + np.float32(0.0722) * rgb[..., 2])


def orthonormal_basis(n):
    """Tangent and bitangent for unit normals n (Duff et al. 2017, branchless)."""
    n0, n1, n2 = n[:, 0], n[:, 1], n[:, 2]
    sign = np.where(n2 >= 0, np.float32(1), np.float32(-1))
    a = -1.0 / (sign + n2)
    b = n0 * n1 * a
    t = np.stack([1.0 + sign * n0 ** 2 * a, sign * b, -sign * n0], axis=1)
    bt = np.stack([b, sign + n1 ** 2 * a, -n1], axis=1)
    return t.astype(np.float32, copy=False), bt.astype(np.float32, copy=False)


def to_world(local, t, b, n):
    """Local (x along t, y along b, z along n) to world directions."""
    if not (t.shape == b.shape == n.shape == local.shape and local.ndim == 2
            and local.dtype == t.dtype == b.dtype == n.dtype):
        return local[:, 0:1] * t + local[:, 1:2] * b + local[:, 2:3] * n
    out = scale(t, local[:, 0])     # core/util/rows.py: column-wise, same sums in the same order
    out += scale(b, local[:, 1])
    out += scale(n, local[:, 2])
    return out


def to_local(w, t, b, n):
    return np.stack([dot(w, t), dot(w, b), dot(w, n)], axis=1)
