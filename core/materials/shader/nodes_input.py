"""Input and vector nodes: Texture Coordinate, UV Map, Geometry, Object Info,
Light Path, Light Falloff, Color Attribute, Attribute, Fresnel, Layer Weight,
Mapping, Normal Map and Bump.

Conventions from Cycles (``svm/tex_coord.h``, ``svm/fresnel.h``,
``svm/mapping_util.h``, ``svm/bump.h``). Bump has no ray differentials here:
its height is sampled at BUMP_OFFSET times the scene's extent along two
tangents of the surface, which gives the same normal wherever the height is
smooth at that scale.
"""

import numpy as np

from ...bsdfs.fresnel import fresnel_dielectric
from ...camera import projection
from .evaluate import f32, node, varying

BUMP_OFFSET = 1e-4      # of the scene extent


def _norm(v):
    v = f32(v)
    n = np.sqrt((v * v).sum(axis=-1, keepdims=True))
    return (v / np.where(n > 0, n, 1)).astype(np.float32)


def _dot(a, b):
    return (a * b).sum(axis=-1)


def _cross(a, b):
    a, b = np.broadcast_arrays(a, b)
    return np.cross(a, b).astype(np.float32)


def _surface_normal(inp, geom, name="Normal"):
    return _norm(inp.vector(name)) if inp.linked(name) else geom.normal


def _camera_and_window(geom):
    """Cycles' Camera coordinates (camera space: x right, y up, z the
    distance along the view) and Window coordinates (the point's place on
    the whole frame, [0, 1]^2, z = 0) of the hits; zero for the world's
    shader and without a camera."""
    zero = np.zeros((geom.n, 3), np.float32)
    camera = getattr(getattr(geom, "scene", None), "camera", None) if not geom.is_world else None
    if camera is None or geom.n == 0:
        return zero, zero
    pos, axes = projection.camera_frame(camera)
    local = (np.asarray(geom.position, np.float64) - pos) @ axes
    cam = (local * np.array([1.0, 1.0, -1.0])).astype(np.float32)
    width, height = geom.scene.width, geom.scene.height
    film, _ = projection.project(camera, width, height, geom.position)
    window = np.stack([film[:, 0] / width, film[:, 1] / height, np.zeros(geom.n, np.float32)], axis=1)
    return cam, np.nan_to_num(window).astype(np.float32)


@varying
@node("TEX_COORD")
def texture_coordinate(inp, geom, n, sh):
    cam, window = _camera_and_window(geom)
    out = {"Generated": geom.generated, "Normal": geom.object_vector(geom.normal), "UV": geom.uv(""),
           "Object": geom.object_coords, "Camera": cam, "Window": window}
    inv = n.props.get("object_matrix_inverse")
    if inv is not None:
        m = np.asarray(inv, np.float32).reshape(4, 4)
        out["Object"] = (geom.position @ m[:3, :3].T + m[:3, 3]).astype(np.float32)
    i, nrm = geom.incoming, geom.normal
    out["Reflection"] = (2 * _dot(i, nrm)[:, None] * nrm - i).astype(np.float32)
    return out


@varying
@node("UVMAP")
def uv_map(inp, geom, n, sh):
    return {"UV": geom.uv(n.props.get("uv_map", ""))}


def radial_tangent(geom):
    """Cycles' tangent without a UV map (the Geometry node's Tangent): around
    the object's Z axis through the centre of its Generated coordinates,
    made perpendicular to the shading normal."""
    g = geom.generated
    data = np.stack([-(g[:, 1] - 0.5), g[:, 0] - 0.5, np.zeros(geom.n, np.float32)], axis=1).astype(np.float32)
    data = geom.object_vector_to_world(data) if not geom.is_world else data
    nrm = geom.normal
    return _norm(_cross(nrm, _norm(_cross(data, nrm))))


@varying
@node("NEW_GEOMETRY")
def geometry(inp, geom, n, sh):
    t = radial_tangent(geom)
    return {"Position": geom.position, "Normal": geom.normal, "Tangent": t,
            "True Normal": geom.true_normal, "Incoming": geom.incoming,
            "Parametric": geom.uv("") * 0, "Backfacing": geom.backfacing,
            "Pointiness": np.full(geom.n, 0.5, np.float32), "Random Per Island": np.zeros(geom.n, np.float32)}


@varying
@node("OBJECT_INFO")
def object_info(inp, geom, n, sh):
    return {"Location": geom.object_info("Location"), "Color": geom.object_info("Color"),
            "Alpha": geom.object_info("Alpha"), "Random": geom.object_info("Random"),
            "Object Index": geom.object_info("Object Index"),
            "Material Index": np.full(geom.n, n.props.get("material_index", 0.0), np.float32)}


@varying
@node("LIGHT_PATH")
def light_path(inp, geom, n, sh):
    zero = np.float32(0)
    if getattr(geom, "shadow_ray", False):
        # A shadow ray deciding whether it passes a surface: Cycles evaluates
        # it with the shadow flag alone (glass made transparent to shadows).
        out = {name: zero for name in _LIGHT_PATH_OUTPUTS}
        out["Is Shadow Ray"] = np.float32(1)
        return out
    cam = np.float32(1.0 if geom.camera_ray else 0.0)
    return {"Is Camera Ray": cam, "Is Shadow Ray": zero, "Is Diffuse Ray": 1 - cam, "Is Glossy Ray": zero,
            "Is Singular Ray": zero, "Is Reflection Ray": 1 - cam, "Is Transmission Ray": zero,
            "Is Volume Scatter Ray": zero, "Ray Length": zero, "Ray Depth": 1 - cam,
            "Diffuse Depth": 1 - cam, "Glossy Depth": zero, "Transparent Depth": zero,
            "Transmission Depth": zero, "Portal Depth": zero}


_LIGHT_PATH_OUTPUTS = ("Is Camera Ray", "Is Shadow Ray", "Is Diffuse Ray", "Is Glossy Ray", "Is Singular Ray",
                       "Is Reflection Ray", "Is Transmission Ray", "Is Volume Scatter Ray", "Ray Length",
                       "Ray Depth", "Diffuse Depth", "Glossy Depth", "Transparent Depth",
                       "Transmission Depth", "Portal Depth")


# Cycles' ray length of distant lights (the sun): Light Falloff passes its Strength.
FAR = np.float32(np.finfo(np.float32).max)


@node("LIGHT_FALLOFF")
def light_falloff(inp, geom, n, sh):
    """Cycles' svm light falloff: Strength times 1, d or d^2 (Quadratic,
    Linear, Constant) and d^2 / (Smooth + d^2) where Smooth > 0, d the ray
    length. A light's node tree is evaluated with the distances to its
    samples (restir_addon/export/lights.py turns it into the light's
    falloff); surfaces carry no ray length here: d = 1, with a warning where
    that matters (a Smooth, or the Linear or Constant output read)."""
    strength = inp.float("Strength", 100.0)
    smooth = inp.float("Smooth", 0.0)
    d = getattr(geom, "ray_length", None)
    if d is None:
        d = np.float32(1)
        index = sh.index.get(id(n)) if sh is not None else None
        if index is not None and (np.any(smooth > 0) or any(
                (index, name) in sh.read_outputs for name in ("Linear", "Constant"))):
            sh.warn_once(("falloff", index), f"node '{n.name or n.kind}': Light Falloff outside a light's "
                         f"nodes is evaluated at distance 1")
    d = f32(d)
    if np.all(d >= FAR):
        return {"Quadratic": strength, "Linear": strength, "Constant": strength}
    d2 = d * d
    soft = np.where(smooth > 0, d2 / np.maximum(smooth + d2, np.float32(1e-30)), np.float32(1))
    return {"Quadratic": f32(strength * soft), "Linear": f32(strength * d * soft),
            "Constant": f32(strength * d2 * soft)}


@varying
@node("VERTEX_COLOR")
def color_attribute(inp, geom, n, sh):
    c, a = geom.attribute(n.props.get("layer_name", ""))
    return {"Color": c, "Alpha": a}


@varying
@node("ATTRIBUTE")
def attribute(inp, geom, n, sh):
    kind = n.props.get("attribute_type", "GEOMETRY")
    name = n.props.get("attribute_name", "")
    if kind in ("OBJECT", "INSTANCER"):
        v = geom.object_attribute(f"{kind.lower()}:{name}")
        c, a = np.ascontiguousarray(v[:, :3]), np.ascontiguousarray(v[:, 3])
    elif kind == "GEOMETRY" and name:
        c, a = geom.attribute(name)
    else:
        # View Layer (warned about at compile time), or no name: Cycles finds
        # no attribute and reads zero (the Color Attribute node's empty name
        # is the mesh's default colours instead).
        c, a = np.zeros((geom.n, 3), np.float32), np.zeros(geom.n, np.float32)
    return {"Color": c, "Vector": c, "Fac": c.mean(axis=-1).astype(np.float32), "Alpha": a}


@node("AMBIENT_OCCLUSION", approximated="its occlusion rays are not traced; it passes its Color "
                                        "(AO 1, as in the open)")
def ambient_occlusion(inp, geom, n, sh):
    """Cycles' Ambient Occlusion node scales its Color by the share of
    cosine-weighted rays within Distance that hit nothing; shading here
    traces no rays, so every point counts as open (right away from other
    geometry, too bright in creases)."""
    return {"Color": inp.color("Color", (1.0, 1.0, 1.0)), "AO": np.float32(1.0)}


@varying
@node("FRESNEL")
def fresnel(inp, geom, n, sh):
    eta = np.maximum(inp.float("IOR", 1.5), 1e-5)
    eta = np.where(geom.backfacing > 0, 1 / eta, eta)
    cos = _dot(geom.incoming, _surface_normal(inp, geom))
    return {"Fac": fresnel_dielectric(cos, eta)[0]}


@varying
@node("LAYER_WEIGHT")
def layer_weight(inp, geom, n, sh):
    blend = inp.float("Blend", 0.5)
    cos = _dot(geom.incoming, _surface_normal(inp, geom))
    eta = np.maximum(1 - blend, 1e-5)
    eta = np.where(geom.backfacing > 0, eta, 1 / eta)
    fres = fresnel_dielectric(cos, eta)[0]
    b = np.clip(blend, 0, 1 - 1e-5)
    b = np.where(b < 0.5, 2 * b, 0.5 / (1 - b))
    facing = np.where(blend != 0.5, np.power(np.abs(cos), b), np.abs(cos))
    return {"Fresnel": fres, "Facing": f32(1 - facing)}


def euler_matrix(rot):
    """Blender's XYZ Euler rotation as (..., 3, 3) matrices: X first, then Y, then Z."""
    rot = f32(rot)
    cx, cy, cz = np.cos(rot[..., 0]), np.cos(rot[..., 1]), np.cos(rot[..., 2])
    sx, sy, sz = np.sin(rot[..., 0]), np.sin(rot[..., 1]), np.sin(rot[..., 2])
    rows = [[cy * cz, sy * sx * cz - cx * sz, sy * cx * cz + sx * sz],
            [cy * sz, sy * sx * sz + cx * cz, sy * cx * sz - sx * cz],
            [-sy, cy * sx, cy * cx]]
    return np.stack([np.stack(np.broadcast_arrays(*r), axis=-1) for r in rows], axis=-2).astype(np.float32)


def _rotate(m, v):
    return np.einsum("...ij,...j->...i", m, v).astype(np.float32)


def _safe_div(a, b):
    return np.where(b != 0, a / np.where(b != 0, b, 1), 0).astype(np.float32)


@node("MAPPING")
def mapping(inp, geom, n, sh):
    v = inp.vector("Vector")
    loc, rot, scale = inp.vector("Location"), inp.vector("Rotation"), inp.vector("Scale", (1, 1, 1))
    m = euler_matrix(rot)
    kind = inp.prop("vector_type", "POINT")
    if kind == "POINT":
        out = _rotate(m, v * scale) + loc
    elif kind == "TEXTURE":
        out = _safe_div(_rotate(np.swapaxes(m, -1, -2), v - loc), scale)
    elif kind == "VECTOR":
        out = _rotate(m, v * scale)
    else:   # NORMAL
        out = _norm(_rotate(m, _safe_div(v, scale)))
    return {"Vector": f32(out)}


@varying
@node("NORMAL_MAP")
def normal_map(inp, geom, n, sh):
    color = inp.color("Color", (0.5, 0.5, 1.0))
    strength = np.maximum(inp.float("Strength", 1.0), 0)
    nrm = geom.normal
    c = 2 * color - 1
    space = inp.prop("space", "TANGENT")
    if space == "TANGENT":
        # Cycles builds the frame on the front side's normal and flips the
        # result for back faces (our normals already face the viewer).
        t, sign = geom.tangent(inp.prop("uv_map", ""))
        flip = np.where(geom.backfacing > 0, np.float32(-1), np.float32(1))[:, None]
        front = nrm * flip
        c = np.broadcast_to(c, (geom.n, 3))
        b = _cross(front, t) * sign[:, None]
        out = (c[:, 0:1] * t + c[:, 1:2] * b + c[:, 2:3] * front) * flip
    else:
        if space.startswith("BLENDER_"):
            c = np.stack([c[..., 0], -c[..., 2], c[..., 1]], axis=-1)
        out = geom.object_vector_to_world(c) if "OBJECT" in space else c
        out = np.broadcast_to(out, (geom.n, 3))
    out = _norm(out)
    # Keep the mapped normal on the side the shading normal faces.
    out = np.where((_dot(out, geom.true_normal) < 0)[:, None], nrm, out) if space == "TANGENT" else out
    s = f32(strength)
    s = s[:, None] if s.ndim else s
    return {"Normal": _norm(nrm + (out - nrm) * s)}


@varying
@node("BUMP")
def bump(inp, geom, n, sh):
    nrm = _surface_normal(inp, geom)
    strength = np.clip(inp.float("Strength", 1.0), 0, 1)
    dist = inp.float("Distance", 1.0) * (-1 if inp.prop("invert", False) else 1)
    if not inp.linked("Height") or geom.is_world:
        return {"Normal": nrm}
    delta = np.float32(BUMP_OFFSET * geom.scene.extent())
    # Two surface tangents from the shading normal.
    t = _norm(_cross(nrm, np.where(np.abs(nrm[:, 2:3]) < 0.9, [[0, 0, 1]], [[1, 0, 0]]).astype(np.float32)))
    b = _cross(nrm, t)
    h0 = inp.float("Height")
    hx = inp.at("Height", geom.offset(t * delta), "float")
    hy = inp.at("Height", geom.offset(b * delta), "float")
    dhx, dhy = (hx - h0) / delta, (hy - h0) / delta
    # Surface gradient: Rx = dPdy x N = b x n = t, Ry = N x dPdx = n x t = b (unit steps).
    surfgrad = t * f32(dhx)[..., None] + b * f32(dhy)[..., None]
    out = _norm(nrm - f32(dist)[..., None] * surfgrad if f32(dist).ndim else nrm - dist * surfgrad)
    s = f32(strength)
    s = s[:, None] if s.ndim else s
    return {"Normal": _norm(s * out + (1 - s) * nrm)}


@node("NORMAL")
def normal_node(inp, geom, n, sh):
    d = _norm(f32(n.props.get("direction", (0.0, 0.0, 1.0))).reshape(1, 3))
    return {"Normal": d, "Dot": f32((_norm(inp.vector("Normal", (0, 0, 1))) * d).sum(axis=-1))}
