"""Choosing among nearby emitters by where the shading point is.

Selecting emitters by power alone (core/lights.py) spends most shadow rays of
a room lit by thirty small lamps on lamps across the room: each is picked as
often from a point beside it as from a point far away. Cycles weighs its
emitters by distance and orientation with a light tree. Here a grid over the
scene's bounds holds, per cell, a distribution over clusters of emitters:
each cluster's power over (its distance to the cell squared + the cell's
half-diagonal squared), mixed with the power distribution (a share of
``DEFENSIVE``) so that no emitter's probability falls far below what power
alone gives it, whatever the grid misjudges (occlusion, orientation).
Within a cluster, emitters are chosen by power.

The probability depends only on the shading point's cell, so the pdf of an
emitter a BSDF-sampled ray found is known exactly (``pmf``), and NEE and
BSDF sampling still combine by multiple importance sampling.

Clusters are runs of emitters in Morton order of their centres (at most
``MAX_CLUSTERS``); cells are cubes, ``CELLS_LONG_AXIS`` along the scene's
longest axis (at most ``MAX_CELLS``). Plain arrays, built in a few ms.
"""

import numpy as np

from .sampling import Distribution1D

MAX_CLUSTERS = 64
CELLS_LONG_AXIS = 16
MAX_CELLS = CELLS_LONG_AXIS ** 3
DEFENSIVE = 0.2
USEFUL = 0.05


class LightGrid:
    """Per-cell selection among L emitters of powers ``power`` (L,) whose
    bounds are (box_lo, box_hi) (L, 3), for points within (lo, hi)."""

    def __init__(self, lo, hi, power, box_lo, box_hi, axis=None, spread=None):
        """axis (L, 3), spread (L,): the direction each emitter shines
        along and the half-angle it reaches from it (a spot's half cone, pi/2
        for an area light, pi or None: every way)."""
        power = np.asarray(power, np.float64)
        box_lo, box_hi = np.array(box_lo, np.float64), np.array(box_hi, np.float64)
        self.count = len(power)
        lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
        if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
            lo = hi = np.zeros(3)               # one cell: power alone
        # An emitter of no finite place could be anywhere: the whole scene.
        lost = ~(np.isfinite(box_lo).all(axis=1) & np.isfinite(box_hi).all(axis=1))
        box_lo[lost], box_hi[lost] = lo, hi
        size = np.maximum(hi - lo, 1e-6 * max(float((hi - lo).max()), 1e-3))
        cell = size.max() / CELLS_LONG_AXIS    # at most 16 cells an axis: MAX_CELLS in all
        dims = np.clip(np.ceil(size / cell - 1e-9), 1, CELLS_LONG_AXIS).astype(np.int64)
        self.lo = lo
        self.dims = dims
        self.inv_cell = (dims / size).astype(np.float64)
        self._lo32 = self.lo.astype(np.float32)
        self._inv32 = self.inv_cell.astype(np.float32)
        self._top32 = (self.dims - 1).astype(np.float32)
        self._strides = np.array([self.dims[1] * self.dims[2], self.dims[2], 1], np.int64)

        # Clusters: equal runs of emitters along a Morton curve of their centres.
        centre = 0.5 * (box_lo + box_hi)
        order = np.argsort(_morton(centre, lo, size), kind="stable")
        k = min(self.count, MAX_CLUSTERS)
        cluster_of_sorted = (np.arange(self.count) * k) // max(self.count, 1)
        self.cluster_of = np.empty(self.count, np.int64)
        self.cluster_of[order] = cluster_of_sorted
        cluster_power = np.bincount(self.cluster_of, power, minlength=k)
        self.within = np.where(cluster_power[self.cluster_of] > 0,
                               power / np.maximum(cluster_power[self.cluster_of], 1e-300), 0.0)
        # Emitters in cluster order; the runs of clusters (first, last).
        self.members = order
        start = np.searchsorted(cluster_of_sorted, np.arange(k))
        last = np.r_[start[1:] - 1, self.count - 1]
        self.cluster_start, self.cluster_last = start, last
        # Weights whose cdf over the runs is (cluster + cdf within it) / k: a
        # cluster that emits nothing spreads its unit evenly (never chosen).
        run = (last - start + 1).astype(np.float64)
        self._run_weights = np.where(cluster_power[cluster_of_sorted] > 0, self.within[order],
                                     1.0 / run[cluster_of_sorted])

        # Per cell: importance of each cluster (power over squared distance
        # from the cell's box to the cluster's) mixed with power alone.
        c_lo = np.minimum.reduceat(box_lo[order], start, axis=0)      # clusters are runs of order
        c_hi = np.maximum.reduceat(box_hi[order], start, axis=0)
        ijk = np.stack(np.meshgrid(*[np.arange(n) for n in dims], indexing="ij"), -1).reshape(-1, 3)
        cell_size = size / dims
        cell_lo = lo + ijk * cell_size
        cell_hi = cell_lo + cell_size
        gap = np.maximum(0.0, np.maximum(c_lo[None] - cell_hi[:, None], cell_lo[:, None] - c_hi[None]))
        d2 = (gap * gap).sum(axis=2) + 0.25 * float((cell_size ** 2).sum())
        importance = cluster_power[None] / d2
        if spread is not None and (np.asarray(spread) < np.pi).any():
            importance *= _facing(np.asarray(axis, np.float64)[order], np.asarray(spread, np.float64)[order],
                                  start, c_lo, c_hi, cell_lo, cell_hi)
        total = cluster_power.sum()
        by_power = cluster_power / total if total > 0 else np.full(k, 1.0 / k)
        norm = importance.sum(axis=1, keepdims=True)
        near = np.where(norm > 0, importance / np.where(norm > 0, norm, 1.0), by_power[None])
        self.cell_pmf = (1.0 - DEFENSIVE) * near + DEFENSIVE * by_power[None]     # (C, K)
        # Worth its cost where some cell's choice differs from power's by
        # more than USEFUL in total variation (not so for one lamp's
        # triangles, or lamps far from everything).
        self.useful = bool(0.5 * np.abs(self.cell_pmf - by_power[None]).sum(axis=1).max() > USEFUL)
        self.k = k
        self._prob = None           # the sampling tables, built on first use

    def _tables(self):
        """Alias tables of the cells' distributions over clusters (Vose's
        method, run for every cell at once: a smallest entry under one is
        paired with the largest each step), so that a row's cluster takes two
        gathers instead of a binary search, whose mispredicted branches cost
        8 ms per 57,600 rows. Emitters within a cluster: Distribution1D's
        table over the clusters' runs."""
        cells, k = self.cell_pmf.shape
        q = self.cell_pmf * k
        prob = np.ones((cells, k))
        alias = np.tile(np.arange(k), (cells, 1))
        lows, highs = q.copy(), q.copy()        # q, with finished entries out of reach
        rows = np.arange(cells)
        for _ in range(k - 1):
            small = np.argmin(lows, axis=1)
            large = np.argmax(highs, axis=1)
            go = (lows[rows, small] < 1.0) & (small != large)
            r, s_, l_ = rows[go], small[go], large[go]
            if not len(r):
                break
            prob[r, s_] = q[r, s_]
            alias[r, s_] = l_
            q[r, l_] -= 1.0 - q[r, s_]
            lows[r, l_] = highs[r, l_] = q[r, l_]
            lows[r, s_], highs[r, s_] = np.inf, -np.inf
        self._prob = prob.ravel()
        self._alias = alias.ravel()
        self._flat_pmf = self.cell_pmf.ravel()
        self._members = Distribution1D(self._run_weights)

    def cells(self, p):
        """Flat cell index (N,) of points p (N, 3); points outside (and NaN)
        fall in the border cells. Column by column: numpy broadcasts a (3,)
        row over (N, 3) with an inner loop of three, some 7x slower."""
        out = None
        for axis in range(3):
            c = np.subtract(p[:, axis], self._lo32[axis], dtype=np.float32)
            c *= self._inv32[axis]
            np.fmin(np.fmax(c, np.float32(0), out=c), self._top32[axis], out=c)
            index = c.astype(np.int64)
            if out is None:
                out = index * self._strides[axis]
            else:
                if self._strides[axis] != 1:
                    index *= self._strides[axis]
                out += index
        return out

    def sample(self, p, u):
        """(emitter index (N,), its probability (N,)) for points p and uniform u (N,)."""
        if self._prob is None:
            self._tables()
        cell = self.cells(p)
        x = np.asarray(u, np.float64) * self.k
        slot = np.minimum(x.astype(np.int64), self.k - 1)
        coin = x - slot                                     # uniform in [0, 1) again
        at = cell * self.k + slot
        prob = np.take(self._prob, at)
        keep = coin < prob
        cluster = np.where(keep, slot, np.take(self._alias, at))
        # Where coin fell within its part of the slot: uniform again, for the
        # emitter within the cluster.
        u2 = np.where(keep, coin / np.where(prob > 0, prob, 1.0),
                      (coin - prob) / np.where(prob < 1.0, 1.0 - prob, 1.0))
        np.clip(u2, 0.0, 1.0 - 1e-12, out=u2)
        m = self._members.locate((cluster + u2) / self.k) - 1
        m = np.clip(m, np.take(self.cluster_start, cluster), np.take(self.cluster_last, cluster))
        light = np.take(self.members, m)
        pmf = np.take(self._flat_pmf, cell * self.k + cluster) * np.take(self.within, light)
        return light, pmf

    def pmf(self, light, p=None, cells=None):
        """Probability (N,) of choosing emitters ``light`` (N,) at points p (or their cells)."""
        if self._prob is None:
            self._tables()
        if cells is None:
            cells = self.cells(p)
        return np.take(self._flat_pmf, cells * self.k + np.take(self.cluster_of, light)) \
            * np.take(self.within, light)


def _facing(axis, spread, start, c_lo, c_hi, cell_lo, cell_hi):
    """(C, K) bound of how much each cluster shines toward each cell: 0
    where no member's cone reaches any point of the cell, the cosine of the
    smallest angle it could make for clusters of area lights (Lambertian),
    1 otherwise (Conty Estevez and Kulla's orientation bound, with the
    cluster's cone: the mean axis and the widest angle off it, plus the
    angle the two boxes subtend). Members in cluster order; runs at start."""
    omni = spread >= np.pi
    unit = axis / np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-30)
    mean = np.add.reduceat(np.where(omni[:, None], 0.0, unit), start, axis=0)
    length = np.linalg.norm(mean, axis=1, keepdims=True)
    mean = mean / np.maximum(length, 1e-30)
    cluster = np.repeat(np.arange(len(start)), np.diff(np.r_[start, len(axis)]))
    off = np.arccos(np.clip((unit * mean[cluster]).sum(axis=1), -1.0, 1.0))
    off = np.where(omni, np.pi, off)
    theta_o = np.maximum.reduceat(off, start)
    theta_o = np.where(length[:, 0] < 1e-6, np.pi, theta_o)
    theta_e = np.maximum.reduceat(spread, start)
    lambertian = np.minimum.reduceat(np.isclose(spread, 0.5 * np.pi), start).astype(bool)
    c_mid, cell_mid = 0.5 * (c_lo + c_hi), 0.5 * (cell_lo + cell_hi)
    reach = 0.5 * (np.linalg.norm(c_hi - c_lo, axis=1)[None] + np.linalg.norm(cell_hi - cell_lo, axis=1)[:, None])
    v = cell_mid[:, None] - c_mid[None]                             # (C, K, 3)
    dist = np.linalg.norm(v, axis=2)
    cos_t = (v * mean[None]).sum(axis=2) / np.maximum(dist, 1e-30)
    theta = np.arccos(np.clip(cos_t, -1.0, 1.0))
    theta_u = np.where(dist > reach, np.arcsin(np.clip(reach / np.maximum(dist, 1e-30), 0.0, 1.0)), np.pi)
    rest = np.maximum(theta - theta_o[None] - theta_u, 0.0)
    out = np.where(rest < theta_e[None], 1.0, 0.0)
    return np.where(lambertian[None], out * np.cos(np.minimum(rest, 0.5 * np.pi)), out)


def _morton(points, lo, size, bits=6):
    """Morton codes of points within the box lo + [0, size] (6 bits an axis:
    enough to order them into at most MAX_CLUSTERS runs)."""
    q = np.clip(((points - lo) / size * (1 << bits)).astype(np.int64), 0, (1 << bits) - 1)
    code = np.zeros(len(points), np.int64)
    for b in range(bits):
        for axis in range(3):
            code |= ((q[:, axis] >> b) & 1) << (3 * b + axis)
    return code
