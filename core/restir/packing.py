"""Narrow encodings of what reservoirs store: unit vectors as octahedral
coordinates in 2 x int16 (a zero vector has a code of its own), radiance as
float16 saturating at its largest value."""

import numpy as np

ZERO = -32768                  # octahedral code of a zero vector (snorm16 uses +-32767)
F16_MAX = np.float32(65504.0)


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
    out[zero] = ZERO
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
    out[q[:, 0] == ZERO] = 0.0
    return out


def encode_radiance(lo):
    return np.minimum(lo, F16_MAX).astype(np.float16)
