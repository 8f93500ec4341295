"""Deterministic random numbers: a pure function of (path seed, dimension).

A path's seed is itself a hash of (render seed, frame, pixel, sample), so the
same settings always give the same image, and ReSTIR can re-trace a stored
path exactly by keeping its 64-bit seed (sample validation).

Each bounce owns a fixed block of dimensions, as pbrt's wavefront integrator
does, so adding a random decision at one bounce never shifts the others.
"""

import numpy as np

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_S30, _S27, _S31 = np.uint64(30), np.uint64(27), np.uint64(31)
_TO_UNIT = np.float32(1.0 / (1 << 24))

# Dimension layout.
DIM_CAMERA = 0            # pixel filter (2) + lens (2)
DIM_BOUNCE_BASE = 8       # first dimension used by bounce 0
DIMS_PER_BOUNCE = 8
# Offsets within a bounce's block.
D_LIGHT_SELECT = 0
D_LIGHT_UV = 1            # two dimensions
D_LOBE = 3
D_BSDF_UV = 4             # two dimensions
D_RR = 6


def mix64(x):
    """SplitMix64 finaliser: a bijective, well-avalanched 64-bit hash (arrays)."""
    x = np.array(x, dtype=np.uint64)    # a copy, worked on in place
    if x.ndim == 0:
        with np.errstate(over="ignore"):
            x = (x ^ (x >> _S30)) * _M1
            x = (x ^ (x >> _S27)) * _M2
        return x ^ (x >> _S31)
    t = np.empty_like(x)
    with np.errstate(over="ignore"):
        for shift, m in ((_S30, _M1), (_S27, _M2)):
            x ^= np.right_shift(x, shift, out=t)
            x *= m
    x ^= np.right_shift(x, _S31, out=t)
    return x


def hash_keys(*keys):
    """Combine integer keys (scalars or equally long arrays) into 64-bit seeds."""
    h = np.uint64(0x6A09E667F3BCC909)
    with np.errstate(over="ignore"):
        for k in keys:
            h = mix64(np.asarray(h, dtype=np.uint64) + _GOLDEN + np.asarray(k).astype(np.uint64))
    return np.asarray(h, dtype=np.uint64)


def path_seeds(seed, frame, pixel_index, sample):
    """One seed per path from the render seed, frame, pixel indices and sample number."""
    return hash_keys(seed, frame, sample, pixel_index)


def uniform(seeds, dim):
    """float32 uniforms in [0, 1) for each seed at dimension ``dim``."""
    with np.errstate(over="ignore"):
        h = mix64(seeds + np.uint64(dim + 1) * _GOLDEN)
    h >>= np.uint64(40)
    u = h.astype(np.float32)
    u *= _TO_UNIT
    return u


def uniform2(seeds, dim):
    """(N, 2) uniforms at dimensions dim and dim + 1."""
    seeds = np.asarray(seeds)
    if seeds.ndim != 1:
        return np.stack([uniform(seeds, dim), uniform(seeds, dim + 1)], axis=1)
    out = np.empty((len(seeds), 2), np.float32)
    out[:, 0] = uniform(seeds, dim)
    out[:, 1] = uniform(seeds, dim + 1)
    return out


def lens_uniforms(camera, seeds):
    """(N, 2) uniforms for the lens position of camera rays (the camera's
    dimensions after the pixel filter's), or None for a pinhole camera."""
    if getattr(camera, "aperture_size", 0.0) <= 0:
        return None
    return uniform2(seeds, DIM_CAMERA + 2)


# The R2 sequence (Roberts 2018): point k is frac(k * (1/g, 1/g^2)), g the
# plastic number. Any run of consecutive points covers the unit square evenly,
# wherever the run starts.
_R2 = (0.7548776662466927, 0.5698402909980532)


def sequence2(index, rotation):
    """(N, 2) float32 uniforms: point ``index`` (an integer, or one per row)
    of the R2 sequence, shifted toroidally by each row's ``rotation`` (N, 2)
    in [0, 1). With a rotation fixed per pixel and uniform, every point is
    uniform (averages stay unbiased), and a pixel's points over consecutive
    indices are spread evenly rather than at random (Cranley-Patterson)."""
    k = np.asarray(index, np.int64) % (1 << 40)
    k = k.astype(np.float64)[..., None] * np.array(_R2)
    point = (k - np.floor(k)).astype(np.float32)
    u = rotation + point
    u -= np.floor(u)
    return np.minimum(u, np.float32(0.99999994), out=u)


def bounce_dim(bounce, offset):
    return DIM_BOUNCE_BASE + bounce * DIMS_PER_BOUNCE + offset


def radical_inverse(k, base):
    """Van der Corput radical inverse of integers k (array) in ``base``, float64 in [0, 1)."""
    k = np.asarray(k, np.int64).copy()
    out = np.zeros(k.shape, np.float64)
    scale = 1.0 / base
    while (k > 0).any():
        out += (k % base) * scale
        k //= base
        scale /= base
    return out


def stratified_light_uniforms(k, count, shift_select, shift_uv):
    """Uniforms for sample k of ``count`` light samples at one point, spread so
    that the count samples cover light selection (k / count) and the light's
    surface (Halton bases 2 and 3) evenly, each set randomly rotated (toroidal
    shift) so every single sample is still uniform: averages stay unbiased.
    Returns (u_select (N,), u (N, 2)) float32 in [0, 1)."""
    top = np.float32(0.99999994)
    u_sel = np.mod(k / np.maximum(count, 1) + shift_select, 1.0)
    pattern = np.stack([radical_inverse(k, 2), radical_inverse(k, 3)], axis=1)
    u = np.mod(pattern + shift_uv, 1.0)
    return (np.minimum(u_sel, top).astype(np.float32), np.minimum(u, top).astype(np.float32))
