"""Texture nodes: Image Texture, Environment Texture, Checker, Brick, Wave, Magic,
Gradient, White Noise and the Sky Texture (its models in sky.py).

Unlinked vectors default as in Cycles: Image Texture reads the active UV
map, procedural textures read Generated coordinates (White Noise the
position), Environment Texture the ray direction. Image lookups (filtering, extension, alpha) are core/materials/texture.py's.
"""

import numpy as np

from .evaluate import f32, node, varying
from .nodes_noise import fbm, hash_floats, hash_floats_to_colour

MAGENTA = np.array([1.0, 0.0, 1.0], np.float32)


def _image(sh, n):
    key = n.props.get("image", "")
    images = sh.images
    if key in images and images[key] is not None:
        return images[key]
    sh.warn_once(("image", key), f"image texture '{n.name}' has no image{f' ({key})' if key else ''}; "
                                 f"it renders magenta")
    return None


def _lookup(sh, n, uv, unassociate=False):
    from ..texture import lookup   # noqa: PLC0415 (texture is optional until an image is read)
    img = _image(sh, n)
    uv = np.ascontiguousarray(np.broadcast_to(f32(uv), (len(uv), 3))[:, :2])
    if img is None:
        return np.broadcast_to(MAGENTA, (len(uv), 3)).astype(np.float32), np.ones(len(uv), np.float32)
    return lookup(img, uv, n.props.get("interpolation", "Linear"), n.props.get("extension", "REPEAT"),
                  unassociate=unassociate)


@varying
@node("TEX_IMAGE")
def image_texture(inp, geom, n, sh):
    """Cycles' Image Texture: Flat projection looks the vector's (u, v) up;
    Box blends three planar lookups by the object-space normal
    (box_weights); Sphere and Tube wrap the vector, remapped from [0, 1]^3
    to [-1, 1]^3, around the object's z axis."""
    uv = inp.vector("Vector") if inp.linked("Vector") else geom.uv("")
    uv = np.broadcast_to(f32(uv), (geom.n, 3))
    projection = n.props.get("projection", "FLAT")
    alpha_read = (sh.index.get(id(n)), "Alpha") in sh.read_outputs
    if projection == "BOX" and hasattr(geom, "object_vector"):
        return _box_lookup(sh, n, geom, uv, float(n.props.get("projection_blend", 0.0)), alpha_read)
    if projection == "SPHERE":
        uv = map_to_sphere((uv - 0.5) * 2.0)
    elif projection == "TUBE":
        uv = map_to_tube((uv - 0.5) * 2.0)
    elif projection != "FLAT":
        sh.warn_once(("projection", projection),
                     f"image texture projection {projection} is not supported; using Flat")
    color, alpha = _lookup(sh, n, uv, unassociate=alpha_read)
    return {"Color": color, "Alpha": alpha}


def map_to_sphere(d):
    """(N, 3) Cycles' sphere mapping of vectors (N, 3): the longitude around
    z (from +y) and the latitude from +z, each in [0, 1] (third column zero)."""
    d = f32(d)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    length = np.sqrt(x * x + y * y + z * z)
    on = length > 0
    u = np.where((x == 0) & (y == 0), 0.0, (1.0 - np.arctan2(x, y) / np.pi) / 2.0)
    v = 1.0 - np.arccos(np.clip(z / np.where(on, length, 1.0), -1.0, 1.0)) / np.pi
    return np.stack([np.where(on, u, 0.0), np.where(on, v, 0.0), np.zeros_like(u)], axis=1).astype(np.float32)


def map_to_tube(d):
    """(N, 3) Cycles' tube mapping: the angle around z (from +y) and the
    height, z from [-1, 1] to [0, 1] (third column zero)."""
    d = f32(d)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    length = np.sqrt(x * x + y * y)
    on = length > 0
    safe = np.where(on, length, 1.0)
    u = (1.0 - np.arctan2(x / safe, y / safe) / np.pi) / 2.0
    v = (z + 1.0) / 2.0
    return np.stack([np.where(on, u, 0.0), np.where(on, v, 0.0), np.zeros_like(u)], axis=1).astype(np.float32)


def box_weights(normal, blend):
    """(N, 3) Cycles' Box projection weights of the x, y and z planar
    lookups from object-space normals (N, 3): one side where the normal is
    near an axis (the corners of the triangle of |n| / sum |n|), two sides
    blended along the edges between and three in the middle, by the
    Projection Blend."""
    a = np.abs(f32(normal))
    a = a / np.maximum(a.sum(axis=1, keepdims=True), 1e-30)
    x, y, z = a[:, 0], a[:, 1], a[:, 2]
    limit = 0.5 * (1.0 + blend)
    w = np.zeros_like(a)
    corner_x = (x > limit * (x + y)) & (x > limit * (x + z))
    corner_y = ~corner_x & (y > limit * (x + y)) & (y > limit * (y + z))
    corner_z = ~corner_x & ~corner_y & (z > limit * (x + z)) & (z > limit * (y + z))
    rest = ~(corner_x | corner_y | corner_z)
    w[corner_x, 0] = 1.0
    w[corner_y, 1] = 1.0
    w[corner_z, 2] = 1.0
    if blend <= 0:
        w[rest, 0] = 1.0        # (no valid choice: one side, as Cycles)
        return w

    def ramp(t):
        return np.clip((t - 0.5 * (1.0 - blend)) / blend, 0.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = rest & (z < (1.0 - limit) * (y + x))
        yz = rest & ~xy & (x < (1.0 - limit) * (y + z))
        xz = rest & ~xy & ~yz & (y < (1.0 - limit) * (x + z))
        mid = rest & ~xy & ~yz & ~xz
        t = ramp(x / (x + y))
        w[xy, 0], w[xy, 1] = t[xy], 1.0 - t[xy]
        t = ramp(y / (y + z))
        w[yz, 1], w[yz, 2] = t[yz], 1.0 - t[yz]
        t = ramp(x / (x + z))
        w[xz, 0], w[xz, 2] = t[xz], 1.0 - t[xz]
        w[mid] = ((2.0 - limit) * a[mid] + (limit - 1.0)) / (2.0 * limit - 1.0)
    return w


def _box_lookup(sh, n, geom, co, blend, unassociate):
    """Box projection: the three planar lookups (mapped so that no side is
    mirrored, as Cycles maps them) weighed by box_weights."""
    normal = geom.object_vector(geom.normal)
    w = box_weights(normal, max(0.0, min(1.0, blend)))
    x, y, z = co[:, 0], co[:, 1], co[:, 2]
    sides = (np.stack([np.where(normal[:, 0] < 0, 1.0 - y, y), z], axis=1),
             np.stack([np.where(normal[:, 1] > 0, 1.0 - x, x), z], axis=1),
             np.stack([np.where(normal[:, 2] > 0, 1.0 - y, y), x], axis=1))
    color = np.zeros((geom.n, 3), np.float32)
    alpha = np.zeros(geom.n, np.float32)
    for k, uv in enumerate(sides):
        rows = np.nonzero(w[:, k] > 0)[0]
        if len(rows) == 0:
            continue
        uv3 = np.concatenate([uv[rows], np.zeros((len(rows), 1), np.float32)], axis=1)
        c, a = _lookup(sh, n, uv3, unassociate=unassociate)
        color[rows] += c * w[rows, k, None]
        alpha[rows] += a * w[rows, k]
    return {"Color": color, "Alpha": alpha}


def direction_to_equirect(d):
    """Cycles' equirectangular mapping of directions (z up) to (u, v) in [0, 1]."""
    d = f32(d)
    u = -np.arctan2(d[..., 1], d[..., 0]) / (2 * np.pi) + 0.5
    v = np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1])) / np.pi + 0.5
    return np.stack([u, v], axis=-1).astype(np.float32)


def direction_to_mirror_ball(d):
    d = f32(d)
    dx, dy, dz = d[..., 0], d[..., 1] - 1.0, d[..., 2]
    div = 2.0 * np.sqrt(np.maximum(-0.5 * dy, 0.0))
    div = np.where(div > 0, div, 1)
    return np.stack([0.5 * dx / div + 0.5, 0.5 * dz / div + 0.5], axis=-1).astype(np.float32)


@varying
@node("TEX_ENVIRONMENT")
def environment_texture(inp, geom, n, sh):
    if inp.linked("Vector"):
        d = inp.vector("Vector")
    else:
        d = geom.position if geom.is_world else -geom.incoming
    d = np.broadcast_to(f32(d), (geom.n, 3))
    length = np.sqrt((d * d).sum(axis=1, keepdims=True))
    d = d / np.where(length > 0, length, 1)
    if n.props.get("projection", "EQUIRECTANGULAR") == "MIRROR_BALL":
        uv = direction_to_mirror_ball(d)
    else:
        uv = direction_to_equirect(d)
    uv3 = np.concatenate([uv, np.zeros((geom.n, 1), np.float32)], axis=1)
    n2 = n if "extension" in n.props else _with_props(n, extension="REPEAT")
    color, _ = _lookup(sh, n2, uv3)
    return {"Color": color}


def _with_props(n, **extra):
    from .graph import Node   # noqa: PLC0415
    return Node(n.kind, n.inputs, {**n.props, **extra}, n.name)


def _coords(inp, geom):
    v = inp.vector("Vector") if inp.linked("Vector") else geom.generated
    return np.broadcast_to(f32(v), (geom.n, 3))


@varying
@node("TEX_CHECKER")
def checker_texture(inp, geom, n, sh):
    p = _coords(inp, geom) * f32(inp.float("Scale", 5.0))[..., None]
    p = (p + 1e-6) * 0.999999
    i = np.abs(np.floor(p).astype(np.int64)) % 2
    # Cycles: ((xi % 2 == yi % 2) == zi % 2) ? 1 : 0, and Fac 1 is Color1.
    fac = ((i[:, 0] == i[:, 1]).astype(np.int64) == i[:, 2]).astype(np.float32)
    c1, c2 = inp.color("Color1", (0.8, 0.8, 0.8)), inp.color("Color2", (0.2, 0.2, 0.2))
    return {"Color": f32(np.where(fac[:, None] > 0, c1, c2)), "Fac": fac}


def _brick_noise(n):
    """Cycles' brick_noise: a float in [0, 1) of a uint32 (wrapping arithmetic)."""
    n = (n + np.uint32(1013)) & np.uint32(0x7FFFFFFF)
    n = (n >> np.uint32(13)) ^ n
    nn = (n * (n * n * np.uint32(60493) + np.uint32(19990303)) + np.uint32(1376312589)) & np.uint32(0x7FFFFFFF)
    return np.float32(0.5) * (nn.astype(np.float32) / np.float32(1073741824.0))


@varying
@node("TEX_BRICK")
def brick_texture(inp, geom, n, sh):
    """Cycles' Brick Texture (svm_brick): rows of bricks, every
    ``offset_frequency``-th row shifted by ``offset`` of a brick and every
    ``squash_frequency``-th row's bricks ``squash`` times as wide; each
    brick's tint between Color1 and Color2 a hash of its row and number
    (plus Bias); mortar within Mortar Size of a brick's edge, blended over
    Mortar Smooth."""
    p = _coords(inp, geom) * f32(inp.float("Scale", 5.0))[..., None]
    x_in, y_in = p[:, 0].astype(np.float32), p[:, 1].astype(np.float32)
    width = np.broadcast_to(f32(inp.float("Brick Width", 0.5)), (geom.n,)).astype(np.float32)
    height = np.broadcast_to(f32(inp.float("Row Height", 0.25)), (geom.n,)).astype(np.float32)
    mortar_size = f32(inp.float("Mortar Size", 0.02))
    smooth = f32(inp.float("Mortar Smooth", 0.1))
    bias = f32(inp.float("Bias", 0.0))
    offset_amount = np.float32(n.props.get("offset", 0.5))
    offset_every = int(n.props.get("offset_frequency", 2))
    squash = np.float32(n.props.get("squash", 1.0))
    squash_every = int(n.props.get("squash_frequency", 2))
    with np.errstate(divide="ignore", invalid="ignore"):
        row = np.floor(y_in / height).astype(np.int64)
        offset = np.zeros(geom.n, np.float32)
        if offset_every and squash_every:
            width = np.where(row % squash_every != 0, width, width * squash).astype(np.float32)
            offset = np.where(row % offset_every != 0, np.float32(0), width * offset_amount).astype(np.float32)
        brick = np.floor((x_in + offset) / width).astype(np.int64)
        x = (x_in + offset) - width * brick.astype(np.float32)
        y = y_in - height * row.astype(np.float32)
    key = (((row << 16) + (brick & 0xFFFF)) & 0xFFFFFFFF).astype(np.uint32)
    tint = np.clip(_brick_noise(key) + bias, 0.0, 1.0)
    edge = np.minimum(np.minimum(x, y), np.minimum(width - x, height - y))
    ramp = 1.0 - edge / np.where(mortar_size != 0, mortar_size, 1.0)
    t = np.clip(ramp / np.where(smooth != 0, smooth, 1.0), 0.0, 1.0)
    blend = np.where(ramp < smooth, t * t * (3.0 - 2.0 * t), 1.0)
    mortar = np.where(edge >= mortar_size, 0.0, np.where(smooth == 0, 1.0, blend)).astype(np.float32)
    mortar = np.nan_to_num(mortar, nan=0.0)
    c1, c2 = inp.color("Color1", (0.8, 0.8, 0.8)), inp.color("Color2", (0.2, 0.2, 0.2))
    c3 = inp.color("Mortar", (0.0, 0.0, 0.0))
    tint = np.where(mortar != 1.0, tint, 0.0)[:, None]
    brick_color = (1.0 - tint) * c1 + tint * c2
    color = brick_color * (1.0 - mortar[:, None]) + c3 * mortar[:, None]
    return {"Color": f32(color), "Fac": mortar}


@varying
@node("TEX_WAVE")
def wave_texture(inp, geom, n, sh):
    """Cycles' Wave Texture (svm_wave): bands along an axis or the diagonal,
    or rings around an axis or a point, 20 units of phase per unit, shifted
    by Phase Offset and by Distortion times a centred fBM of the point
    (Detail, Detail Scale, Detail Roughness), through a sine, saw or
    triangle profile."""
    p = _coords(inp, geom) * f32(inp.float("Scale", 5.0)).reshape(-1, 1)
    p = ((p + np.float32(1e-6)) * np.float32(0.999999)).astype(np.float32)
    if n.props.get("wave_type", "BANDS") == "RINGS":
        keep = {"X": (0, 1, 1), "Y": (1, 0, 1), "Z": (1, 1, 0)}.get(n.props.get("rings_direction", "X"), (1, 1, 1))
        r = p * f32(keep)
        phase = np.sqrt((r * r).sum(axis=1)) * np.float32(20.0)
    else:
        axis = n.props.get("bands_direction", "X")
        phase = (p.sum(axis=1) * np.float32(10.0)) if axis == "DIAGONAL" else \
            p[:, "XYZ".index(axis) if axis in ("X", "Y", "Z") else 0] * np.float32(20.0)
    phase = phase + f32(inp.float("Phase Offset", 0.0))
    distortion = np.broadcast_to(f32(inp.float("Distortion", 0.0)), (geom.n,))
    if np.any(distortion != 0):
        q = (p * f32(inp.float("Detail Scale", 1.0)).reshape(-1, 1)).astype(np.float32)
        turbulence = fbm(q, inp.float("Detail", 2.0), inp.float("Detail Roughness", 0.5), 2.0)
        phase = phase + distortion * (turbulence * np.float32(2.0) - np.float32(1.0))
    profile = n.props.get("wave_profile", "SIN")
    if profile == "SAW":
        t = phase / np.float32(2.0 * np.pi)
        fac = t - np.floor(t)
    elif profile == "TRI":
        t = phase / np.float32(2.0 * np.pi)
        fac = np.abs(t - np.floor(t + np.float32(0.5))) * np.float32(2.0)
    else:
        fac = np.float32(0.5) + np.float32(0.5) * np.sin(phase - np.float32(np.pi / 2))
    fac = np.nan_to_num(np.broadcast_to(fac, (geom.n,)).astype(np.float32), nan=0.0)
    return {"Color": np.repeat(fac[:, None], 3, axis=1), "Fac": fac}


# Cycles' Magic Texture: after the first three waves, up to ten more steps,
# each replacing one coordinate by a sine or cosine of a signed sum of all three.
_MAGIC_STEPS = ((1, -1, (1, -1, 1), np.cos), (0, 1, (1, -1, -1), np.cos), (2, 1, (-1, -1, -1), np.sin),
                (0, -1, (-1, 1, -1), np.cos), (1, -1, (-1, 1, 1), np.sin), (1, -1, (-1, 1, 1), np.cos),
                (0, 1, (1, 1, 1), np.cos), (2, 1, (1, 1, -1), np.sin), (0, -1, (-1, -1, 1), np.cos),
                (1, -1, (1, -1, 1), np.sin))


@varying
@node("TEX_MAGIC")
def magic_texture(inp, geom, n, sh):
    """Cycles' Magic Texture (svm_magic): psychedelic interference of sines
    and cosines, turbulence_depth steps deep, scaled by Distortion."""
    p = (_coords(inp, geom) * f32(inp.float("Scale", 5.0)).reshape(-1, 1)).astype(np.float64)
    p = np.fmod(p, 4.0 * np.pi)     # sines of 5 (x + y + z): unchanged, and finite for huge p
    d = np.broadcast_to(np.asarray(inp.float("Distortion", 1.0), np.float64), (geom.n,))
    c = [np.sin((p[:, 0] + p[:, 1] + p[:, 2]) * 5.0), np.cos((-p[:, 0] + p[:, 1] - p[:, 2]) * 5.0),
         -np.cos((-p[:, 0] - p[:, 1] + p[:, 2]) * 5.0)]
    depth = int(n.props.get("turbulence_depth", 2))
    if depth > 0:
        c = [v * d for v in c]
        for axis, sign, signs, fn in _MAGIC_STEPS[:min(depth, 10)]:
            c[axis] = sign * fn(signs[0] * c[0] + signs[1] * c[1] + signs[2] * c[2]) * d
    scale = np.where(d != 0, 2.0 * d, 1.0)
    color = np.stack([0.5 - v / scale for v in c], axis=1).astype(np.float32)
    color = np.nan_to_num(color, nan=0.0, posinf=0.0, neginf=0.0)
    return {"Color": color, "Fac": color.mean(axis=1).astype(np.float32)}


def gradient(kind, p):
    x, y = p[:, 0], p[:, 1]
    if kind == "QUADRATIC":
        f = np.maximum(x, 0) ** 2
    elif kind == "EASING":
        r = np.clip(x, 0, 1)
        t = r * r
        f = 3 * t - 2 * t * r
    elif kind == "DIAGONAL":
        f = (x + y) * 0.5
    elif kind == "RADIAL":
        f = np.arctan2(y, x) / (2 * np.pi) + 0.5
    elif kind in ("QUADRATIC_SPHERE", "SPHERICAL"):
        r = np.maximum(0.999999 - np.sqrt((p * p).sum(axis=1)), 0)
        f = r * r if kind == "QUADRATIC_SPHERE" else r
    else:   # LINEAR
        f = x
    return np.clip(f, 0, 1).astype(np.float32)


@varying
@node("TEX_GRADIENT")
def gradient_texture(inp, geom, n, sh):
    f = gradient(n.props.get("gradient_type", "LINEAR"), _coords(inp, geom))
    return {"Color": np.repeat(f[:, None], 3, axis=1), "Fac": f}


@varying
@node("TEX_SKY")
def sky_texture(inp, geom, n, sh):
    """Blender's sky models (core/materials/shader/sky.py); a type not modelled yet is a
    plain blue gradient over a darker ground, of about a clear sky's
    brightness, so scenes lit by it stay lit."""
    from .sky import sky_model   # noqa: PLC0415 (tables are built on first use)
    d = inp.vector("Vector") if inp.linked("Vector") else (geom.position if geom.is_world else -geom.incoming)
    d = np.broadcast_to(f32(d), (geom.n, 3))
    model = sky_model(n.props)
    if model is not None:
        return {"Color": model.radiance(d)}
    sky_type = n.props.get("sky_type", "")
    sh.warn_once(("sky", sky_type), f"Sky Texture '{n.name}': {sky_type.replace('_', ' ').title()} is "
                                    f"approximated by a gradient (no physical sky)")
    z = np.clip(d[:, 2] / np.maximum(np.sqrt((d * d).sum(axis=1)), 1e-8), -1, 1)
    horizon, zenith, ground = f32((0.45, 0.55, 0.7)), f32((0.12, 0.25, 0.6)), f32((0.1, 0.1, 0.1))
    t = np.sqrt(np.maximum(z, 0))[:, None]
    sky = horizon + t * (zenith - horizon)
    return {"Color": f32(np.where((z >= 0)[:, None], sky, ground))}


@varying
@node("TEX_WHITE_NOISE")
def white_noise_texture(inp, geom, n, sh):
    """Cycles' White Noise: a hash of the input's float bits (1D: W; 2D: x,
    y; 3D: the vector; 4D: the vector and W), as Value and Color. An
    unlinked Vector is the hit's position, as in Cycles."""
    dims = {"1D": 1, "2D": 2, "4D": 4}.get(n.props.get("noise_dimensions", "3D"), 3)
    v = np.broadcast_to(f32(inp.vector("Vector") if inp.linked("Vector") else geom.position), (geom.n, 3))
    w = np.broadcast_to(f32(inp.float("W", 0.0)).reshape(-1), (geom.n,))
    columns = {1: [w], 2: [v[:, 0], v[:, 1]], 3: [v[:, 0], v[:, 1], v[:, 2]],
               4: [v[:, 0], v[:, 1], v[:, 2], w]}[dims]
    columns = [np.ascontiguousarray(c, np.float32) for c in columns]
    return {"Value": hash_floats(*columns), "Color": hash_floats_to_colour(columns)}
