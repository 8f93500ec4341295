"""Row operations on (N, k) struct-of-arrays buffers, written for numpy's speed.

numpy's own spellings of these are slow for short rows: ``a[idx]`` on an
(N, 3) array, ``out[idx] = v``, ``a.max(axis=1)`` and ``np.isfinite(a).all(axis=1)``
loop over rows of three in an inner loop of three, several times slower than
the same work as whole columns or as one item per row. Every hot pass uses
these instead (bench/bench_path.py measures the frame).
"""

import numpy as np


def gather(a, index):
    """Rows of ``a`` at an integer index array (a copy): a[index]."""
    return np.take(a, index, axis=0)


def _as_items(a):
    """View of a C-contiguous (N, ...) array as N opaque items, one per row."""
    return a.view(np.dtype((np.void, a.dtype.itemsize * int(np.prod(a.shape[1:], dtype=np.int64))))) \
        .reshape(a.shape[0])


def scatter(out, index, values):
    """out[index] = values, for integer indices, in place (rows moved as items)."""
    if out.ndim == 1 or not out.flags.c_contiguous or len(index) == 0:
        out[index] = values
        return out
    values = np.ascontiguousarray(np.broadcast_to(values, (len(index),) + out.shape[1:]), out.dtype)
    _as_items(out)[index] = _as_items(values)
    return out


def scatter_add(out, index, values):
    """out[index] += values for integer indices without repeats, in place."""
    if len(index) == 0:
        return out
    return scatter(out, index, gather(out, index) + values)


def row_max(a):
    """Largest of the three columns of each row of an (N, 3) array."""
    return np.maximum(np.maximum(a[:, 0], a[:, 1]), a[:, 2])


def rows_finite(a):
    """True for the rows of an (N, 3) array whose three entries are all finite."""
    f = np.isfinite(a)
    return f[:, 0] & f[:, 1] & f[:, 2]



def _by_column(op, a, s):
    """op(a, s[:, None]) for an (N, k) array and (N,) values, column by column."""
    a, s = np.asarray(a), np.asarray(s)
    if a.ndim != 2 or s.ndim != 1 or len(a) != len(s):
        return op(a, s[:, None])
    out = np.empty(a.shape, np.result_type(a.dtype, s.dtype))
    for k in range(a.shape[1]):
        op(a[:, k], s, out=out[:, k])
    return out


def scale(a, s):
    """a * s[:, None] for an (N, 3) array and (N,) factors."""
    return _by_column(np.multiply, a, s)


def divide(a, s):
    """a / s[:, None] for an (N, 3) array and (N,) divisors."""
    return _by_column(np.divide, a, s)


def matmul3(a, m):
    """a @ m for (N, 3) rows and a 3x3 (or 3-vector) m, as column sums.

    numpy hands ``@`` to BLAS, whose threads stall for tens of milliseconds on
    a loaded machine; three columns of multiply-adds never do."""
    m = np.asarray(m)
    if m.ndim == 1:
        return a[:, 0] * m[0] + a[:, 1] * m[1] + a[:, 2] * m[2]
    return np.stack([a[:, 0] * m[0, j] + a[:, 1] * m[1, j] + a[:, 2] * m[2, j]
                     for j in range(m.shape[1])], axis=1)
