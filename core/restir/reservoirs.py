"""Reservoirs of ReSTIR GI as struct-of-arrays, one row per pixel.

A reservoir holds one chosen *sample* (a secondary surface point x2 with its
outgoing radiance and the seed of the path that estimated it) and the
resampling state: w_sum (sum of resampling weights), M (number of candidates
seen, a float so it can be capped and scaled) and W (the unbiased contribution
weight of the chosen sample, in solid angle at the owning pixel's visible point).

Weighted reservoir sampling over whole images: ``merge`` streams one candidate
per row into every row at once, choosing it with probability w / w_sum.

Whole-image storage (``StoredReservoirs``): reservoirs in narrow types, what
a frame keeps for the next.
The passes compute on float32 ``Reservoirs`` of their pixel range; the whole
image's temporal and spatial reservoirs are stored here and read back by row:

- unit vectors (the sample's geometric and shading normals, its direction
  back to the point that found it) as octahedral coordinates in 2 x int16
  (angular error below 1e-4 rad; a zero vector has a code of its own);
- the sample's radiance as float16 (relative rounding 2^-11, absolute 2^-25
  below 6e-5; values above float16's largest, 65504, are stored as that);
- the sample's age as int16 (saturating: ages are compared with max_age).

Positions, weights, counts and seeds keep their types: reuse compares
positions at scene scale and sums weights over many frames.

Images below NARROW_MIN_PIXELS keep float32 ``Reservoirs`` instead: there the
state is small and decoding it was about 8 % of a 320x180 frame.
"""

from dataclasses import dataclass, fields

import numpy as np

from ..util.rows import gather, scatter
from ..util.vectors import luminance
from .packing import ZERO, decode_unit, encode_radiance, encode_unit


@dataclass
class SampleView:
    """The fields of gathered rows that resampling weights need (no copies of the rest)."""
    x2: np.ndarray
    ng2: np.ndarray
    lo: np.ndarray
    prim2: np.ndarray
    W: np.ndarray
    M: np.ndarray

    @property
    def has_sample(self):
        return self.prim2 != Reservoirs.NO_SAMPLE

    def view(self, index):
        """The rows at an index array (copies)."""
        return sample_view(self, index)


def sample_view(src, index):
    """SampleView of the rows of ``src`` (Reservoirs or SampleView) at an index array."""
    return SampleView(gather(src.x2, index), gather(src.ng2, index), gather(src.lo, index),
                      np.take(src.prim2, index), np.take(src.W, index), np.take(src.M, index))


@dataclass
class Reservoirs:
    # --- the chosen sample -------------------------------------------------
    x2: np.ndarray      # (N, 3) sample point
    ng2: np.ndarray     # (N, 3) geometric normal at x2, facing the visible point that found it
    n2: np.ndarray      # (N, 3) shading normal at x2
    wo2: np.ndarray     # (N, 3) direction from x2 back toward the point that found it
    prim2: np.ndarray   # (N,) int32 triangle at x2 (its material: scene.material_ids);
                        # NO_SAMPLE, or WORLD_SAMPLE for the sky
    lo: np.ndarray      # (N, 3) outgoing radiance of x2 (path traced, NEE + MIS)
    seed: np.ndarray    # (N,) uint64 seed of the path from x2 (for validation)
    kind: np.ndarray    # (N,) int8 kind of the sample ray (integrators/bounces.py): the
                        # path from x2 counted it as its first bounce (for validation)
    age: np.ndarray     # (N,) int32 frames since the sample was created
    # --- resampling state --------------------------------------------------
    w_sum: np.ndarray   # (N,)
    M: np.ndarray       # (N,) float32
    W: np.ndarray       # (N,)

    NO_SAMPLE = -1
    WORLD_SAMPLE = -2   # the ray escaped: x2 is a far point in its direction, lo the world
    SAMPLE_FIELDS = ("x2", "ng2", "n2", "wo2", "prim2", "lo", "seed", "kind", "age")

    def __len__(self):
        return len(self.M)

    @staticmethod
    def empty(n):
        z3 = lambda: np.zeros((n, 3), np.float32)  # noqa: E731
        z1 = lambda: np.zeros(n, np.float32)  # noqa: E731
        return Reservoirs(x2=z3(), ng2=z3(), n2=z3(), wo2=z3(), prim2=np.full(n, -1, np.int32),
                          lo=z3(), seed=np.zeros(n, np.uint64), kind=np.zeros(n, np.int8),
                          age=np.zeros(n, np.int32), w_sum=z1(), M=z1(), W=z1())

    def field(self, name, index):
        """One field of the rows at an index array (a copy)."""
        return gather(getattr(self, name), index)

    def put(self, index, other):
        """Rows at an index array = the rows of other, in place."""
        for f in fields(self):
            scatter(getattr(self, f.name), index, getattr(other, f.name))

    def write_rows(self, start, stop, other):
        """Rows [start, stop) = other's rows, in place."""
        for f in fields(self):
            getattr(self, f.name)[start:stop] = getattr(other, f.name)

    def whole_image(self, n):
        """Where Workers.map_into gathers ranges' reservoirs: for images of
        NARROW_MIN_PIXELS or more the narrow store, below it
        float32 rows like these (whole_image)."""
        return whole_image(n)

    def take(self, index):
        """Rows gathered by an index array (a copy)."""
        return Reservoirs(**{f.name: gather(getattr(self, f.name), index) for f in fields(self)})

    def view(self, index):
        """SampleView of rows gathered by an index array."""
        return sample_view(self, index)

    def rows(self, start, stop):
        """Rows [start, stop) as views (no copy)."""
        return Reservoirs(**{f.name: getattr(self, f.name)[start:stop] for f in fields(self)})

    def copy(self):
        return Reservoirs(**{f.name: getattr(self, f.name).copy() for f in fields(self)})

    def assign(self, mask, other):
        """Overwrite rows where mask is True with the same rows of other."""
        for f in fields(self):
            dst = getattr(self, f.name)
            dst[mask] = getattr(other, f.name)[mask]

    def drop(self, rows):
        """Zero the weights and counts of rows (validation: a changed sample)."""
        self.M[rows] = 0
        self.W[rows] = 0
        self.w_sum[rows] = 0

    def clear(self, mask):
        """Forget the rows where mask is True."""
        self.w_sum[mask] = 0
        self.M[mask] = 0
        self.W[mask] = 0
        self.lo[mask] = 0
        self.prim2[mask] = -1

    @property
    def valid(self):
        return self.has_sample & (self.W > 0)

    @property
    def has_sample(self):
        return self.prim2 != Reservoirs.NO_SAMPLE

    @property
    def nbytes(self):
        return sum(getattr(self, f.name).nbytes for f in fields(self))


def target(lo):
    """Luminance of a sample's radiance: the factor of ReSTIR GI's target
    function that does not depend on the receiving point (see restir/shift.py)."""
    return np.maximum(luminance(lo), 0.0).astype(np.float32)


def merge(dst, src, weight, M_src, u, index=None):
    """Stream one candidate per row into dst, in place.

    src: Reservoirs with the candidates (same length as dst); weight: their
    resampling weights (0 where the candidate is worthless here); M_src: how
    many candidates each stands for (0 where a row has no candidate: a
    zero-weight candidate still counts in M); u: uniforms deciding replacement;
    index: if given, row i's candidate is src row index[i] (src is then any
    length: only the rows that win are gathered).
    Returns the mask of rows whose chosen sample was replaced.
    """
    w = np.where(np.isfinite(weight) & (weight > 0), weight, 0.0).astype(np.float32)
    dst.w_sum += w
    dst.M += np.asarray(M_src, np.float32)
    take = (w > 0) & (u * dst.w_sum < w)
    rows = np.nonzero(take)[0]
    if len(rows):
        src_rows = rows if index is None else index[rows]
        for name in Reservoirs.SAMPLE_FIELDS:
            scatter(getattr(dst, name), rows, gather(getattr(src, name), src_rows))
    return take


def finalize(res, p_hat, Z=None):
    """Set W = w_sum / (Z p_hat(y)), with Z = M (biased 1/M) unless given (1/Z);
    p_hat: the owner's target function at each row's chosen sample."""
    z = res.M if Z is None else Z
    den = z * p_hat
    with np.errstate(invalid="ignore", divide="ignore"):
        W = np.where(den > 0, res.w_sum / np.where(den > 0, den, 1.0), 0.0)
    res.W[:] = np.where(np.isfinite(W), W, 0.0)
    return res


def cap_history(res, cap):
    """Bound M, scaling w_sum with it, so old history keeps a bounded weight."""
    over = res.M > cap
    if over.any():
        scale = np.where(over, cap / np.maximum(res.M, 1e-30), 1.0).astype(np.float32)
        res.w_sum *= scale
        res.M *= scale
    return res


def choose(weights, u):
    """Weighted reservoir sampling of C candidates per row in one step: the same
    choice as C streamed merges (candidate c with probability w_c / sum w),
    with the sample fields then gathered once instead of at every merge.

    weights: list of C (N,) non-negative resampling weights; u: (N,) uniforms.
    Returns (choice (N,) int, -1 where every weight is zero; w_sum (N,)).
    """
    clean = [np.where(np.isfinite(w) & (w > 0), w, 0.0).astype(np.float32) for w in weights]
    w_sum = np.zeros(len(u), np.float32)
    for w in clean:
        w_sum += w
    threshold = u * w_sum
    choice = np.zeros(len(u), np.int64)
    last = np.full(len(u), -1, np.int64)        # last candidate with weight, for rounding at the top
    acc = np.zeros(len(u), np.float32)
    for c, w in enumerate(clean):
        acc += w
        choice += acc <= threshold
        last[w > 0] = c
    choice = np.where(choice >= len(clean), last, choice)
    return np.where(w_sum > 0, choice, -1), w_sum


# --- whole-image storage --------------------------------------------------

# Images of at least this many pixels store their reservoirs narrowed; below
# it the 36 bytes per pixel and reservoir saved cost more time than they are
# worth (docs/memory.md).
NARROW_MIN_PIXELS = 1 << 20

_DIRECTIONS = ("ng2", "n2", "wo2")


def whole_image(n):
    """The whole-image reservoirs of an image of n pixels (empty)."""
    return StoredReservoirs.empty(n) if n >= NARROW_MIN_PIXELS else Reservoirs.empty(n)


def bytes_per_row(pixels, kept=False):
    """Bytes per pixel of the whole-image reservoirs of an image of ``pixels``
    pixels; kept: as kept for the next frame (narrow ones without w_sum)."""
    if pixels >= NARROW_MIN_PIXELS:
        return StoredReservoirs.bytes_per_row(kept)
    return Reservoirs.empty(1).nbytes


@dataclass
class StoredReservoirs:
    """Reservoirs of a whole image, narrowed (module docstring); read rows
    with take/rows/field, write them with write_rows/put."""
    x2: np.ndarray      # (P, 3) float32
    ng2_oct: np.ndarray  # (P, 2) int16
    n2_oct: np.ndarray  # (P, 2) int16
    wo2_oct: np.ndarray  # (P, 2) int16
    prim2: np.ndarray   # (P,) int32
    lo16: np.ndarray    # (P, 3) float16
    seed: np.ndarray    # (P,) uint64
    kind: np.ndarray    # (P,) int8
    age: np.ndarray     # (P,) int16
    w_sum: np.ndarray   # (P,) float32; None once the frame is done (nothing reads it after)
    M: np.ndarray       # (P,) float32
    W: np.ndarray       # (P,) float32

    NO_SAMPLE = Reservoirs.NO_SAMPLE
    WORLD_SAMPLE = Reservoirs.WORLD_SAMPLE

    @staticmethod
    def empty(n):
        return StoredReservoirs(
            x2=np.zeros((n, 3), np.float32), ng2_oct=np.full((n, 2), ZERO, np.int16),
            n2_oct=np.full((n, 2), ZERO, np.int16), wo2_oct=np.full((n, 2), ZERO, np.int16),
            prim2=np.full(n, -1, np.int32), lo16=np.zeros((n, 3), np.float16),
            seed=np.zeros(n, np.uint64), kind=np.zeros(n, np.int8), age=np.zeros(n, np.int16),
            w_sum=np.zeros(n, np.float32), M=np.zeros(n, np.float32), W=np.zeros(n, np.float32))

    @staticmethod
    def bytes_per_row(kept=False):
        """Bytes per pixel; kept: as kept for the next frame (without w_sum)."""
        return StoredReservoirs.empty(1).nbytes - (4 if kept else 0)

    def keep_for_next_frame(self):
        """Let go of w_sum: the next frame starts every reservoir's sum of
        weights over (temporal.py, spatial.py) and reads only W and M."""
        self.w_sum = None

    def __len__(self):
        return len(self.M)

    @property
    def nbytes(self):
        return sum(getattr(self, f.name).nbytes for f in fields(self) if getattr(self, f.name) is not None)

    # --- reading -----------------------------------------------------------
    def field(self, name, index):
        """One field of the rows at an index array (or slice), as Reservoirs holds it."""
        if name in _DIRECTIONS:
            return decode_unit(self._rows(getattr(self, name + "_oct"), index))
        if name == "lo":
            return self._rows(self.lo16, index).astype(np.float32)
        if name == "age":
            return self._rows(self.age, index).astype(np.int32)
        if name == "w_sum" and self.w_sum is None:
            return np.zeros(len(self._rows(self.M, index)), np.float32)
        return self._rows(getattr(self, name), index)

    @staticmethod
    def _rows(a, index):
        return a[index] if isinstance(index, slice) else gather(a, index)

    def take(self, index):
        """float32 Reservoirs of the rows at an index array (a copy)."""
        return Reservoirs(**{f.name: self.field(f.name, index) for f in fields(Reservoirs)})

    def view(self, index):
        """SampleView of the rows at an index array (what resampling weights read)."""
        return SampleView(*(self.field(name, index) for name in ("x2", "ng2", "lo", "prim2", "W", "M")))

    def rows(self, start, stop):
        """float32 Reservoirs of rows [start, stop) (a copy)."""
        return self.take(slice(start, stop))

    @property
    def lo(self):
        """(P, 3) float32 radiance of the whole image (a copy)."""
        return self.lo16.astype(np.float32)

    @property
    def ng2(self):
        """(P, 3) float32 geometric normals at the samples (a copy)."""
        return decode_unit(self.ng2_oct)

    @property
    def n2(self):
        return decode_unit(self.n2_oct)

    @property
    def wo2(self):
        return decode_unit(self.wo2_oct)

    @property
    def has_sample(self):
        return self.prim2 != Reservoirs.NO_SAMPLE

    @property
    def valid(self):
        return self.has_sample & (self.W > 0)

    def copy(self):
        return StoredReservoirs(**{f.name: None if getattr(self, f.name) is None else getattr(self, f.name).copy()
                                   for f in fields(self)})

    # --- writing -----------------------------------------------------------
    def _store(self, key, res):
        for f in fields(Reservoirs):
            value = getattr(res, f.name)
            if f.name in _DIRECTIONS:
                getattr(self, f.name + "_oct")[key] = encode_unit(value)
            elif f.name == "lo":
                self.lo16[key] = encode_radiance(value)
            elif f.name == "age":
                self.age[key] = np.minimum(value, 32767)
            elif f.name == "w_sum" and self.w_sum is None:
                continue
            else:
                getattr(self, f.name)[key] = value

    def write_rows(self, start, stop, res):
        """Rows [start, stop) = the float32 Reservoirs res (Workers.map_into)."""
        self._store(slice(start, stop), res)

    def put(self, index, res):
        """Rows at an index array = the float32 Reservoirs res."""
        self._store(index, res)

    def drop(self, rows):
        """Zero the weights and counts of rows (validation: a changed sample)."""
        self.M[rows] = 0
        self.W[rows] = 0
        if self.w_sum is not None:
            self.w_sum[rows] = 0

    def clear(self, mask):
        """Forget the rows where mask is True."""
        if self.w_sum is not None:
            self.w_sum[mask] = 0
        self.M[mask] = 0
        self.W[mask] = 0
        self.lo16[mask] = 0
        self.prim2[mask] = -1


def distinct(*sets):
    """The reservoir sets, each once (without spatial reuse the spatial
    reservoirs are the temporal ones)."""
    return [r for i, r in enumerate(sets) if all(r is not other for other in sets[:i])]
