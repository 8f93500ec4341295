"""Point clouds and hair curves as triangles, for Embree's triangle meshes.

Cycles intersects point clouds as spheres and hair as curves; embreex offers
triangle meshes only (no user geometry), so both are tessellated here, once
per export, with numpy:

- every point a geodesic sphere (an icosahedron subdivided ``level`` times:
  20, 80 or 320 triangles, fewer for large clouds), scaled so its surface
  area is the sphere's (so its silhouette's mean area is too: Cauchy's
  formula), with the sphere's normals at its corners;
- every curve a tube of ``sides`` sides along the Catmull-Rom spline
  through its points (sampled between them), rings kept from twisting by
  parallel transport, the radius of each point scaled so the
  polygon's perimeter is the circle's (again the same mean silhouette), with
  the tube's normals at its corners, and round ends (a ring at 45 degrees
  and a tip), as Cycles' swept-sphere curves have.

Cycles' curves follow a Catmull-Rom spline through the points, with the
end points repeated; so do the tubes, at the points the spline is sampled.

Bad input is dropped, never passed on: points of zero, negative or
non-finite radius or position; curves of fewer than two usable points.
"""

import numpy as np

ICOSPHERE_LEVELS = ((4096, 2), (65536, 1))    # (most points, level); more points: level 0
TUBE_SIDES = ((200000, 8), (2000000, 6))                   # (most points, sides); more points: 4


def _icosahedron():
    t = (1.0 + 5.0 ** 0.5) / 2.0
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t],
                  [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], np.float64)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                  [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                  [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]], np.int64)
    return v / np.linalg.norm(v, axis=1, keepdims=True), f


def _subdivide(v, f):
    """Every triangle into four, new vertices on the unit sphere."""
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    unique, inverse = np.unique(edges, axis=0, return_inverse=True)
    mid = v[unique[:, 0]] + v[unique[:, 1]]
    mid /= np.linalg.norm(mid, axis=1, keepdims=True)
    m = inverse.reshape(3, -1) + len(v)         # midpoints of edges 01, 12, 20 of each face
    a, b, c = f[:, 0], f[:, 1], f[:, 2]
    m01, m12, m20 = m
    faces = np.concatenate([np.stack(x, axis=1) for x in
                            ((a, m01, m20), (b, m12, m01), (c, m20, m12), (m01, m12, m20))])
    return np.concatenate([v, mid]), faces


_SPHERES = {}


def unit_sphere(level):
    """(vertices (V, 3), faces (F, 3)) of the geodesic sphere of that level,
    scaled to the unit sphere's surface area."""
    if level not in _SPHERES:
        v, f = _icosahedron()
        for _ in range(level):
            v, f = _subdivide(v, f)
        e1, e2 = v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]
        area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1).sum()
        _SPHERES[level] = (v * np.sqrt(4.0 * np.pi / area), f)
    return _SPHERES[level]


def _pick(table, count, last):
    return next((value for most, value in table if count <= most), last)


def spheres(centres, radii, level=None):
    """Triangles of spheres: (positions (P*V, 3), triangles (P*F, 3) int32,
    corner normals (P*F, 3, 3), kept (N,) bool: the points used)."""
    c = np.asarray(centres, np.float64).reshape(-1, 3)
    r = np.asarray(radii, np.float64).reshape(-1)
    keep = np.isfinite(c).all(axis=1) & np.isfinite(r) & (r > 0)
    c, r = c[keep], r[keep]
    if level is None:
        level = _pick(ICOSPHERE_LEVELS, len(c), 0)
    v, f = unit_sphere(level)
    unit = v / np.linalg.norm(v, axis=1, keepdims=True)
    pos = (c[:, None, :] + r[:, None, None] * v[None]).reshape(-1, 3)
    tris = (f[None] + (np.arange(len(c)) * len(v))[:, None, None]).reshape(-1, 3)
    normals = np.broadcast_to(unit[f][None], (len(c), len(f), 3, 3)).reshape(-1, 3, 3)
    return pos.astype(np.float32), tris.astype(np.int32), normals.astype(np.float32), keep


def _tangents(p, start, count):
    """(N, 3) unit tangents of polyline points (central differences; one-sided
    at the ends); start, count: (N,) their curve's first point and length."""
    idx = np.arange(len(p))
    prev = np.maximum(idx - 1, start)
    nxt = np.minimum(idx + 1, start + count - 1)
    t = p[nxt] - p[prev]
    length = np.linalg.norm(t, axis=1, keepdims=True)
    return t / np.where(length > 0, length, 1.0), length[:, 0] > 0


def _any_perpendicular(t):
    """A unit vector perpendicular to each row of t (Duff et al.'s basis)."""
    sign = np.where(t[:, 2] >= 0, 1.0, -1.0)
    a = -1.0 / (sign + t[:, 2])
    b = t[:, 0] * t[:, 1] * a
    return np.stack([1.0 + sign * t[:, 0] * t[:, 0] * a, sign * b, -sign * t[:, 0]], axis=1)


def catmull_rom(p, r, curve, counts, steps):
    """The curves through points p (N, 3) with radii r (N,) (curve: each
    point's curve, counts: the points per curve, in order) with ``steps``
    points added in each segment on the uniform Catmull-Rom spline through
    them (end points repeated, as Cycles does), radii along the same spline.
    Returns (p, r, curve, counts)."""
    n = len(p)
    start = np.repeat(np.concatenate([[0], np.cumsum(counts)[:-1]]), counts)
    end = start + np.repeat(counts, counts) - 1
    i = np.arange(n)
    seg = i[i < end]                            # segments from point i to i + 1
    pr = np.concatenate([p, r[:, None]], axis=1)
    a, b = pr[np.maximum(seg - 1, start[seg])], pr[seg]
    c, d = pr[seg + 1], pr[np.minimum(seg + 2, end[seg])]
    t = (np.arange(1, steps + 1) / (steps + 1))[None, :, None]
    inner = 0.5 * (2 * b[:, None] + (c - a)[:, None] * t + (2 * a - 5 * b + 4 * c - d)[:, None] * t * t
                   + (3 * b - a - 3 * c + d)[:, None] * t * t * t)           # (S, steps, 4)
    # Each segment's first point, then its inner points; each curve's last point after them.
    out = np.concatenate([b[:, None], inner], axis=1).reshape(-1, 4)
    owner = np.repeat(seg, steps + 1)
    last = i[i == end]
    out = np.concatenate([out, pr[last]])
    owner = np.concatenate([owner, last])
    order = np.argsort(owner, kind="stable")
    out = out[order]
    new_curve = curve[owner[order]]
    new_counts = counts + (counts - 1) * steps
    return out[:, :3], np.maximum(out[:, 3], 0.0), new_curve, new_counts


MAX_SPLINE_STEPS = 8
SPLINE_POINTS = 2000000         # spline points at most (of all curves of an object)


def spline_steps(points, offsets):
    """Points to add in each segment along the spline: enough that the
    curves' turns (the 90th percentile of the angles between consecutive
    segments) take about 5 degrees a step, within SPLINE_POINTS."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    offsets = np.asarray(offsets, np.int64)
    if len(p) < 3:
        return 0
    seg = np.diff(p, axis=0)
    seg /= np.maximum(np.linalg.norm(seg, axis=1, keepdims=True), 1e-30)
    inner = np.ones(len(p), bool)
    inner[offsets[:-1][offsets[:-1] < len(p)]] = False
    inner[np.clip(offsets[1:] - 1, 0, len(p) - 1)] = False      # first and last point of each curve
    idx = np.nonzero(inner[1:-1])[0] + 1
    if len(idx) == 0:
        return 0
    cos = np.clip((seg[idx - 1] * seg[idx]).sum(axis=1), -1.0, 1.0)
    turn = np.degrees(np.percentile(np.arccos(cos), 90))
    steps = int(min(MAX_SPLINE_STEPS, np.ceil(turn / 5.0)))
    return max(0, min(steps, SPLINE_POINTS // max(len(p), 1) - 1))


def _caps(p, r, t, ring, scale, start_of, counts, curve, sides, pos, nrm, tris, of_curve):
    """Round ends, as Cycles' curves (swept spheres) have: at each curve end
    of radius > 0, a ring at 45 degrees and a tip one radius out along the
    curve, joined to the end's ring."""
    ends = np.concatenate([start_of, start_of + counts - 1])
    out = np.concatenate([-np.ones(len(start_of)), np.ones(len(start_of))])     # away from the curve
    keep = r[ends] > 0
    ends, out = ends[keep], out[keep]
    if len(ends) == 0:
        return pos, nrm, tris, of_curve
    c = np.sqrt(0.5)
    axis = t[ends] * out[:, None]
    mid_dir = c * ring[ends] + c * axis[:, None, :]                  # (E, sides, 3)
    mid = p[ends][:, None, :] + (r[ends] * scale)[:, None, None] * c * ring[ends] \
        + (r[ends] * c)[:, None, None] * axis[:, None, :]
    tip = p[ends] + r[ends][:, None] * axis
    base = len(pos)
    m0 = base + np.arange(len(ends))[:, None] * sides + np.arange(sides)[None, :]
    m1 = base + np.arange(len(ends))[:, None] * sides + (np.arange(sides)[None, :] + 1) % sides
    tip_i = base + len(ends) * sides + np.arange(len(ends))[:, None] + 0 * m0
    e0 = ends[:, None] * sides + np.arange(sides)[None, :]
    e1 = ends[:, None] * sides + (np.arange(sides)[None, :] + 1) % sides
    # wound to face outward: the far end's as the tube's sides run, the near end's reversed
    far = (out > 0)[:, None, None]
    band = np.concatenate([np.stack([e0, e1, m1], -1), np.stack([e0, m1, m0], -1)], axis=1)
    band = np.where(far, band, band[..., ::-1])
    cone = np.stack([m0, m1, tip_i], -1)
    cone = np.where(far, cone, cone[..., ::-1])
    cap_tris = np.concatenate([band, cone], axis=1).reshape(-1, 3)
    pos = np.concatenate([pos, mid.reshape(-1, 3), tip])
    nrm = np.concatenate([nrm, mid_dir.reshape(-1, 3), axis])
    return pos, nrm, np.concatenate([tris, cap_tris]), np.concatenate([of_curve,
                                                                        np.repeat(curve[ends], 3 * sides)])


def tubes(points, radii, offsets, sides=None, spline_steps=0):
    """Triangles of tubes along curves: points (N, 3) and radii (N,) of all
    curves, offsets (C + 1,) each curve's first point (and the end);
    spline_steps: points added in each segment along the Catmull-Rom spline
    through the points (Cycles' curves follow it). Returns (positions,
    triangles int32, corner normals (T, 3, 3), curve of each triangle (T,)
    int64). Points of non-finite position or radius and repeated points are
    dropped; curves left with fewer than two points and segments between
    two zero radii give nothing."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    r = np.asarray(radii, np.float64).reshape(-1)
    offsets = np.asarray(offsets, np.int64)
    counts = np.diff(offsets)
    curve = np.repeat(np.arange(len(counts)), counts)
    ok = np.isfinite(p).all(axis=1) & np.isfinite(r)
    # a point equal to the one before it in its curve adds nothing
    same = np.zeros(len(p), bool)
    if len(p) > 1:
        same[1:] = (np.abs(p[1:] - p[:-1]).max(axis=1) == 0) & (curve[1:] == curve[:-1])
    ok &= ~same
    p, r, curve = p[ok], np.maximum(r[ok], 0.0), curve[ok]
    counts = np.bincount(curve, minlength=len(counts))
    keep_curve = counts >= 2
    keep = keep_curve[curve]
    p, r, curve = p[keep], r[keep], curve[keep]
    counts = counts[keep_curve]
    if spline_steps > 0 and len(p):
        p, r, curve, counts = catmull_rom(p, r, curve, counts, int(spline_steps))
    if sides is None:
        sides = _pick(TUBE_SIDES, len(p), 4)
    empty = (np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32), np.zeros((0, 3, 3), np.float32),
             np.zeros(0, np.int64))
    if len(p) == 0:
        return empty
    start_of = np.concatenate([[0], np.cumsum(counts)[:-1]])
    start = np.repeat(start_of, counts)
    count = np.repeat(counts, counts)
    t, _ = _tangents(p, start, count)
    # Parallel transport of each ring's first axis along its curve: a loop
    # over the points' place in their curves, every curve at once.
    u = np.zeros_like(p)
    u[start_of] = _any_perpendicular(t[start_of])
    j = np.arange(len(p)) - start
    for k in range(1, int(counts.max())):
        rows = np.nonzero(j == k)[0]
        prev = u[rows - 1]
        proj = prev - (prev * t[rows]).sum(axis=1, keepdims=True) * t[rows]
        length = np.linalg.norm(proj, axis=1, keepdims=True)
        fresh = _any_perpendicular(t[rows])
        u[rows] = np.where(length > 1e-6, proj / np.maximum(length, 1e-30), fresh)
    w = np.cross(t, u)
    # Each curve's polygon turned by its own angle (a golden-ratio sequence
    # over the curves): a polygon's width across the view varies with its
    # turn (by 1 - cos(pi / sides)), and strands all turned alike toward the
    # camera would all be too wide or too narrow together.
    turn = (np.repeat(np.nonzero(keep_curve)[0], counts) * 0.6180339887498949 % 1.0) * (2.0 * np.pi / sides)
    angle = 2.0 * np.pi * np.arange(sides)[None, :] / sides + turn[:, None]
    ring = np.cos(angle)[:, :, None] * u[:, None, :] + np.sin(angle)[:, :, None] * w[:, None, :]
    scale = np.pi / (sides * np.sin(np.pi / sides))     # the polygon's perimeter is the circle's
    pos = (p[:, None, :] + (r * scale)[:, None, None] * ring).reshape(-1, 3)
    nrm = ring.reshape(-1, 3)
    # Segments from each point to the next in its curve.
    seg = np.nonzero(j < count - 1)[0]
    seg = seg[(r[seg] > 0) | (r[seg + 1] > 0)]
    s = np.arange(sides)
    a0 = seg[:, None] * sides + s[None, :]
    a1 = seg[:, None] * sides + (s[None, :] + 1) % sides
    b0, b1 = a0 + sides, a1 + sides
    tris = np.concatenate([np.stack([a0, a1, b1], axis=-1), np.stack([a0, b1, b0], axis=-1)], axis=1)
    tris = tris.reshape(-1, 3)
    of_curve = np.repeat(curve[seg], 2 * sides)
    pos, nrm, tris, of_curve = _caps(p, r, t, ring, scale, start_of, counts, curve, sides, pos, nrm, tris, of_curve)
    # A tip of radius zero makes one triangle of each side's pair a line.
    e = np.cross(pos[tris[:, 1]] - pos[tris[:, 0]], pos[tris[:, 2]] - pos[tris[:, 0]])
    ok = (e * e).sum(axis=1) > 0
    tris, of_curve = tris[ok], of_curve[ok]
    return pos.astype(np.float32), tris.astype(np.int32), nrm[tris].astype(np.float32), of_curve
