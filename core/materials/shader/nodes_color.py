"""Colour nodes: Mix (float, vector, colour), legacy MixRGB, Invert, Gamma,
Hue/Saturation/Value, Bright/Contrast, Separate and Combine Color, RGB to BW,
Color Ramp and the curve nodes.

Blend modes follow Cycles' ``svm/color_util.h``. Colour Ramp and curves are
read from the tables the exporter baked (``props["ramp"]``, ``props["curves"]``).
"""

import numpy as np

from .evaluate import LUMA, f32, node, vec


def _c(x):
    x = f32(x)
    return x[..., None] if x.ndim else x


def rgb_to_hsv(rgb):
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    cmax = np.maximum(np.maximum(r, g), b)
    cmin = np.minimum(np.minimum(r, g), b)
    delta = cmax - cmin
    s = np.where(cmax != 0, delta / np.where(cmax != 0, cmax, 1), 0)
    safe = np.where(delta != 0, delta, 1)
    rc, gc, bc = (cmax - r) / safe, (cmax - g) / safe, (cmax - b) / safe
    h = np.where(r == cmax, bc - gc, np.where(g == cmax, 2 + rc - bc, 4 + gc - rc)) / 6
    h = np.where(h < 0, h + 1, h)
    h = np.where(s != 0, h, 0)
    return np.stack([h, s, cmax], axis=-1).astype(np.float32)


def hsv_to_rgb(hsv):
    h, s, v = hsv[..., 0], hsv[..., 1], hsv[..., 2]
    h6 = (h - np.floor(h)) * 6
    i = np.floor(h6)
    f = h6 - i
    p, q, t = v * (1 - s), v * (1 - s * f), v * (1 - s * (1 - f))
    i = i.astype(np.int64) % 6
    r = np.choose(i, [v, q, p, p, t, v])
    g = np.choose(i, [t, v, v, q, p, p])
    b = np.choose(i, [p, p, t, v, v, q])
    out = np.stack([r, g, b], axis=-1)
    return np.where((s == 0)[..., None], v[..., None], out).astype(np.float32)


def rgb_to_hsl(rgb):
    cmax, cmin = rgb.max(axis=-1), rgb.min(axis=-1)
    l_ = (cmax + cmin) / 2
    d = cmax - cmin
    s = np.where(d != 0, d / np.where(d != 0, 1 - np.abs(2 * l_ - 1), 1).clip(1e-8), 0)
    h = rgb_to_hsv(rgb)[..., 0]
    return np.stack([h, s, l_], axis=-1).astype(np.float32)


def hsl_to_rgb(hsl):
    h, s, l_ = hsl[..., 0], hsl[..., 1], hsl[..., 2]
    c = (1 - np.abs(2 * l_ - 1)) * s
    v = l_ + c / 2
    sv = np.where(v > 0, c / np.where(v > 0, v, 1), 0)
    return hsv_to_rgb(np.stack([h, sv, v], axis=-1))


def blend(mode, t, c1, c2):
    """Blender's colour blend of c2 over c1 by factor t."""
    t1 = _c(t)
    if mode == "MIX":
        return c1 + t1 * (c2 - c1)
    if mode == "ADD":
        return c1 + t1 * c2
    if mode == "MULTIPLY":
        return c1 * (1 - t1 + t1 * c2)
    if mode == "SCREEN":
        return 1 - (1 - t1 + t1 * (1 - c2)) * (1 - c1)
    if mode == "OVERLAY":
        return np.where(c1 < 0.5, c1 * (1 - t1 + 2 * t1 * c2), 1 - (1 - t1 + 2 * t1 * (1 - c2)) * (1 - c1))
    if mode == "SUBTRACT":
        return c1 - t1 * c2
    if mode == "DIVIDE":
        return np.where(c2 != 0, (1 - t1) * c1 + t1 * c1 / np.where(c2 != 0, c2, 1), c1)
    if mode == "DIFFERENCE":
        return c1 + t1 * (np.abs(c1 - c2) - c1)
    if mode == "EXCLUSION":
        return np.maximum(c1 + t1 * ((c1 + c2 - 2 * c1 * c2) - c1), 0)
    if mode == "DARKEN":
        return c1 + t1 * (np.minimum(c1, c2) - c1)
    if mode == "LIGHTEN":
        return c1 + t1 * (np.maximum(c1, c2) - c1)
    if mode == "DODGE":
        tmp = 1 - t1 * c2
        q = c1 / np.where(tmp > 0, tmp, 1)
        return np.where(c1 != 0, np.where((tmp <= 0) | (q > 1), 1, q), c1)
    if mode == "BURN":
        tmp = (1 - t1) + t1 * c2
        return np.where(tmp <= 0, 0, np.clip(1 - (1 - c1) / np.where(tmp > 0, tmp, 1), 0, 1))
    if mode == "SOFT_LIGHT":
        scr = 1 - (1 - c2) * (1 - c1)
        return (1 - t1) * c1 + t1 * ((1 - c1) * c2 * c1 + c1 * scr)
    if mode == "LINEAR_LIGHT":
        return c1 + t1 * (2 * c2 - 1)
    if mode in ("HUE", "SATURATION", "VALUE", "COLOR"):
        h1, h2 = rgb_to_hsv(c1), rgb_to_hsv(c2)
        h1, h2 = np.broadcast_arrays(h1, h2)
        h = h1.copy()
        if mode == "HUE":
            h[..., 0] = h2[..., 0]
            return np.where((h2[..., 1] != 0)[..., None], c1 + t1 * (hsv_to_rgb(h) - c1), c1)
        if mode == "COLOR":
            h[..., 0], h[..., 1] = h2[..., 0], h2[..., 1]
            return np.where((h2[..., 1] != 0)[..., None], c1 + t1 * (hsv_to_rgb(h) - c1), c1)
        t = np.broadcast_to(f32(t), h[..., 0].shape)
        if mode == "SATURATION":
            h[..., 1] = h1[..., 1] + t * (h2[..., 1] - h1[..., 1])
            return np.where((h1[..., 1] != 0)[..., None], hsv_to_rgb(h), c1)
        h[..., 2] = h1[..., 2] + t * (h2[..., 2] - h1[..., 2])
        return hsv_to_rgb(h)
    return None


def _blend(sh, mode, t, c1, c2):
    out = blend(mode, t, c1, c2)
    if out is None:
        sh.warn_once(("blend", mode), f"blend mode {mode} is not supported; using Mix")
        out = blend("MIX", t, c1, c2)
    return f32(out)


@node("MIX")
def mix(inp, geom, n, sh):
    kind = inp.prop("data_type", "FLOAT")
    if kind == "VECTOR" and inp.prop("factor_mode", "UNIFORM") == "NON_UNIFORM":
        t = inp.vector("Factor_Vector", (0.5, 0.5, 0.5))
    else:
        t = inp.float("Factor_Float", 0.5)
    if inp.prop("clamp_factor", True):
        t = np.clip(t, 0, 1)
    if kind == "FLOAT":
        a, b = inp.float("A_Float"), inp.float("B_Float")
        return {"Result_Float": f32(a + t * (b - a))}
    if kind == "VECTOR":
        a, b = inp.vector("A_Vector"), inp.vector("B_Vector")
        tv = t if f32(t).ndim == 2 else _c(t)
        return {"Result_Vector": f32(a + tv * (b - a))}
    out = _blend(sh, inp.prop("blend_type", "MIX"), t, inp.color("A_Color", (0.5, 0.5, 0.5)),
                 inp.color("B_Color", (0.5, 0.5, 0.5)))
    if inp.prop("clamp_result", False):
        out = np.clip(out, 0, 1)
    return {"Result_Color": out}


@node("MIX_RGB")
def mix_rgb(inp, geom, n, sh):
    t = np.clip(inp.float("Fac", 0.5), 0, 1)
    out = _blend(sh, inp.prop("blend_type", "MIX"), t, inp.color("Color1", (0.5, 0.5, 0.5)),
                 inp.color("Color2", (0.5, 0.5, 0.5)))
    if inp.prop("use_clamp", False):
        out = np.clip(out, 0, 1)
    return {"Color": out}


@node("INVERT")
def invert(inp, geom, n, sh):
    c, t = inp.color("Color"), _c(inp.float("Fac", 1.0))
    return {"Color": f32(c + t * ((1 - c) - c))}


@node("GAMMA")
def gamma(inp, geom, n, sh):
    c, g = inp.color("Color", (1, 1, 1)), _c(inp.float("Gamma", 1.0))
    return {"Color": f32(np.where(c > 0, np.power(np.maximum(c, 0), g), c))}


@node("HUE_SAT")
def hue_saturation(inp, geom, n, sh):
    c = inp.color("Color", (0.8, 0.8, 0.8))
    hsv = rgb_to_hsv(c).copy()
    hsv, hue, sat, val = np.broadcast_arrays(hsv, _c(inp.float("Hue", 0.5)), _c(inp.float("Saturation", 1.0)),
                                             _c(inp.float("Value", 1.0)))
    hsv = hsv.copy()
    h = hsv[..., 0] + hue[..., 0] + 0.5
    hsv[..., 0] = h - np.floor(h)
    hsv[..., 1] = np.clip(hsv[..., 1] * sat[..., 0], 0, 1)
    hsv[..., 2] = hsv[..., 2] * val[..., 0]
    out = np.maximum(hsv_to_rgb(hsv), 0)
    t = _c(inp.float("Fac", 1.0))
    return {"Color": f32(c + t * (out - c))}


@node("BRIGHTCONTRAST")
def bright_contrast(inp, geom, n, sh):
    c = inp.color("Color", (1, 1, 1))
    bright, contrast = _c(inp.float("Bright")), _c(inp.float("Contrast"))
    return {"Color": f32(np.maximum((1 + contrast) * c + (bright - contrast * 0.5), 0))}


@node("RGBTOBW")
def rgb_to_bw(inp, geom, n, sh):
    return {"Val": f32((inp.color("Color", (0.5, 0.5, 0.5)) * LUMA).sum(axis=-1))}


@node("SEPARATE_COLOR", "SEPRGB", "SEPHSV")
def separate_color(inp, geom, n, sh):
    c = inp.color("Color", (0.8, 0.8, 0.8)) if "Color" in n.inputs or not n.inputs.get("Image") \
        else inp.color("Image")
    mode = inp.prop("mode", "HSV" if n.kind == "SEPHSV" else "RGB")
    v = rgb_to_hsv(c) if mode == "HSV" else rgb_to_hsl(c) if mode == "HSL" else c
    if n.kind == "SEPHSV":
        return {"H": v[..., 0], "S": v[..., 1], "V": v[..., 2]}
    return {"Red": v[..., 0], "Green": v[..., 1], "Blue": v[..., 2],
            "R": v[..., 0], "G": v[..., 1], "B": v[..., 2]}


@node("COMBINE_COLOR", "COMBRGB", "COMBHSV")
def combine_color(inp, geom, n, sh):
    names = ("H", "S", "V") if n.kind == "COMBHSV" else \
        ("R", "G", "B") if n.kind == "COMBRGB" else ("Red", "Green", "Blue")
    a, b, c = np.broadcast_arrays(*(inp.float(k) for k in names))
    v = np.stack([a, b, c], axis=-1).astype(np.float32)
    mode = inp.prop("mode", "HSV" if n.kind == "COMBHSV" else "RGB")
    if mode == "HSV":
        v = hsv_to_rgb(v)
    elif mode == "HSL":
        v = hsl_to_rgb(v)
    return {"Color": vec(v), "Image": vec(v)}


def ramp(props, t):
    """Color Ramp: (colour, alpha) at factors t from the baked stops.

    From the exporter's table of Blender's own evaluation where there is one
    (every interpolation and colour mode); else from the stops: Constant,
    Linear and Ease as Blender does, Cardinal and B-Spline as Linear."""
    r = props.get("ramp") or {}
    table = r.get("table")
    if table is not None and len(table) > 1:
        # Blender's own evaluation of the ramp at K even steps (what Cycles renders from).
        table = np.asarray(table, np.float32).reshape(-1, 4)
        x = np.clip(f32(t), 0, 1) * (len(table) - 1)
        i = np.minimum(np.floor(x).astype(np.int64), len(table) - 2)
        f = (x - i)[..., None]
        out = table[i] * (1 - f) + table[i + 1] * f
        return f32(out[..., :3]), f32(out[..., 3])
    pos = np.asarray(r.get("positions") or [0.0, 1.0], np.float32)
    cols = np.asarray(r.get("colors") or [(0, 0, 0, 1), (1, 1, 1, 1)], np.float32).reshape(-1, 4)
    order = np.argsort(pos, kind="stable")
    pos, cols = pos[order], cols[order]
    t = f32(t)
    mode = r.get("interpolation", "LINEAR")
    if mode == "CONSTANT":
        k = np.clip(np.searchsorted(pos, t, side="right") - 1, 0, len(pos) - 1)
        out = cols[k]
    else:
        k = np.clip(np.searchsorted(pos, t, side="right"), 1, max(len(pos) - 1, 1))
        if len(pos) == 1:
            out = np.broadcast_to(cols[0], t.shape + (4,))
        else:
            p0, p1 = pos[k - 1], pos[k]
            f = np.clip(np.where(p1 > p0, (t - p0) / np.where(p1 > p0, p1 - p0, 1), 0), 0, 1)
            if mode == "EASE":
                f = f * f * (3 - 2 * f)
            out = cols[k - 1] + f[..., None] * (cols[k] - cols[k - 1])
            out = np.where((t <= pos[0])[..., None], cols[0], out)
            out = np.where((t >= pos[-1])[..., None], cols[-1], out)
    return f32(out[..., :3]), f32(out[..., 3])


@node("VALTORGB")
def color_ramp(inp, geom, n, sh):
    c, a = ramp(n.props, inp.float("Fac", 0.5))
    return {"Color": vec(c), "Alpha": a}


def _curve(table, lo, hi, x):
    """A baked curve (K samples over [lo, hi]) at x; beyond the range the end
    values hold (Blender's default extrapolation is constant)."""
    table = np.asarray(table, np.float32)
    if len(table) == 0:
        return x
    grid = np.linspace(lo, hi, len(table), dtype=np.float32)
    return np.interp(x, grid, table).astype(np.float32)


@node("CURVE_RGB")
def rgb_curves(inp, geom, n, sh):
    """Blender applies the combined curve (C) first, then each channel's."""
    c = inp.color("Color", (1, 1, 1))
    curves = n.props.get("curves") or []
    lo, hi = n.props.get("range", (0.0, 1.0))
    if len(curves) < 4:
        return {"Color": c}
    comb, r, g, b = curves[0], curves[1], curves[2], curves[3]     # stored as C, R, G, B
    out = np.stack([_curve(tab, lo, hi, _curve(comb, lo, hi, c[..., i])) for i, tab in enumerate((r, g, b))],
                   axis=-1)
    t = _c(inp.float("Fac", 1.0))
    return {"Color": f32(c + t * (out - c))}


@node("CURVE_VEC")
def vector_curves(inp, geom, n, sh):
    v = inp.vector("Vector")
    curves = n.props.get("curves") or []
    lo, hi = n.props.get("range", (-1.0, 1.0))
    if len(curves) < 3:
        return {"Vector": v}
    out = np.stack([_curve(curves[i], lo, hi, v[..., i]) for i in range(3)], axis=-1)
    t = _c(inp.float("Fac", 1.0))
    return {"Vector": f32(v + t * (out - v))}


@node("CURVE_FLOAT")
def float_curve(inp, geom, n, sh):
    x = inp.float("Value", 1.0)
    curves = n.props.get("curves") or []
    lo, hi = n.props.get("range", (0.0, 1.0))
    if not curves:
        return {"Value": x}
    t = inp.float("Factor", 1.0)
    return {"Value": f32(x + t * (_curve(curves[0], lo, hi, x) - x))}
