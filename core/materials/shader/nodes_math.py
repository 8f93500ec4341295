"""Math nodes: Math, Vector Math, Clamp, Map Range, Value, RGB, Separate and
Combine XYZ.

Operations follow Cycles' "safe" definitions (``svm/math_util.h``): a
division by zero gives 0, the square root and logarithm of a negative number
give 0, a negative base to a fractional power gives 0. Inputs are scalars,
(N,) or (N, 3) arrays; numpy broadcasting does the rest.
"""

import numpy as np

from .evaluate import BLACK, f32, node, vec


def _div(a, b):
    return np.where(b != 0, a / np.where(b != 0, b, 1), 0).astype(np.float32)


def _pow(a, b):
    ok = (a >= 0) | (np.floor(b) == b)
    return np.where(ok, np.power(np.where(ok, a, 0), b), 0).astype(np.float32)


def _fmod(a, b):
    return np.where(b != 0, np.fmod(a, np.where(b != 0, b, 1)), 0).astype(np.float32)


def _floored_mod(a, b):
    return np.where(b != 0, a - np.floor(_div(a, b)) * b, 0).astype(np.float32)


def _wrap(v, hi, lo):
    r = hi - lo
    return np.where(r != 0, v - r * np.floor(_div(v - lo, r)), lo).astype(np.float32)


def _smoothmin(a, b, c):
    h = np.maximum(c - np.abs(a - b), 0) / np.where(c != 0, c, 1)
    return np.where(c != 0, np.minimum(a, b) - h * h * h * c * (1.0 / 6.0), np.minimum(a, b))


def _pingpong(a, b):
    frac = lambda x: x - np.floor(x)   # noqa: E731
    return np.where(b != 0, np.abs(frac(_div(a - b, b * 2)) * b * 2 - b), 0)


MATH = {
    "ADD": lambda a, b, c: a + b,
    "SUBTRACT": lambda a, b, c: a - b,
    "MULTIPLY": lambda a, b, c: a * b,
    "DIVIDE": lambda a, b, c: _div(a, b),
    "MULTIPLY_ADD": lambda a, b, c: a * b + c,
    "POWER": lambda a, b, c: _pow(a, b),
    "LOGARITHM": lambda a, b, c: np.where((a > 0) & (b > 0) & (b != 1),
                                          np.log(np.maximum(a, 1e-30)) / np.log(np.where((b > 0) & (b != 1), b, 2)), 0),
    "SQRT": lambda a, b, c: np.sqrt(np.maximum(a, 0)),
    "INVERSE_SQRT": lambda a, b, c: np.where(a > 0, 1 / np.sqrt(np.where(a > 0, a, 1)), 0),
    "ABSOLUTE": lambda a, b, c: np.abs(a),
    "EXPONENT": lambda a, b, c: np.exp(a),
    "MINIMUM": lambda a, b, c: np.minimum(a, b),
    "MAXIMUM": lambda a, b, c: np.maximum(a, b),
    "LESS_THAN": lambda a, b, c: (a < b).astype(np.float32),
    "GREATER_THAN": lambda a, b, c: (a > b).astype(np.float32),
    "SIGN": lambda a, b, c: np.sign(a),
    "COMPARE": lambda a, b, c: (np.abs(a - b) <= np.maximum(c, 1e-5)).astype(np.float32),
    "SMOOTH_MIN": lambda a, b, c: _smoothmin(a, b, c),
    "SMOOTH_MAX": lambda a, b, c: -_smoothmin(-a, -b, c),
    "ROUND": lambda a, b, c: np.floor(a + 0.5),
    "FLOOR": lambda a, b, c: np.floor(a),
    "CEIL": lambda a, b, c: np.ceil(a),
    "TRUNC": lambda a, b, c: np.trunc(a),
    "FRACT": lambda a, b, c: a - np.floor(a),
    "MODULO": lambda a, b, c: _fmod(a, b),
    "FLOORED_MODULO": lambda a, b, c: _floored_mod(a, b),
    "WRAP": lambda a, b, c: _wrap(a, b, c),
    "SNAP": lambda a, b, c: np.floor(_div(a, b)) * b,
    "PINGPONG": lambda a, b, c: _pingpong(a, b),
    "SINE": lambda a, b, c: np.sin(a),
    "COSINE": lambda a, b, c: np.cos(a),
    "TANGENT": lambda a, b, c: np.tan(a),
    "ARCSINE": lambda a, b, c: np.arcsin(np.clip(a, -1, 1)),
    "ARCCOSINE": lambda a, b, c: np.arccos(np.clip(a, -1, 1)),
    "ARCTANGENT": lambda a, b, c: np.arctan(a),
    "ARCTAN2": lambda a, b, c: np.arctan2(a, b),
    "SINH": lambda a, b, c: np.sinh(a),
    "COSH": lambda a, b, c: np.cosh(a),
    "TANH": lambda a, b, c: np.tanh(a),
    "RADIANS": lambda a, b, c: a * np.float32(np.pi / 180),
    "DEGREES": lambda a, b, c: a * np.float32(180 / np.pi),
}


@node("MATH")
def math(inp, geom, n, sh):
    a, b, c = inp.float("Value", 0.5), inp.float("Value_001", 0.5), inp.float("Value_002", 0.5)
    op = inp.prop("operation", "ADD")
    fn = MATH.get(op)
    if fn is None:
        sh.warn_once(("math", op), f"Math operation {op} is not supported; it gives 0")
        return {"Value": f32(0)}
    v = f32(fn(a, b, c))
    if inp.prop("use_clamp", False):
        v = np.clip(v, 0, 1)
    return {"Value": v}


def _dot(a, b):
    return (a * b).sum(axis=-1)


def _length(a):
    return np.sqrt(_dot(a, a))


def _normalize(a):
    n = _length(a)
    return a / np.where(n > 0, n, 1)[..., None]


def _refract(i, nrm, eta):
    k = 1 - eta * eta * (1 - _dot(nrm, i) ** 2)
    out = eta[..., None] * i - (eta * _dot(nrm, i) + np.sqrt(np.maximum(k, 0)))[..., None] * nrm
    return np.where((k < 0)[..., None], 0, out)


def _project(a, b):
    bb = _dot(b, b)
    return b * _div(_dot(a, b), bb)[..., None]


VECTOR_OPS = {   # (a, b, c, scale) -> vector or ("value", v)
    "ADD": lambda a, b, c, s: a + b,
    "SUBTRACT": lambda a, b, c, s: a - b,
    "MULTIPLY": lambda a, b, c, s: a * b,
    "DIVIDE": lambda a, b, c, s: _div(a, b),
    "MULTIPLY_ADD": lambda a, b, c, s: a * b + c,
    "CROSS_PRODUCT": lambda a, b, c, s: np.cross(*np.broadcast_arrays(a, b)),
    "PROJECT": lambda a, b, c, s: _project(a, b),
    "REFLECT": lambda a, b, c, s: a - 2 * _dot(_normalize(b), a)[..., None] * _normalize(b),
    "REFRACT": lambda a, b, c, s: _refract(_normalize(a), _normalize(b), f32(s)),
    "FACEFORWARD": lambda a, b, c, s: np.where((_dot(c, b) < 0)[..., None], a, -a),
    "DOT_PRODUCT": lambda a, b, c, s: ("value", _dot(a, b)),
    "DISTANCE": lambda a, b, c, s: ("value", _length(a - b)),
    "LENGTH": lambda a, b, c, s: ("value", _length(a)),
    "SCALE": lambda a, b, c, s: a * f32(s)[..., None],
    "NORMALIZE": lambda a, b, c, s: _normalize(a),
    "ABSOLUTE": lambda a, b, c, s: np.abs(a),
    "POWER": lambda a, b, c, s: _pow(a, b),
    "SIGN": lambda a, b, c, s: np.sign(a),
    "MINIMUM": lambda a, b, c, s: np.minimum(a, b),
    "MAXIMUM": lambda a, b, c, s: np.maximum(a, b),
    "FLOOR": lambda a, b, c, s: np.floor(a),
    "CEIL": lambda a, b, c, s: np.ceil(a),
    "FRACTION": lambda a, b, c, s: a - np.floor(a),
    "MODULO": lambda a, b, c, s: _fmod(a, b),
    "WRAP": lambda a, b, c, s: _wrap(a, b, c),
    "SNAP": lambda a, b, c, s: np.floor(_div(a, b)) * b,
    "SINE": lambda a, b, c, s: np.sin(a),
    "COSINE": lambda a, b, c, s: np.cos(a),
    "TANGENT": lambda a, b, c, s: np.tan(a),
}


@node("VECT_MATH")
def vector_math(inp, geom, n, sh):
    a, b, c = inp.vector("Vector"), inp.vector("Vector_001"), inp.vector("Vector_002")
    s = inp.float("Scale", 1.0)
    op = inp.prop("operation", "ADD")
    fn = VECTOR_OPS.get(op)
    if fn is None:
        sh.warn_once(("vmath", op), f"Vector Math operation {op} is not supported; it gives 0")
        return {"Vector": BLACK, "Value": f32(0)}
    r = fn(a, b, c, s)
    if isinstance(r, tuple):
        return {"Value": f32(r[1]), "Vector": BLACK}
    return {"Vector": f32(r), "Value": f32(0)}


@node("CLAMP")
def clamp(inp, geom, n, sh):
    v, lo, hi = inp.float("Value", 1.0), inp.float("Min", 0.0), inp.float("Max", 1.0)
    if inp.prop("clamp_type", "MINMAX") == "RANGE":
        lo, hi = np.minimum(lo, hi), np.maximum(lo, hi)
    return {"Result": f32(np.minimum(np.maximum(v, lo), hi))}


def _smoothstep(e0, e1, x):
    t = np.clip(_div(x - e0, e1 - e0), 0, 1)
    return t * t * (3 - 2 * t)


def _smootherstep(e0, e1, x):
    t = np.clip(_div(x - e0, e1 - e0), 0, 1)
    return t * t * t * (t * (t * 6 - 15) + 10)


def _map_range(v, fmin, fmax, tmin, tmax, steps, mode, clamp_):
    if mode in ("SMOOTHSTEP", "SMOOTHERSTEP"):
        step = _smoothstep if mode == "SMOOTHSTEP" else _smootherstep
        f = np.where(fmin > fmax, 1 - step(fmax, fmin, v), step(fmin, fmax, v))
        return tmin + f * (tmax - tmin)
    f = _div(v - fmin, fmax - fmin)
    if mode == "STEPPED":
        f = np.where(steps > 0, np.floor(f * (steps + 1)) / np.where(steps > 0, steps, 1), 0)
    r = tmin + f * (tmax - tmin)
    if clamp_:
        r = np.clip(r, np.minimum(tmin, tmax), np.maximum(tmin, tmax))
    return r


@node("MAP_RANGE")
def map_range(inp, geom, n, sh):
    mode = inp.prop("interpolation_type", "LINEAR")
    clamp_ = inp.prop("clamp", True)
    if inp.prop("data_type", "FLOAT") == "FLOAT_VECTOR":
        r = _map_range(inp.vector("Vector"), inp.vector("From_Min_FLOAT3"), inp.vector("From_Max_FLOAT3", (1, 1, 1)),
                       inp.vector("To_Min_FLOAT3"), inp.vector("To_Max_FLOAT3", (1, 1, 1)),
                       inp.vector("Steps_FLOAT3", (4, 4, 4)), mode, clamp_)
        return {"Vector": f32(r), "Result": f32(0)}
    r = _map_range(inp.float("Value", 1.0), inp.float("From Min", 0.0), inp.float("From Max", 1.0),
                   inp.float("To Min", 0.0), inp.float("To Max", 1.0), inp.float("Steps", 4.0), mode, clamp_)
    return {"Result": f32(r), "Vector": BLACK}


@node("VALUE")
def value(inp, geom, n, sh):
    return {"Value": f32(inp.prop("value", inp.prop("default_value", 0.5)))}


@node("RGB")
def rgb(inp, geom, n, sh):
    c = inp.prop("color", inp.prop("default_value", (0.5, 0.5, 0.5)))
    return {"Color": vec(f32(c)[:3])}


@node("SEPXYZ")
def separate_xyz(inp, geom, n, sh):
    v = inp.vector("Vector")
    return {"X": v[..., 0], "Y": v[..., 1], "Z": v[..., 2]}


@node("COMBXYZ")
def combine_xyz(inp, geom, n, sh):
    x, y, z = np.broadcast_arrays(inp.float("X"), inp.float("Y"), inp.float("Z"))
    return {"Vector": vec(np.stack([x, y, z], axis=-1))}
