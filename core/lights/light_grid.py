"""Choosing among nearby emitters by where the shading point is.

Selecting emitters by power alone (core/lights/light_set.py) spends most shadow rays of
a room lit by thirty small lamps on lamps across the room: each is picked as
often from a point beside it as from a point far away. Cycles weighs its
emitters by distance and orientation with a light tree. Here a grid over the
scene's bounds holds, per cell, a distribution over clusters of emitters:
each cluster's power over (its distance to the cell squared + the cell's
half-diagonal squared), mixed with the power distribution (a share of
``DEFENSIVE``) so that no emitter's probability falls far below what power
alone gives it, whatever the grid misjudges (occlusion, orientation).
Within a cluster, emitters are chosen by power.

A cell is coarse: a wall point 2 cm from a small emissive cube and one
30 cm from it share a cell, and the cube's triangles got no more from the
first than any other nearby emitter (the corpus room of small emitters: the
facing triangle had 4 % of the choices and held most of the light, so NEE
near the cubes was the image's noise). So at each point of a cell with an
emitter within about a cell of it, a share ``LOCAL`` of the choice goes by
the point's own distance to and orientation toward the ``TOP`` clusters its
cell ranks highest (as a light tree's importance does, Conty Estevez and
Kulla 2018); elsewhere a point sees the emitters much as its cell does, and
the cell alone chooses.

The probability is a function of the shading point alone, so the pdf of an
emitter a BSDF-sampled ray found is known exactly (``pmf``), and NEE and
BSDF sampling still combine by multiple importance sampling.

Clusters are runs of emitters in Morton order of their centres (at most
``MAX_CLUSTERS``); cells are cubes, ``CELLS_LONG_AXIS`` along the scene's
longest axis (at most ``MAX_CELLS``). Plain arrays: the corpus room of small
emitters (360 triangles, 1,792 cells) builds in 0.07 s and its sampling
tables in 0.2 s on first use.
"""

import numpy as np

from ..sampling.warps import Distribution1D

MAX_CLUSTERS = 256  # one or two triangles each on the corpus room of 30 emissive cubes (360
                    # triangles); its direct light's variance per frame with 128 was 1.4x, with
                    # 512 0.93x (docs/plan.md)
CELLS_LONG_AXIS = 16
MAX_CELLS = CELLS_LONG_AXIS ** 3
DEFENSIVE = 0.2     # share of the choice by power alone, at every point
LOCAL = 0.5         # share of the choice by the point's own importance of its cell's top clusters
TOP = 16            # clusters a cell ranks highest, among which a point chooses by its own
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
        self._cone = None
        if spread is not None and (np.asarray(spread) < np.pi).any():
            self._cone = _cluster_cones(np.asarray(axis, np.float64)[order],
                                        np.asarray(spread, np.float64)[order], start, c_lo, c_hi)
            importance *= _facing(self._cone, 0.5 * (cell_lo + cell_hi),
                                  0.5 * np.linalg.norm(cell_hi - cell_lo, axis=1)[:, None])
        total = cluster_power.sum()
        by_power = cluster_power / total if total > 0 else np.full(k, 1.0 / k)
        norm = importance.sum(axis=1, keepdims=True)
        near = np.where(norm > 0, importance / np.where(norm > 0, norm, 1.0), by_power[None])
        # Per point: its importance of the cell's TOP clusters, from a table
        # per cell (C, 5, T) of their centres, half-diagonals squared and
        # powers (float32, one gather a point).
        self.top = np.argsort(-near, axis=1, kind="stable")[:, :min(TOP, k)]
        centre = 0.5 * (c_lo + c_hi)
        r2 = 0.25 * ((c_hi - c_lo) ** 2).sum(axis=1)
        columns = np.stack([centre[:, 0], centre[:, 1], centre[:, 2], r2, cluster_power])    # (5, K)
        self._top_table = np.ascontiguousarray(columns[:, self.top].transpose(1, 0, 2), np.float32)
        # Cells with a top cluster within their half-diagonal: only there do
        # a cell's points weigh its clusters differently enough to pay for it.
        nearest = np.take_along_axis((gap * gap).sum(axis=2), self.top, axis=1).min(axis=1)
        self._near_cell = nearest < 0.25 * float((cell_size ** 2).sum())
        # Power's share of the cell's own choice: DEFENSIVE, and in cells
        # where points take LOCAL by their own importance, as much more as
        # keeps every cluster DEFENSIVE x power over both parts (a cell
        # without that part choosing with the larger share was flatter:
        # bench/light_selection.py floors 0.24 -> 0.41).
        share = np.where(self._near_cell, DEFENSIVE / (1.0 - LOCAL), DEFENSIVE)[:, None]
        self.cell_pmf = (1.0 - share) * near + share * by_power[None]     # (C, K)
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

    def local_importance(self, p, cells, n=None):
        """Importance at points p of their cells' top clusters, for the points
        whose cell has an emitter within about a cell of it (elsewhere a
        point weighs them as its cell does, and the cell alone chooses):
        (rows, top (R, T) clusters, importance (R, T), total (N,) each
        point's sum, zero for the others). Importance: power over the
        squared distance to the cluster's centre plus its half-diagonal
        squared, times the cone's orientation bound and, with the points'
        unit normals n, the bound of the cosine at the receiving surface
        (either side of it: glass takes light from behind)."""
        rows = np.nonzero(np.take(self._near_cell, cells))[0]
        total = np.zeros(len(cells), np.float32)
        if len(rows) == len(cells):
            rows = slice(None)
        q, c = p[rows], cells[rows]
        table = np.take(self._top_table, c, axis=0)        # (R, 5, T)
        d2 = np.zeros(table.shape[::2], np.float32)
        along = None if n is None else np.zeros_like(d2)    # n . (centre - p)
        for axis in range(3):
            d = np.subtract(table[:, axis], q[:, axis:axis + 1], dtype=np.float32)
            if along is not None:
                along += d * n[rows, axis:axis + 1]
            d *= d
            d2 += d
        if along is not None:
            cos_r = _receiver_bound(along, d2, table[:, 3])
        d2 += table[:, 3]
        imp = np.divide(table[:, 4], d2, out=d2, where=d2 > 0)
        if along is not None:
            imp *= cos_r
        top = np.take(self.top, c, axis=0)
        if self._cone is not None:
            imp *= np.asarray(_facing(self._cone, q.astype(np.float64)[:, None, :], 0.0, top), np.float32)
        total[rows] = imp.sum(axis=1)
        return (np.arange(len(cells)) if isinstance(rows, slice) else rows), top, imp, total

    def sample(self, p, u, n=None):
        """(emitter index (N,), its probability (N,)) for points p, uniform u
        (N,) and, if given, the points' unit normals n (N, 3), which pmf must
        then be given too."""
        if self._prob is None:
            self._tables()
        cell = self.cells(p)
        rows, top, imp, total = self.local_importance(p, cell, n)
        u = np.asarray(u, np.float64)
        # Rows below LOCAL (with some importance) choose among their top
        # clusters by it, the others by the cell's table; either way the
        # rest of u picks the emitter within the cluster.
        by_point = np.nonzero((np.take(u, rows) < LOCAL) & (np.take(total, rows) > 0))[0]
        if LOCAL > 0:
            u_cell = np.where(total > 0, np.where(u < LOCAL, u / LOCAL, (u - LOCAL) / (1.0 - LOCAL)), u)
        else:
            u_cell = u
        x = u_cell * self.k
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
        if len(by_point):
            r = rows[by_point]
            cum = np.cumsum(imp[by_point], axis=1, dtype=np.float64)
            x = u_cell[r] * cum[:, -1]
            j = np.minimum((cum <= x[:, None]).sum(axis=1), cum.shape[1] - 1)
            at_j = np.arange(len(r))
            before = np.where(j > 0, cum[at_j, np.maximum(j - 1, 0)], 0.0)
            width = cum[at_j, j] - before
            cluster[r] = top[by_point, j]
            u2[r] = (x - before) / np.where(width > 0, width, 1.0)
        np.clip(u2, 0.0, 1.0 - 1e-12, out=u2)
        m = self._members.locate((cluster + u2) / self.k) - 1
        m = np.clip(m, np.take(self.cluster_start, cluster), np.take(self.cluster_last, cluster))
        light = np.take(self.members, m)
        return light, self._pmf(cell, cluster, rows, top, imp, total) * np.take(self.within, light)

    def _pmf(self, cell, cluster, rows, top, imp, total):
        """Probability (N,) of choosing clusters (N,) at points of cells (N,),
        given local_importance's (rows, top, imp, total)."""
        pmf = np.take(self._flat_pmf, cell * self.k + cluster)
        # Points with no importance among their top clusters choose by the cell alone.
        live = np.nonzero(np.take(total, rows) > 0)[0]
        if len(live):
            r = rows[live]
            mine = (imp[live] * (top[live] == cluster[r][:, None])).sum(axis=1) / total[r]
            pmf[r] = LOCAL * mine + (1.0 - LOCAL) * pmf[r]
        return pmf

    def pmf(self, light, p, cells=None, n=None):
        """Probability (N,) of choosing emitters ``light`` (N,) at points p (N, 3)
        (cells: their cells, if known; n: their normals, as sample had them)."""
        if self._prob is None:
            self._tables()
        if cells is None:
            cells = self.cells(p)
        cluster = np.take(self.cluster_of, light)
        return self._pmf(cells, cluster, *self.local_importance(p, cells, n)) * np.take(self.within, light)


def _receiver_bound(along, d2, r2):
    """Largest |cos| between a normal and any direction into a sphere of
    squared radius r2 whose centre lies at squared distance d2, along the
    normal by ``along`` (arrays of one shape, float32): 1 within the sphere
    or where it spans the normal's direction, else cos(phi - theta_u), phi
    the angle from the nearer of +-n to the centre and sin(theta_u) = r / d."""
    with np.errstate(invalid="ignore", divide="ignore"):
        inv = 1.0 / np.sqrt(d2)
        cos_phi = np.minimum(np.abs(along) * inv, 1.0)
        sin_phi = np.sqrt(np.maximum(1.0 - cos_phi * cos_phi, 0.0))
        sin_u = np.minimum(np.sqrt(r2) * inv, 1.0)
        cos_u = np.sqrt(np.maximum(1.0 - sin_u * sin_u, 0.0))
        bound = cos_phi * cos_u + sin_phi * sin_u
    # Inside the sphere, or the normal's direction within it (phi < theta_u).
    return np.where((d2 > r2) & (cos_phi < cos_u), bound, 1.0).astype(np.float32)


def _cluster_cones(axis, spread, start, c_lo, c_hi):
    """Each cluster's cone (members in cluster order, runs at start): mean
    axis (K, 3), the widest angle of a member's axis off it theta_o, the
    widest reach theta_e, whether all are Lambertian area emitters, the
    box's centre and half-diagonal."""
    omni = spread >= np.pi
    unit = axis / np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-30)
    cluster = np.repeat(np.arange(len(start)), np.diff(np.r_[start, len(axis)]))
    mean = np.add.reduceat(np.where(omni[:, None], 0.0, unit), start, axis=0)
    length = np.linalg.norm(mean, axis=1, keepdims=True)
    mean = mean / np.maximum(length, 1e-30)
    off = np.arccos(np.clip((unit * mean[cluster]).sum(axis=1), -1.0, 1.0))
    off = np.where(omni, np.pi, off)
    theta_o = np.maximum.reduceat(off, start)
    theta_o = np.where(length[:, 0] < 1e-6, np.pi, theta_o)
    theta_e = np.maximum.reduceat(spread, start)
    lambertian = np.minimum.reduceat(np.isclose(spread, 0.5 * np.pi), start).astype(bool)
    return (mean, theta_o, theta_e, lambertian, 0.5 * (c_lo + c_hi), 0.5 * np.linalg.norm(c_hi - c_lo, axis=1))


def _facing(cone, at, at_reach, top=None):
    """Bound of how much each cluster shines toward places ``at`` of
    half-diagonal at_reach: 0 where no member's cone reaches any point of
    the place, the cosine of the smallest angle it could make for clusters
    of area lights (Lambertian), 1 otherwise (Conty Estevez and Kulla's
    orientation bound, with the cluster's cone: the mean axis and the widest
    angle off it, plus the angle the two boxes subtend). For cells, at is
    (C, 3), at_reach (C, 1) and the result (C, K); for points with top (N, T) clusters, at
    is (N, 1, 3) and the result (N, T)."""
    mean, theta_o, theta_e, lambertian, c_mid, c_reach = cone
    if top is not None:
        mean, theta_o, theta_e, lambertian, c_mid, c_reach = (np.take(a, top, axis=0) for a in cone)
    else:
        at = at[:, None, :]
    reach = c_reach + at_reach
    v = at - c_mid
    dist = np.linalg.norm(v, axis=-1)
    cos_t = (v * mean).sum(axis=-1) / np.maximum(dist, 1e-30)
    theta = np.arccos(np.clip(cos_t, -1.0, 1.0))
    theta_u = np.where(dist > reach, np.arcsin(np.clip(reach / np.maximum(dist, 1e-30), 0.0, 1.0)), np.pi)
    rest = np.maximum(theta - theta_o - theta_u, 0.0)
    out = np.where(rest < theta_e, 1.0, 0.0)
    return np.where(lambertian, out * np.cos(np.minimum(rest, 0.5 * np.pi)), out)


def _morton(points, lo, size, bits=6):
    """Morton codes of points within the box lo + [0, size] (6 bits an axis:
    enough to order them into at most MAX_CLUSTERS runs)."""
    q = np.clip(((points - lo) / size * (1 << bits)).astype(np.int64), 0, (1 << bits) - 1)
    code = np.zeros(len(points), np.int64)
    for b in range(bits):
        for axis in range(3):
            code |= ((q[:, axis] >> b) & 1) << (3 * b + axis)
    return code
