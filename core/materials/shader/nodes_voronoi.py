"""Voronoi Texture (1D to 4D: F1, F2 and Smooth F1 by Euclidean, Manhattan,
Chebychev and Minkowski distances; Distance to Edge; N-Sphere Radius) as
Cycles computes it, so cells line up with Cycles' renders of the same file.

The nearest (F2: second nearest) of one jittered point per cell (the jitter
and the cell colour from the PCG hashes of the integer cell) over the 3^D
cells around the point; Smooth F1 blends the 5^D around it by a smooth
minimum. Distance to Edge measures to the nearest plane halfway between the
nearest point and another; N-Sphere Radius is half the distance from the
nearest point to its own nearest. 1D (along W) and 4D (the vector and W)
as Cycles, and Detail's octaves (fractal_voronoi: fBM with lerped
positions; Normalize). All on float32 arrays, the whole batch at once.
"""

from itertools import product

import numpy as np

from .evaluate import f32, node, varying
from .nodes_noise import hash_floats, hash_floats_to_colour

_PCG_MUL, _PCG_ADD = np.int32(1664525), np.int32(1013904223)


def _to_unit(v):
    return ((v & np.int32(0x7FFFFFFF)).astype(np.float32) * np.float32(1.0 / 0x7FFFFFFF)).astype(np.float32)


def _pcg(cells, mix):
    """The PCG hashes of "Hash Functions for GPU Rendering" (JCGT 2020) on
    signed 32-bit integer cells (N, D), as Cycles spells them: a linear
    step, ``mix`` (the D-dimensional cross terms, in place), a shift, and
    ``mix`` again; (N, D) in [0, 1]."""
    v = np.ascontiguousarray(cells, np.int32).copy()
    with np.errstate(over="ignore"):
        v = v * _PCG_MUL + _PCG_ADD
        mix(v)
        v ^= v >> np.int32(16)
        mix(v)
    return _to_unit(v)


def _mix2(v):
    v[:, 0] += v[:, 1] * _PCG_MUL
    v[:, 1] += v[:, 0] * _PCG_MUL


def _mix3(v):
    v[:, 0] += v[:, 1] * v[:, 2]
    v[:, 1] += v[:, 2] * v[:, 0]
    v[:, 2] += v[:, 0] * v[:, 1]


def _mix4(v):
    v[:, 0] += v[:, 1] * v[:, 3]
    v[:, 1] += v[:, 2] * v[:, 0]
    v[:, 2] += v[:, 0] * v[:, 1]
    v[:, 3] += v[:, 1] * v[:, 2]


def cell_random(cells):
    """Cycles' hash_int3_to_float3 of integer cells (N, 3): the PCG 3D hash."""
    return _pcg(cells, _mix3)


def cell_random2(cells):
    """Cycles' hash_int2_to_float2 of integer cells (N, 2): the PCG 2D hash."""
    return _pcg(cells, _mix2)


def cell_random4(cells):
    """Cycles' hash_int4_to_float4 of integer cells (N, 4): the PCG 4D hash."""
    return _pcg(cells, _mix4)


def _jitter(cells):
    """Each cell's point, in the cell's own [0, 1]^D (1D cells: Cycles'
    hash_float_to_float of the cell)."""
    dims = cells.shape[1]
    if dims == 1:
        return hash_floats(cells[:, 0].astype(np.float32))[:, None]
    return {2: cell_random2, 4: cell_random4}.get(dims, cell_random)(cells)


def _colour(cells):
    """Each cell's colour (N, 3): 2D cells hash as (x, y, 0), 4D cells by
    the first three of their hash, 1D cells as Cycles' hash_float_to_float3."""
    dims = cells.shape[1]
    if dims == 1:
        return hash_floats_to_colour([cells[:, 0].astype(np.float32)])
    if dims == 4:
        return cell_random4(cells)[:, :3]
    if dims == 2:
        cells = np.concatenate([cells, np.zeros((len(cells), 1), np.int32)], axis=1)
    return cell_random(cells)


def _offsets(dims, reach=1):
    return [np.int32(o[::-1]) for o in product(range(-reach, reach + 1), repeat=dims)]


def voronoi_distance(a, b, metric="EUCLIDEAN", exponent=1.0):
    """Cycles' voronoi_distance between point rows a and b (N, D)."""
    d = np.abs(a - b)
    if metric == "MANHATTAN":
        return d.sum(axis=1)
    if metric == "CHEBYCHEV":
        return d.max(axis=1)
    if metric == "MINKOWSKI":
        e = f32(exponent).reshape(-1)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            r = (d ** e[:, None]).sum(axis=1) ** (1.0 / e)
        return np.nan_to_num(r, nan=0.0, posinf=0.0).astype(np.float32)
    return np.sqrt((d * d).sum(axis=1))


def _cells(coord):
    floor = np.floor(coord)
    return floor, coord - floor, floor.astype(np.int64).astype(np.int32)


def voronoi_f1(coord, randomness, metric="EUCLIDEAN", exponent=1.0, second=False):
    """(distance (N,), colour (N, 3), position (N, D)) of Cycles' Voronoi F1
    (or F2 with ``second``) of points (N, D): the nearest (second nearest) of
    the jittered points of the 3^D cells around each point, by ``metric``."""
    floor, local, cell = _cells(coord)
    n = len(coord)
    best, best2 = np.full(n, np.inf, np.float32), np.full(n, np.inf, np.float32)
    offset1, offset2 = np.zeros_like(coord), np.zeros_like(coord)
    point1, point2 = np.zeros_like(coord), np.zeros_like(coord)
    r = f32(randomness).reshape(-1, 1)
    for o in _offsets(coord.shape[1]):
        offset = o.astype(np.float32)
        point = offset + _jitter(cell + o) * r
        d = voronoi_distance(point, local, metric, exponent)
        closer = d < best
        if second:      # the old nearest becomes the second, or d does
            nearer2 = ~closer & (d < best2)
            best2 = np.where(closer, best, np.where(nearer2, d, best2))
            offset2 = np.where(closer[:, None], offset1, np.where(nearer2[:, None], offset, offset2))
            point2 = np.where(closer[:, None], point1, np.where(nearer2[:, None], point, point2))
        best = np.where(closer, d, best)
        offset1 = np.where(closer[:, None], offset, offset1)
        point1 = np.where(closer[:, None], point, point1)
    if second:
        best, offset1, point1 = best2, offset2, point2
    colour = _colour(cell + offset1.astype(np.int32))
    return best.astype(np.float32), colour, (point1 + floor).astype(np.float32)


def voronoi_smooth_f1(coord, randomness, smoothness, metric="EUCLIDEAN", exponent=1.0):
    """Cycles' Smooth F1: the 5^D cells around each point blended by a
    smooth minimum of width ``smoothness`` (already halved and clamped)."""
    floor, local, cell = _cells(coord)
    n = len(coord)
    sm = np.broadcast_to(f32(smoothness), (n,)).astype(np.float32)
    dist = np.full(n, 8.0, np.float32)
    colour, position = np.zeros((n, 3), np.float32), np.zeros_like(coord)
    r = f32(randomness).reshape(-1, 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        for o in _offsets(coord.shape[1], 2):
            point = o.astype(np.float32) + _jitter(cell + o) * r
            d = voronoi_distance(point, local, metric, exponent)
            t = np.clip(0.5 + 0.5 * (dist - d) / sm, 0.0, 1.0)
            h = np.where(sm > 0, t * t * (3.0 - 2.0 * t), (d < dist).astype(np.float32))
            correction = sm * h * (1.0 - h)
            dist = dist + h * (d - dist) - correction
            correction = (correction / (1.0 + 3.0 * sm))[:, None]
            hh = h[:, None]
            colour = colour + hh * (_colour(cell + o) - colour) - correction
            position = position + hh * (point - position) - correction
    return dist.astype(np.float32), colour.astype(np.float32), (position + floor).astype(np.float32)


def voronoi_distance_to_edge(coord, randomness):
    """(N,) Cycles' Distance to Edge: from the point to the nearest edge of
    its cell, the plane halfway between the nearest cell point and each of
    the others around (Euclidean, as Cycles always measures it). In 1D the
    nearer of the midpoints between the point's own cell's point and its
    neighbours'."""
    _floor, local, cell = _cells(coord)
    r = f32(randomness).reshape(-1, 1)
    if coord.shape[1] == 1:
        mid, left, right = (o + _jitter(cell + np.int32(o)) * r for o in (0, -1, 1))
        return np.minimum(np.abs((mid + left) / 2 - local), np.abs((mid + right) / 2 - local))[:, 0] \
            .astype(np.float32)
    to_points = [o.astype(np.float32) + _jitter(cell + o) * r - local for o in _offsets(coord.shape[1])]
    best = np.full(len(coord), 8.0, np.float32)
    closest = np.zeros_like(coord)
    for v in to_points:
        d = (v * v).sum(axis=1)
        closer = d < best
        best = np.where(closer, d, best)
        closest = np.where(closer[:, None], v, closest)
    edge = np.full(len(coord), 8.0, np.float32)
    for v in to_points:
        perp = v - closest
        length2 = (perp * perp).sum(axis=1)
        far = length2 > 0.0001
        with np.errstate(divide="ignore", invalid="ignore"):
            d = (((closest + v) * 0.5) * perp).sum(axis=1) / np.sqrt(length2)
        edge = np.where(far, np.minimum(edge, d), edge)
    return edge.astype(np.float32)


def voronoi_n_sphere_radius(coord, randomness):
    """(N,) Cycles' N-Sphere Radius: half the distance from the nearest cell
    point to the point nearest to it (of the cells around its own)."""
    _floor, local, cell = _cells(coord)
    r = f32(randomness).reshape(-1, 1)
    n, dims = coord.shape
    best, closest, closest_cell = np.full(n, 8.0, np.float32), np.zeros_like(coord), np.zeros((n, dims), np.int32)
    for o in _offsets(dims):
        point = o.astype(np.float32) + _jitter(cell + o) * r
        d = np.sqrt(((point - local) ** 2).sum(axis=1))
        closer = d < best
        best = np.where(closer, d, best)
        closest = np.where(closer[:, None], point, closest)
        closest_cell = np.where(closer[:, None], o, closest_cell)
    best, neighbour = np.full(n, 8.0, np.float32), np.zeros_like(coord)
    for o in _offsets(dims):
        if not o.any():
            continue
        c = closest_cell + o
        point = c.astype(np.float32) + _jitter(cell + c) * r
        d = np.sqrt(((point - closest) ** 2).sum(axis=1))
        closer = d < best
        best = np.where(closer, d, best)
        neighbour = np.where(closer[:, None], point, neighbour)
    return (np.sqrt(((neighbour - closest) ** 2).sum(axis=1)) * 0.5).astype(np.float32)


VORONOI_FEATURES = ("F1", "F2", "SMOOTH_F1", "DISTANCE_TO_EDGE", "N_SPHERE_RADIUS")


def _octaves(detail, roughness):
    """Per row: whether detail adds nothing (one octave: detail or roughness
    0), the octaves to run, and the fraction of the last one (Cycles' fBM
    of Voronoi: octaves 0 .. ceil(detail), the last by detail's remainder)."""
    single = (detail == 0) | (roughness == 0)
    return single, int(np.ceil(detail.max())) if len(detail) else 0, detail - np.floor(detail)


def _mix(a, b, t):
    return a + (b - a) * t


def fractal_voronoi(octave, coord, detail, roughness, lacunarity, normalize, max_distance):
    """(distance, colour, position) of Cycles' fractal Voronoi: octave(c) ->
    (distance (N,), colour (N, 3), position (N, D)) at coordinates c, summed
    over octaves of growing frequency (lacunarity) and falling amplitude
    (roughness), positions blended in; detail, roughness, lacunarity (N,);
    normalize divides by the amplitudes and max_distance."""
    single, count, remainder = _octaves(detail, roughness)
    n = len(coord)
    dist, colour, position = np.zeros(n, np.float32), np.zeros((n, 3), np.float32), np.zeros_like(coord)
    amplitude, total, scale = np.ones(n, np.float32), np.zeros(n, np.float32), np.ones(n, np.float32)
    for i in range(count + 1):
        d, c, p = octave(coord * scale[:, None])
        if i == 0:
            first = (d, c, p)
        whole = i <= detail
        part = ~whole & (remainder != 0)
        a = amplitude
        p = p / scale[:, None]
        if whole.any():
            total = np.where(whole, total + a, total)
            dist = np.where(whole, dist + d * a, dist)
            colour = np.where(whole[:, None], colour + c * a[:, None], colour)
            position = np.where(whole[:, None], _mix(position, p, a[:, None]), position)
        if part.any():
            r = remainder
            total = np.where(part, _mix(total, total + a, r), total)
            dist = np.where(part, _mix(dist, dist + d * a, r), dist)
            colour = np.where(part[:, None], _mix(colour, colour + c * a[:, None], r[:, None]), colour)
            position = np.where(part[:, None], _mix(position, _mix(position, p, a[:, None]), r[:, None]), position)
        scale = np.where(whole, scale * lacunarity, scale)
        amplitude = np.where(whole, amplitude * roughness, amplitude)
    total = np.where(single, 1.0, total)
    dist = np.where(single, first[0], dist)
    colour = np.where(single[:, None], first[1], colour)
    position = np.where(single[:, None], first[2], position)
    if normalize:
        with np.errstate(divide="ignore", invalid="ignore"):
            dist = np.nan_to_num(dist / (total * max_distance), nan=0.0, posinf=0.0, neginf=0.0)
            colour = np.nan_to_num(colour / total[:, None], nan=0.0, posinf=0.0, neginf=0.0)
    return dist.astype(np.float32), colour.astype(np.float32), position.astype(np.float32)


def fractal_distance_to_edge(coord, randomness, detail, roughness, lacunarity, normalize):
    """(N,) Cycles' fractal Distance to Edge: the nearest edge over octaves,
    each blended in by its amplitude; normalize divides by the blended
    largest distance."""
    single, count, remainder = _octaves(detail, roughness)
    n = len(coord)
    largest = (0.5 + 0.5 * np.broadcast_to(f32(randomness), (n,))).astype(np.float32)
    reach, dist = largest.copy(), np.full(n, 8.0, np.float32)
    amplitude, scale = np.ones(n, np.float32), np.ones(n, np.float32)
    for i in range(count + 1):
        d = voronoi_distance_to_edge(coord * scale[:, None], randomness)
        if i == 0:
            first = d
        whole = i <= detail
        part = ~whole & (remainder != 0)
        a = amplitude
        nearer = _mix(dist, np.minimum(dist, d / scale), a)
        further = _mix(reach, largest / scale, a)
        reach = np.where(whole, further, np.where(part, _mix(reach, further, remainder), reach))
        dist = np.where(whole, nearer, np.where(part, _mix(dist, np.minimum(dist, nearer), remainder), dist))
        scale = np.where(whole, scale * lacunarity, scale)
        amplitude = np.where(whole, amplitude * roughness, amplitude)
    dist = np.where(single, first, dist)
    if normalize:
        with np.errstate(divide="ignore", invalid="ignore"):
            dist = np.nan_to_num(dist / reach, nan=0.0, posinf=0.0, neginf=0.0)
    return dist.astype(np.float32)


@varying
@node("TEX_VORONOI")
def voronoi_texture(inp, geom, n, sh):
    props = n.props
    feature, metric = props.get("feature", "F1"), props.get("distance", "EUCLIDEAN")
    dims = {"1D": 1, "2D": 2, "4D": 4}.get(props.get("voronoi_dimensions", "3D"), 3)
    if feature not in VORONOI_FEATURES:
        sh.warn_once(("voronoi", feature), f"Voronoi Texture '{n.name}': feature {feature} is not "
                                           f"supported; using F1")
        feature = "F1"
    scale = np.maximum(f32(inp.float("Scale", 5.0)), 1e-8)
    factor = f32(inp.float("Scale", 5.0)).reshape(-1, 1)
    # The W input is the coordinate of 1D Voronoi and the fourth of 4D, scaled alike.
    w = np.broadcast_to(f32(inp.float("W", 0.0)).reshape(-1, 1) * factor, (geom.n, 1)) if dims in (1, 4) else None
    if dims == 1:
        p = np.ascontiguousarray(w, np.float32)
    else:
        v = inp.vector("Vector") if inp.linked("Vector") else geom.generated
        p = np.broadcast_to(f32(v), (geom.n, 3)) * factor
        p = np.ascontiguousarray(p[:, :dims] if dims < 4 else np.concatenate([p, w], axis=1), np.float32)
    randomness = np.clip(inp.float("Randomness", 1.0), 0, 1)
    exponent = inp.float("Exponent", 0.5)
    zero, zero3 = np.zeros(geom.n, np.float32), np.zeros((geom.n, 3), np.float32)
    if feature == "N_SPHERE_RADIUS":
        return {"Radius": voronoi_n_sphere_radius(p, randomness), "Distance": zero, "Color": zero3,
                "Position": zero3, "W": zero}

    def column(name, default, lo=None, hi=None):
        x = np.broadcast_to(f32(inp.float(name, default)).reshape(-1), (geom.n,)).astype(np.float32)
        return x if lo is None else np.clip(x, lo, hi)

    detail, roughness = column("Detail", 0.0, 0.0, 15.0), column("Roughness", 0.5, 0.0, 1.0)
    lacunarity, normalize = column("Lacunarity", 2.0), bool(props.get("normalize", False))
    if feature == "DISTANCE_TO_EDGE":
        return {"Distance": fractal_distance_to_edge(p, randomness, detail, roughness, lacunarity, normalize),
                "Color": zero3, "Position": zero3, "W": zero, "Radius": zero}
    smoothness = np.clip(f32(inp.float("Smoothness", 1.0)) / 2.0, 0.0, 0.5)
    if feature == "SMOOTH_F1" and np.any(smoothness != 0):
        def octave(c):
            return voronoi_smooth_f1(c, randomness, smoothness, metric, exponent)
    else:
        def octave(c):
            return voronoi_f1(c, randomness, metric, exponent, second=feature == "F2")
    half = 0.5 + 0.5 * np.broadcast_to(f32(randomness), (geom.n,)).astype(np.float32)
    largest = voronoi_distance(np.zeros((geom.n, dims), np.float32), np.repeat(half[:, None], dims, axis=1),
                               metric, exponent) if dims > 1 else half
    largest = largest * (2.0 if feature == "F2" else 1.0)
    dist, colour, position = fractal_voronoi(octave, p, detail, roughness, lacunarity, normalize, largest)
    inv = 1.0 / scale.reshape(-1, 1)
    out_w = zero
    if dims == 1:       # a 1D position is W alone
        out_w = (position[:, 0] * inv[:, 0]).astype(np.float32)
        position = np.zeros((geom.n, 3), np.float32)
    elif dims == 4:
        out_w = (position[:, 3] * inv[:, 0]).astype(np.float32)
        position = position[:, :3]
    elif dims == 2:     # a 2D position lies in the z = 0 plane
        position = np.concatenate([position, np.zeros((geom.n, 1), np.float32)], axis=1)
    return {"Distance": dist, "Color": colour, "Position": (position * inv).astype(np.float32),
            "W": out_w, "Radius": zero}
