"""Noise Texture (1D to 4D; fBM, multifractal, hetero terrain, hybrid and
ridged multifractal) as Cycles computes it, so patterns line up with
Cycles' renders of the same file (Voronoi: nodes_voronoi.py).

Gradient noise on the integer lattice (Perlin's "improved" gradients chosen
by Bob Jenkins' lookup3 hash of the cell corner), quintic fade, scaled by
0.982 into [-1, 1]; fractal Brownian motion over ``Detail`` octaves of
``Lacunarity`` frequency steps and ``Roughness`` amplitude steps, the
fractional last octave blended in, normalised to [0, 1]; ``Distortion``
offsets the point by three noises first; Color's green and blue are the same
fBM at two fixed offsets. 4D noise (the W input, as for animated noise)
interpolates 16 corners with Cycles' 4D gradients and hash, 1D and 2D noise
2 and 4 with theirs (each dimension has its own scale); the other types sum
or multiply the same octaves as Cycles' fractal noise.
All on uint32 and float32 arrays, the whole batch at once.
"""

import numpy as np

from .evaluate import f32, node, varying

_U32 = np.uint32


def _rot(x, k):
    return (x << _U32(k)) | (x >> _U32(32 - k))


def _final(a, b, c):
    """lookup3's final mix of three uint32 arrays; returns c."""
    c = (c ^ b) - _rot(b, 14)
    a = (a ^ c) - _rot(c, 11)
    b = (b ^ a) - _rot(a, 25)
    c = (c ^ b) - _rot(b, 16)
    a = (a ^ c) - _rot(c, 4)
    b = (b ^ a) - _rot(a, 14)
    c = (c ^ b) - _rot(b, 24)
    return c


def hash_uint3(x, y, z):
    init = _U32(0xDEADBEEF + (3 << 2) + 13)
    with np.errstate(over="ignore"):
        return _final(init + x.astype(_U32), init + y.astype(_U32), init + z.astype(_U32))


def _mix(a, b, c):
    """lookup3's mix of three uint32 arrays (new arrays)."""
    a = (a - c) ^ _rot(c, 4)
    c = c + b
    b = (b - a) ^ _rot(a, 6)
    a = a + c
    c = (c - b) ^ _rot(b, 8)
    b = b + a
    a = (a - c) ^ _rot(c, 16)
    c = c + b
    b = (b - a) ^ _rot(a, 19)
    a = a + c
    c = (c - b) ^ _rot(b, 4)
    b = b + a
    return a, b, c


def hash_uint4(x, y, z, w):
    init = _U32(0xDEADBEEF + (4 << 2) + 13)
    with np.errstate(over="ignore"):
        a, b, c = _mix(init + x.astype(_U32), init + y.astype(_U32), init + z.astype(_U32))
        return _final(a + w.astype(_U32), b, c)


def hash_uint(x):
    init = _U32(0xDEADBEEF + (1 << 2) + 13)
    with np.errstate(over="ignore"):
        full = np.full(np.shape(x), init, _U32)
        return _final(init + np.asarray(x, _U32), full, full.copy())


def hash_uint2(x, y):
    init = _U32(0xDEADBEEF + (2 << 2) + 13)
    with np.errstate(over="ignore"):
        return _final(init + np.asarray(x, _U32), init + np.asarray(y, _U32), np.full(np.shape(x), init, _U32))


def _float_bits(v):
    return np.asarray(v, np.float32).view(_U32)


_U32_MAX = np.float32(4294967295.0)


def hash_floats(*columns):
    """Cycles' hash_floatN_to_float of float32 columns (N,) each (N = 1 to
    4): lookup3 of their bits, in [0, 1]."""
    bits = [np.ascontiguousarray(np.asarray(c, np.float32)).view(_U32) for c in columns]
    h = (hash_uint, hash_uint2, hash_uint3, hash_uint4)[len(bits) - 1](*bits)
    return (h.astype(np.float32) / _U32_MAX).astype(np.float32)


def hash_floats_to_colour(columns):
    """(N, 3) Cycles' hash_floatN_to_float3 of N float32 columns: the hash of
    the columns, then (N < 4) of the columns with 1 and with 2 appended, or
    (4D) of the columns reordered (z, x, w, y) and (w, z, y, x)."""
    if len(columns) == 4:
        x, y, z, w = columns
        parts = [hash_floats(x, y, z, w), hash_floats(z, x, w, y), hash_floats(w, z, y, x)]
    else:
        salt = [np.full(len(columns[0]), k, np.float32) for k in (1.0, 2.0)]
        parts = [hash_floats(*columns), hash_floats(*columns, salt[0]), hash_floats(*columns, salt[1])]
    return np.stack(parts, axis=1)


def random_offset(seed, dims=3):
    """Cycles' random_float3_offset (random_float4_offset with dims 4): a
    fixed shift in [100, 200)^dims per seed."""
    s = _float_bits(np.float32(seed))
    if dims == 1:       # random_float_offset: a hash of the seed alone
        return np.float32([100.0 + float(hash_uint(s)) / 4294967295.0 * 100.0])
    out = [100.0 + float(hash_uint2(s, _float_bits(np.float32(k)))) / 4294967295.0 * 100.0 for k in range(dims)]
    return np.float32(out)


def _snoise1(p):
    """Cycles' 1D Perlin noise: gradients 1..8 of either sign, scaled into about [-1, 1]."""
    x = p[:, 0]
    fl = np.floor(x)
    i = fl.astype(np.int64).astype(np.int32).view(_U32)
    f = x - fl

    def grad(h, t):
        h = h & _U32(15)
        g = (_U32(1) + (h & _U32(7))).astype(np.float32)
        return np.where((h & 8) != 0, -g, g) * t

    a, b = grad(hash_uint(i), f), grad(hash_uint(i + _U32(1)), f - 1.0)
    r = a + _fade(f) * (b - a)
    return (0.25 * np.where(np.isfinite(r), r, 0.0)).astype(np.float32)


def _snoise2(p):
    """Cycles' 2D Perlin noise (4 corners), scaled into about [-1, 1]."""
    fl = np.floor(p)
    i = fl.astype(np.int64).astype(np.int32).view(_U32)
    f = p - fl
    fx, fy = f[:, 0], f[:, 1]
    X, Y = i[:, 0], i[:, 1]
    one = _U32(1)

    def grad(h, x, y):
        h = h & _U32(7)
        u = np.where(h < 4, x, y)
        v = 2.0 * np.where(h < 4, y, x)
        return np.where((h & 1) != 0, -u, u) + np.where((h & 2) != 0, -v, v)

    u, v = _fade(fx), _fade(fy)
    x0 = grad(hash_uint2(X, Y), fx, fy)
    x0 = x0 + u * (grad(hash_uint2(X + one, Y), fx - 1.0, fy) - x0)
    x1 = grad(hash_uint2(X, Y + one), fx, fy - 1.0)
    x1 = x1 + u * (grad(hash_uint2(X + one, Y + one), fx - 1.0, fy - 1.0) - x1)
    r = x0 + v * (x1 - x0)
    return (0.6616 * np.where(np.isfinite(r), r, 0.0)).astype(np.float32)


def _grad4(h, x, y, z, w):
    h = h & _U32(31)
    u = np.where(h < 24, x, y)
    v = np.where(h < 16, y, z)
    s = np.where(h < 8, z, w)
    return np.where((h & 1) != 0, -u, u) + np.where((h & 2) != 0, -v, v) + np.where((h & 4) != 0, -s, s)


def _snoise4(p):
    """Cycles' 4D Perlin noise (16 lattice corners), scaled into about [-1, 1]."""
    fl = np.floor(p)
    i = fl.astype(np.int64).astype(np.int32).view(_U32)
    f = p - fl
    fade = [_fade(f[:, k]) for k in range(4)]

    def corner(dx, dy, dz, dw):
        cell = [i[:, 0] + _U32(dx), i[:, 1] + _U32(dy), i[:, 2] + _U32(dz), i[:, 3] + _U32(dw)]
        return _grad4(hash_uint4(*cell), f[:, 0] - dx, f[:, 1] - dy, f[:, 2] - dz, f[:, 3] - dw)

    def lerp(t, a, b):
        return a + t * (b - a)

    def along(axis, offsets):
        """Interpolate the corners below ``axis`` with the lower axes free."""
        if axis < 0:
            return corner(*offsets)
        lo = along(axis - 1, offsets[:axis] + (0,) + offsets[axis + 1:])
        hi = along(axis - 1, offsets[:axis] + (1,) + offsets[axis + 1:])
        return lerp(fade[axis], lo, hi)

    r = along(3, (0, 0, 0, 0))
    r = np.where(np.isfinite(r), r, 0.0)
    return (0.8344 * r).astype(np.float32)


def _grad(h, x, y, z):
    h = h & _U32(15)
    u = np.where(h < 8, x, y)
    vt = np.where((h == 12) | (h == 14), x, z)
    v = np.where(h < 4, y, vt)
    return np.where((h & 1) != 0, -u, u) + np.where((h & 2) != 0, -v, v)


def _fade(t):
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


def snoise(p):
    """Signed Perlin noise of points (N, D), D = 1 to 4, in about [-1, 1]."""
    with np.errstate(over="ignore"):
        p = f32(p)
        return (_snoise1, _snoise2, _snoise, _snoise4)[p.shape[-1] - 1](p)


def _snoise(p):
    fl = np.floor(p)
    i = fl.astype(np.int64).astype(np.int32).view(_U32)
    f = p - fl
    fx, fy, fz = f[:, 0], f[:, 1], f[:, 2]
    X, Y, Z = i[:, 0], i[:, 1], i[:, 2]
    one = _U32(1)
    X1, Y1, Z1 = X + one, Y + one, Z + one
    u, v, w = _fade(fx), _fade(fy), _fade(fz)

    def g(a, b, c, dx, dy, dz):
        return _grad(hash_uint3(a, b, c), fx - dx, fy - dy, fz - dz)

    def lerp(t, a, b):
        return a + t * (b - a)

    x00 = lerp(u, g(X, Y, Z, 0, 0, 0), g(X1, Y, Z, 1, 0, 0))
    x10 = lerp(u, g(X, Y1, Z, 0, 1, 0), g(X1, Y1, Z, 1, 1, 0))
    x01 = lerp(u, g(X, Y, Z1, 0, 0, 1), g(X1, Y, Z1, 1, 0, 1))
    x11 = lerp(u, g(X, Y1, Z1, 0, 1, 1), g(X1, Y1, Z1, 1, 1, 1))
    r = lerp(w, lerp(v, x00, x10), lerp(v, x01, x11))
    r = np.where(np.isfinite(r), r, 0.0)
    return (0.982 * r).astype(np.float32)


def fbm(p, detail, roughness, lacunarity, normalize=True):
    """Fractal Brownian motion of snoise (Cycles' noise_fbm), per point."""
    detail = np.clip(f32(detail), 0.0, 15.0)
    roughness = np.maximum(f32(roughness), 0.0)
    lacunarity = f32(lacunarity)
    n = len(p)
    octaves = int(np.floor(np.max(detail))) if detail.size else 0
    fscale = np.ones(n, np.float32)
    amp = np.ones(n, np.float32)
    maxamp = np.zeros(n, np.float32)
    total = np.zeros(n, np.float32)
    whole = np.floor(np.broadcast_to(detail, (n,)))
    for k in range(octaves + 1):
        active = k <= whole
        t = snoise(p * fscale[:, None])
        total = total + np.where(active, t * amp, 0.0)
        maxamp = maxamp + np.where(active, amp, 0.0)
        amp = np.where(active, amp * roughness, amp)
        fscale = np.where(active, fscale * lacunarity, fscale)
    rmd = np.broadcast_to(detail, (n,)) - whole
    t = snoise(p * fscale[:, None])
    total2 = total + t * amp
    if normalize:
        a = 0.5 * total / np.maximum(maxamp, 1e-8) + 0.5
        b = 0.5 * total2 / np.maximum(maxamp + amp, 1e-8) + 0.5
    else:
        a, b = total, total2
    return np.where(rmd != 0, a + rmd * (b - a), a).astype(np.float32)


def _octaves(detail):
    """(whole octaves beyond the first, fraction of the next) of Detail."""
    detail = float(np.clip(np.max(f32(detail)), 0.0, 15.0)) if np.size(detail) else 0.0
    return int(np.floor(detail)), detail - np.floor(detail)


def multifractal(kind, p, detail, roughness, lacunarity, offset, gain):
    """Cycles' other noise types (noise_multi_fractal, noise_hetero_terrain,
    noise_hybrid_multi_fractal, noise_ridged_multi_fractal), per point;
    Detail is taken as one value for the batch (the octave count)."""
    octaves, rmd = _octaves(detail)
    rough = f32(roughness)
    lac = f32(lacunarity)
    offset, gain = f32(offset), f32(gain)
    n = len(p)
    if kind == "MULTIFRACTAL":
        value, pwr = np.ones(n, np.float32), np.ones(n, np.float32)
        for _ in range(octaves + 1):
            value = value * (pwr * snoise(p) + 1.0)
            pwr = pwr * rough
            p = p * lac
        if rmd != 0:
            value = value * (rmd * pwr * snoise(p) + 1.0)
        return value.astype(np.float32)
    if kind == "HETERO_TERRAIN":
        pwr = np.broadcast_to(rough, (n,)).astype(np.float32)
        value = offset + snoise(p)
        p = p * lac
        for _ in range(octaves):
            value = value + (snoise(p) + offset) * pwr * value
            pwr = pwr * rough
            p = p * lac
        if rmd != 0:
            value = value + rmd * (snoise(p) + offset) * pwr * value
        return np.asarray(value, np.float32)
    if kind == "HYBRID_MULTIFRACTAL":
        pwr, value, weight = np.ones(n, np.float32), np.zeros(n, np.float32), np.ones(n, np.float32)
        for _ in range(octaves + 1):
            live = weight > 0.001
            weight = np.minimum(weight, 1.0)
            signal = (snoise(p) + offset) * pwr
            pwr = pwr * rough
            value = np.where(live, value + weight * signal, value)
            weight = np.where(live, weight * gain * signal, weight)
            p = p * lac
        if rmd != 0:
            live = weight > 0.001
            signal = (snoise(p) + offset) * pwr
            value = np.where(live, value + rmd * np.minimum(weight, 1.0) * signal, value)
        return value.astype(np.float32)
    # RIDGED_MULTIFRACTAL
    pwr = np.broadcast_to(rough, (n,)).astype(np.float32)
    signal = offset - np.abs(snoise(p))
    signal = signal * signal
    value = signal
    for _ in range(octaves):
        p = p * lac
        weight = np.clip(signal * gain, 0.0, 1.0)
        signal = offset - np.abs(snoise(p))
        signal = signal * signal * weight
        value = value + signal * pwr
        pwr = pwr * rough
    return np.asarray(value, np.float32)


NOISE_TYPES = ("FBM", "MULTIFRACTAL", "HETERO_TERRAIN", "HYBRID_MULTIFRACTAL", "RIDGED_MULTIFRACTAL")


@varying
@node("TEX_NOISE")
def noise_texture(inp, geom, n, sh):
    dims = {"1D": 1, "2D": 2, "4D": 4}.get(n.props.get("noise_dimensions", "3D"), 3)
    kind = n.props.get("noise_type", "FBM")
    if kind not in NOISE_TYPES:
        sh.warn_once(("noise", kind), f"Noise Texture '{n.name}': type {kind} is not evaluated; using fBM")
        kind = "FBM"
    v = inp.vector("Vector") if inp.linked("Vector") else geom.generated
    scale = f32(inp.float("Scale", 5.0)).reshape(-1, 1)
    xyz = np.broadcast_to(np.broadcast_to(f32(v), (geom.n, 3)) * scale, (geom.n, 3))
    # The W input is the coordinate of 1D noise and the fourth of 4D noise, scaled alike.
    w = np.broadcast_to(f32(inp.float("W", 0.0)).reshape(-1, 1) * scale, (geom.n, 1)) if dims in (1, 4) else None
    p = {1: w, 2: xyz[:, :2], 3: xyz, 4: None}[dims] if dims != 4 else np.concatenate([xyz, w], axis=1)
    p = np.ascontiguousarray(p, np.float32)
    distortion = f32(inp.float("Distortion", 0.0)).reshape(-1, 1)
    if np.any(distortion != 0):
        shift = np.stack([snoise(p + random_offset(k, dims)) for k in range(dims)], axis=1)
        p = (p + shift * distortion).astype(np.float32)
    if kind == "FBM":
        args = (inp.float("Detail", 2.0), inp.float("Roughness", 0.5), inp.float("Lacunarity", 2.0),
                bool(n.props.get("normalize", True)))

        def noise(q):
            return fbm(q, *args)
    else:
        args = (inp.float("Detail", 2.0), inp.float("Roughness", 0.5), inp.float("Lacunarity", 2.0),
                inp.float("Offset", 0.0), inp.float("Gain", 1.0))

        def noise(q):
            return multifractal(kind, q, *args)
    value = noise(p)
    if (sh.index.get(id(n)), "Color") not in sh.read_outputs:
        return {"Fac": value}       # the colour's two more noises only where it is read
    color = np.stack([value, noise(p + random_offset(dims, dims)), noise(p + random_offset(dims + 1, dims))],
                     axis=1)
    return {"Fac": value, "Color": color.astype(np.float32)}
