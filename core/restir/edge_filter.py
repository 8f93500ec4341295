"""Edge-avoiding filters on blocks of image rows, for the denoiser (denoise.py).

A pass's pixel range computes the image rows it touches. Those rows, with
as many rows and columns around them as its taps reach (the halo), are laid
out flat (Block), zeros outside the image, so that every tap is one
contiguous slice and every operation runs over whole arrays: a pixel's
result is the same whichever range computes it. Zero normals mark pixels
that see no surface; a tap there weighs nothing.

Weights follow SVGF (Schied et al. 2017): depth against the screen-space
depth gradient (sigma_z 1), normals to the power 128, luminance against the
square root of the 3x3-blurred variance (sigma_l 4), B3 spline taps.
"""

from dataclasses import dataclass

import numpy as np

SHORT_HISTORY = 4.0         # frames of history below which variance is estimated spatially
SPATIAL_RADIUS = 3          # 7x7 pixels for that estimate
SIGMA_DEPTH = 1.0           # SVGF's sigma_z
NORMAL_POWER = 128.0        # SVGF's sigma_n
SIGMA_LUMINANCE = 4.0       # SVGF's sigma_l
DEPTH_FLOOR = 1e-3          # share of the depth always allowed between taps (float rounding)
LUMINANCE_FLOOR = 1e-10     # added to the luminance scale (no division by zero)
B3 = (1.0 / 16, 1.0 / 4, 3.0 / 8, 1.0 / 4, 1.0 / 16)
# A pixel on an edge between two surfaces (a room's corner, where a wall
# meets the ceiling) sees one or the other from frame to frame (the pixel
# filter's jitter): the mean of its normals lies between theirs and is
# shorter than 1. Against either side's normals the weight (n_p . n_q)^128
# is nothing, so the filter left such pixels as they were, noisy: dotted
# lines along the edges of a still. Where that length L is under
# MIXED_LENGTH (2 % of a right angle's other side), a tap's normal weight
# is the mean normal's projection on the tap's, max(L n_p . n_q, 0): each
# surface in about the share of the pixel it covers (the projections of a
# mean of perpendicular normals are the shares). Its neighbours weigh it as
# before. Glossy interior, still camera, frame 32 against Cycles at 4096
# spp: MSE 0.000785 -> 0.000637 (the cosine to 1 / L capped at 1 instead,
# so both sides in full: 0.000648).
MIXED_LENGTH = 0.98


@dataclass
class Image:
    """What an a-trous iteration reads, whole-image arrays (P,) float32 (a
    tuple of them is what Workers.map_into fills range by range)."""
    red: np.ndarray
    green: np.ndarray
    blue: np.ndarray
    lum: np.ndarray
    var: np.ndarray
    guide: np.ndarray = None    # luminance the weights compare (None: lum)


def depth_gradient(zimg, nimg, r0, r1):
    """(gx, gy) (r1 - r0, W) float32: per pixel of rows r0..r1, the smaller
    of the depth differences to its two neighbours along x (and along y)
    that see a surface (0 where neither does)."""
    h, w = zimg.shape
    a, b = max(r0 - 1, 0), min(r1 + 1, h)
    ok = (nimg[0, a:b] != 0) | (nimg[1, a:b] != 0) | (nimg[2, a:b] != 0)
    big = np.float32(np.inf)
    zz = np.where(ok, zimg[a:b], big)
    dx = np.full((b - a, w + 1), big, np.float32)
    dy = np.full((b - a + 1, w), big, np.float32)
    with np.errstate(invalid="ignore"):         # inf - inf: no neighbour on either side
        dx[:, 1:w] = np.abs(zz[:, 1:] - zz[:, :-1])
        dy[1:b - a] = np.abs(zz[1:] - zz[:-1])
    gx = np.fmin(dx[:, :-1], dx[:, 1:])
    gy = np.fmin(dy[:-1], dy[1:])
    gx[~np.isfinite(gx)] = 0.0
    gy[~np.isfinite(gy)] = 0.0
    return gx[r0 - a:r1 - a], gy[r0 - a:r1 - a]


class Block:
    """Rows r0..r1 of the image with ``halo`` rows and columns around them,
    flattened so that every tap is a contiguous slice: block row i (image
    row r0 - halo + i) and column j (image column j - halo) at flat index
    halo + i * wp + j, zeros outside the image. Zero normals mark pixels
    that see no surface, so taps there weigh nothing; the centres are the
    rows r0..r1 with their padding columns (computed and dropped)."""

    def __init__(self, r0, r1, halo, width, height):
        self.r0, self.r1, self.halo, self.width, self.height = r0, r1, halo, width, height
        self.wp = width + 2 * halo
        self.rows = r1 - r0 + 2 * halo
        self.size = self.rows * self.wp + 2 * halo
        self.base = halo + halo * self.wp
        self.m = (r1 - r0) * self.wp

    def flat(self, plane):
        """The block of an (H, W) image."""
        out = np.zeros(self.size, np.float32)
        view = out[self.halo:self.halo + self.rows * self.wp].reshape(self.rows, self.wp)
        top = self.r0 - self.halo
        a, b = max(top, 0), min(self.r1 + self.halo, self.height)
        view[a - top:b - top, self.halo:self.halo + self.width] = plane[a:b]
        return out

    def centres(self, rows):
        """(m,) centres of (r1 - r0, W) values of rows r0..r1 (0 in the padding)."""
        out = np.zeros((self.r1 - self.r0, self.wp), np.float32)
        out[:, self.halo:self.halo + self.width] = rows
        return out.ravel()

    def centre(self, flat):
        return flat[self.base:self.base + self.m]

    def tap(self, flat, oy, ox):
        q = self.base + oy * self.wp + ox
        return flat[q:q + self.m]

    def image(self, centres):
        """(r1 - r0, W) of (m,) centres."""
        return centres.reshape(self.r1 - self.r0, self.wp)[:, self.halo:self.halo + self.width]


def geometry(blk, n_flat, z_flat, gx, gy, steps):
    """Per-centre terms of the edge-stopping weights: normals times
    NORMAL_POWER, depths, and for each tap distance (|i|, |j|) in steps the
    reciprocal of the depth difference allowed (SIGMA_DEPTH times the
    gradient along the offset, plus DEPTH_FLOOR of the depth)."""
    power = np.float32(NORMAL_POWER)
    nc = [blk.centre(n) * power for n in n_flat]
    zc = blk.centre(z_flat)
    gxc, gyc = blk.centres(gx), blk.centres(gy)
    floor = np.float32(DEPTH_FLOOR) * np.abs(zc) + np.float32(1e-12)
    inv_z = {}
    for i, j in steps:
        allowed = np.float32(SIGMA_DEPTH * i) * gxc
        allowed += np.float32(SIGMA_DEPTH * j) * gyc
        allowed += floor
        inv_z[(i, j)] = np.float32(1.0) / allowed
    return nc, zc, inv_z


def weight(out, tmp, nc, nq, zc, zq, inv_z, constant):
    """exp(NORMAL_POWER (n_p . n_q - 1) - |z_p - z_q| / allowed + log h) into
    out: (n_p . n_q)^128 as exp(128 (n_p . n_q - 1)), within 1 % where the
    weight matters (cosines above 0.99) and zero where normals differ. nc:
    the centres' normals times NORMAL_POWER; constant: log h - NORMAL_POWER."""
    np.multiply(nc[0], nq[0], out=out)
    out += np.multiply(nc[1], nq[1], out=tmp)
    out += np.multiply(nc[2], nq[2], out=tmp)
    out += constant
    np.subtract(zq, zc, out=tmp)
    np.abs(tmp, out=tmp)
    tmp *= inv_z
    out -= tmp
    return out


def variance(m1, m2, count, zimg, nimg, gx, gy, r0, r1):
    """(rows * W,) float32 variance of the luminance of the means of rows
    r0..r1: from each pixel's moments over its history (m1, m2: (H, W)
    images of the mean luminance and mean square), divided by its frames
    (count, (H, W)); where that history is shorter than SHORT_HISTORY frames,
    from the moments of the 7x7 pixels around it that see its surface."""
    height, width = zimg.shape
    c = count[r0:r1].ravel()
    a1, a2 = m1[r0:r1].ravel(), m2[r0:r1].ravel()
    var = np.maximum(a2 - a1 * a1, 0.0)
    short = c < SHORT_HISTORY
    if short.any():
        r = SPATIAL_RADIUS
        blk = Block(r0, r1, r, width, height)
        n_flat = [blk.flat(nimg[k]) for k in range(3)]
        z_flat = blk.flat(zimg)
        steps = [(i, j) for i in range(r + 1) for j in range(r + 1) if i or j]
        nc, zc, inv_z = geometry(blk, n_flat, z_flat, gx, gy, steps)
        f1, f2 = blk.flat(m1), blk.flat(m2)
        s1, s2 = blk.centre(f1).copy(), blk.centre(f2).copy()
        sw = np.ones(blk.m, np.float32)
        w = np.empty(blk.m, np.float32)
        tmp = np.empty(blk.m, np.float32)
        constant = np.float32(-NORMAL_POWER)
        for oy in range(-r, r + 1):
            for ox in range(-r, r + 1):
                if oy == 0 and ox == 0:
                    continue
                nq = [blk.tap(n, oy, ox) for n in n_flat]
                weight(w, tmp, nc, nq, zc, blk.tap(z_flat, oy, ox), inv_z[(abs(ox), abs(oy))], constant)
                np.exp(w, out=w)
                sw += w
                s1 += np.multiply(w, blk.tap(f1, oy, ox), out=tmp)
                s2 += np.multiply(w, blk.tap(f2, oy, ox), out=tmp)
        s1 /= sw
        s2 /= sw
        s1 *= s1
        spatial = blk.image(np.maximum(s2 - s1, 0.0)).ravel()
        var = np.where(short, spatial, var)
    return (var / c).astype(np.float32)


def surface_blur(img, zimg, nimg, gx, gy, r0, r1):
    """(r1 - r0, W) float32: the 3x3 binomial blur of img (H, W) on rows
    r0..r1 over the pixels that see the centre's surface (the a-trous
    weights without luminance), each pixel's weights normalised. The first
    iteration compares these instead of each pixel's own luminance: a
    single bright pixel then stands out less, and the filter, which weighs
    neighbours by how far their luminance lies from the centre's, darkens
    less (on noise skewed as light is, with a heavy bright tail: synthetic
    exponential noise, 8 % darker without it, 1.3 % with it)."""
    height, width = img.shape
    blk = Block(r0, r1, 1, width, height)
    n_flat = [blk.flat(nimg[k]) for k in range(3)]
    z_flat = blk.flat(zimg)
    nc, zc, inv_z = geometry(blk, n_flat, z_flat, gx, gy, [(1, 0), (0, 1), (1, 1)])
    x_flat = blk.flat(img)
    valid = (nc[0] != 0) | (nc[1] != 0) | (nc[2] != 0)
    h = (0.25, 0.5, 0.25)
    wsum = np.where(valid, np.float32(h[1] * h[1]), np.float32(0)).astype(np.float32)
    acc = blk.centre(x_flat) * wsum
    w = np.empty(blk.m, np.float32)
    tmp = np.empty(blk.m, np.float32)
    for oy in (-1, 0, 1):
        for ox in (-1, 0, 1):
            if oy == 0 and ox == 0:
                continue
            constant = np.float32(np.log(h[oy + 1] * h[ox + 1]) - NORMAL_POWER)
            nq = [blk.tap(n, oy, ox) for n in n_flat]
            weight(w, tmp, nc, nq, zc, blk.tap(z_flat, oy, ox), inv_z[(abs(ox), abs(oy))], constant)
            np.exp(w, out=w)
            wsum += w
            acc += np.multiply(w, blk.tap(x_flat, oy, ox), out=tmp)
    out = np.where(wsum > 0, acc / np.where(wsum > 0, wsum, np.float32(1)), blk.centre(x_flat))
    return blk.image(out.astype(np.float32))


def _blur3(v, r0, r1):
    """(r1 - r0, W) the 3x3 binomial blur of image v (H, W) on rows r0..r1
    (the border repeated)."""
    h, w = v.shape
    a, b = max(r0 - 1, 0), min(r1 + 1, h)
    top = 1 if r0 == 0 else 0
    bottom = 1 if r1 == h else 0
    p = np.pad(v[a:b], ((top, bottom), (1, 1)), mode="edge")
    q = np.float32(0.25)
    hor = q * p[:, :-2] + np.float32(0.5) * p[:, 1:-1] + q * p[:, 2:]
    return q * hor[:-2] + np.float32(0.5) * hor[1:-1] + q * hor[2:]


def _mixed_centres(blk, lengths, nc):
    """(rows, unit normals (3 of (k,)), lengths (k,)) of the block's centres
    whose mean normal is shorter than MIXED_LENGTH and not zero (no
    surface), or None where there are none. nc: the centres' normals times
    NORMAL_POWER."""
    if lengths is None:
        return None
    length = blk.centre(blk.flat(lengths))
    rows = np.nonzero((length < np.float32(MIXED_LENGTH)) & (length > 0))[0]
    if len(rows) == 0:
        return None
    unit = [np.take(x, rows) * np.float32(1.0 / NORMAL_POWER) for x in nc]
    return rows, unit, np.take(length, rows)


def _mixed_terms(blk, mixed, n_flat, offsets):
    """(taps, k) float32: what each tap (flat offsets, in the a-trous loop's
    order) adds to the log weight of the mixed centres: log max(L n_p . n_q,
    0) in place of NORMAL_POWER (n_p . n_q - 1)."""
    rows, unit, length = mixed
    at = blk.base + rows[None, :] + np.asarray(offsets, np.int64)[:, None]
    cos = unit[0] * np.take(n_flat[0], at)
    cos += unit[1] * np.take(n_flat[1], at)
    cos += unit[2] * np.take(n_flat[2], at)
    out = np.log(np.maximum(cos * length, np.float32(1e-30)))
    out -= np.float32(NORMAL_POWER) * (cos - np.float32(1.0))
    return out.astype(np.float32, copy=False)


def atrous(img, zimg, nimg, gimg, r0, r1, step, need_var=True, lengths=None):
    """One a-trous iteration (taps at multiples of step) of img (Image) on
    rows r0..r1: (red, green, blue, lum, var) as (r1 - r0, W) float32
    arrays (var None without need_var). zimg (H, W), nimg (3, H, W): depth
    and unit normals; gimg: the depth gradient images (gx, gy); lengths (H,
    W) or None: the lengths of the mean normals nimg's are the directions
    of (see MIXED_LENGTH)."""
    height, width = zimg.shape
    shape = (height, width)
    blk = Block(r0, r1, 2 * step, width, height)
    c_flat = [blk.flat(x.reshape(shape)) for x in (img.red, img.green, img.blue)]
    l_flat = blk.flat((img.lum if img.guide is None else img.guide).reshape(shape))
    v_img = img.var.reshape(shape)
    v_flat = blk.flat(v_img) if need_var else None
    n_flat = [blk.flat(nimg[k]) for k in range(3)]
    z_flat = blk.flat(zimg)
    steps = [(i * step, j * step) for i in range(3) for j in range(3) if i or j]
    nc, zc, inv_z = geometry(blk, n_flat, z_flat, gimg[0][r0:r1], gimg[1][r0:r1], steps)
    mixed = _mixed_centres(blk, lengths, nc)
    offsets = [ty * step * blk.wp + tx * step for ty in range(-2, 3) for tx in range(-2, 3) if tx or ty]
    mixed_terms = None if mixed is None else _mixed_terms(blk, mixed, n_flat, offsets)
    tap = 0
    lc = blk.centre(l_flat)
    inv_l = blk.centres(np.float32(1.0) / (np.float32(SIGMA_LUMINANCE) * np.sqrt(_blur3(v_img, r0, r1))
                                           + np.float32(LUMINANCE_FLOOR)))
    valid = (nc[0] != 0) | (nc[1] != 0) | (nc[2] != 0)
    centre = np.float32(B3[2] * B3[2])
    wsum = np.where(valid, centre, np.float32(0)).astype(np.float32)
    acc = [blk.centre(c) * wsum for c in c_flat]
    vacc = blk.centre(v_flat) * (wsum * wsum) if need_var else None
    w = np.empty(blk.m, np.float32)
    tmp = np.empty(blk.m, np.float32)
    for ty in range(-2, 3):
        for tx in range(-2, 3):
            if tx == 0 and ty == 0:
                continue
            oy, ox = ty * step, tx * step
            constant = np.float32(np.log(B3[ty + 2] * B3[tx + 2]) - NORMAL_POWER)
            nq = [blk.tap(n, oy, ox) for n in n_flat]
            weight(w, tmp, nc, nq, zc, blk.tap(z_flat, oy, ox), inv_z[(abs(ox), abs(oy))], constant)
            if mixed_terms is not None:
                w[mixed[0]] += mixed_terms[tap]
            tap += 1
            np.subtract(blk.tap(l_flat, oy, ox), lc, out=tmp)
            np.abs(tmp, out=tmp)
            tmp *= inv_l
            w -= tmp
            np.exp(w, out=w)
            wsum += w
            for k in range(3):
                acc[k] += np.multiply(w, blk.tap(c_flat[k], oy, ox), out=tmp)
            if need_var:
                w *= w
                vacc += np.multiply(w, blk.tap(v_flat, oy, ox), out=tmp)
    inv = np.float32(1.0) / np.where(wsum > 0, wsum, np.float32(1.0))
    out = [blk.image(np.where(valid, a * inv, blk.centre(c))) for a, c in zip(acc, c_flat)]
    lum = np.float32(0.2126) * out[0] + np.float32(0.7152) * out[1] + np.float32(0.0722) * out[2]
    var = None
    if need_var:
        var = blk.image(np.where(valid, vacc * (inv * inv), blk.centre(v_flat)).astype(np.float32))
    return out[0], out[1], out[2], lum, var
