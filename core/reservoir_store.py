"""Whole-image reservoirs in narrow types: what a frame keeps for the next.

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

from .reservoirs import Reservoirs, SampleView
from .rows import gather

# Images of at least this many pixels store their reservoirs narrowed; below
# it the 36 bytes per pixel and reservoir saved cost more time than they are
# worth (docs/memory.md).
NARROW_MIN_PIXELS = 1 << 20

_ZERO = -32768                  # octahedral code of a zero vector (snorm16 uses +-32767)
_F16_MAX = np.float32(65504.0)
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


def encode_unit(v):
    """(N, 3) unit (or zero) vectors -> (N, 2) int16 octahedral coordinates."""
    v = np.asarray(v, np.float32)
    a = np.abs(v)
    s = a[:, 0] + a[:, 1] + a[:, 2]
    zero = ~(s > 0)
    inv = 1.0 / np.where(zero, 1.0, s)
    x, y = v[:, 0] * inv, v[:, 1] * inv
    lower = v[:, 2] < 0
    sx = np.where(x >= 0, 1.0, -1.0).astype(np.float32)
    sy = np.where(y >= 0, 1.0, -1.0).astype(np.float32)
    ox = np.where(lower, (1.0 - np.abs(y)) * sx, x)
    oy = np.where(lower, (1.0 - np.abs(x)) * sy, y)
    out = np.empty((len(v), 2), np.int16)
    out[:, 0] = np.rint(np.clip(ox, -1.0, 1.0) * 32767.0)
    out[:, 1] = np.rint(np.clip(oy, -1.0, 1.0) * 32767.0)
    out[zero] = _ZERO
    return out


def decode_unit(q):
    """(N, 2) int16 octahedral coordinates -> (N, 3) float32 unit vectors."""
    x = q[:, 0].astype(np.float32) * np.float32(1.0 / 32767.0)
    y = q[:, 1].astype(np.float32) * np.float32(1.0 / 32767.0)
    z = 1.0 - np.abs(x) - np.abs(y)
    t = np.maximum(-z, 0.0)
    x = x - np.where(x >= 0, t, -t)
    y = y - np.where(y >= 0, t, -t)
    inv = 1.0 / np.sqrt(np.maximum(x * x + y * y + z * z, 1e-30))
    out = np.empty((len(q), 3), np.float32)
    out[:, 0], out[:, 1], out[:, 2] = x * inv, y * inv, z * inv
    out[q[:, 0] == _ZERO] = 0.0
    return out


def encode_radiance(lo):
    return np.minimum(lo, _F16_MAX).astype(np.float16)


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
            x2=np.zeros((n, 3), np.float32), ng2_oct=np.full((n, 2), _ZERO, np.int16),
            n2_oct=np.full((n, 2), _ZERO, np.int16), wo2_oct=np.full((n, 2), _ZERO, np.int16),
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
