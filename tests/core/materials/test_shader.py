"""Shader graphs (core/shader/, core/materials/shading.py): node evaluators
against plain scalar definitions of Cycles' formulas. Graphs end to end on
hits of a textured quad: test_shader_graphs.py.
"""

import math

import numpy as np
import pytest

from restir_gi.core import Materials
from restir_gi.core.bsdfs import principled
from restir_gi.core.materials.shader import CompiledShader, Link, Node, ShaderGraph, WorldGeometry
from restir_gi.core.materials.shader.nodes_color import blend, hsv_to_rgb, rgb_to_hsv
from restir_gi.core.materials.shader.nodes_math import MATH

ONE = WorldGeometry(np.array([[0.0, 0.0, 1.0]], np.float32))


def run(nodes, output, socket, geom=ONE, warn=None):
    g = ShaderGraph(nodes=nodes, output=None)
    sh = CompiledShader(g, warn=warn)
    return sh.outputs(geom)[output][socket]


# --- 1. node evaluators against scalar definitions --------------------------

def _scalar_math(op, a, b, c):
    """Cycles' svm_math, one value at a time."""
    if op == "DIVIDE":
        return a / b if b != 0 else 0.0
    if op == "POWER":
        if a == 0 and b < 0:
            return 0.0      # infinite: outputs are made finite (zero)
        return a ** b if a >= 0 or float(b).is_integer() else 0.0
    if op == "LOGARITHM":
        return math.log(a) / math.log(b) if a > 0 and b > 0 and b != 1 else 0.0
    if op == "SQRT":
        return math.sqrt(a) if a > 0 else 0.0
    if op == "MODULO":
        return math.fmod(a, b) if b != 0 else 0.0
    if op == "FLOORED_MODULO":
        return a - math.floor(a / b) * b if b != 0 else 0.0
    if op == "WRAP":
        r = b - c
        return a - r * math.floor((a - c) / r) if r != 0 else c
    if op == "PINGPONG":
        return abs(((a - b) / (b * 2) - math.floor((a - b) / (b * 2))) * b * 2 - b) if b != 0 else 0.0
    if op == "SMOOTH_MIN":
        if c == 0:
            return min(a, b)
        h = max(c - abs(a - b), 0) / c
        return min(a, b) - h ** 3 * c / 6
    if op == "COMPARE":
        return float(abs(a - b) <= max(c, 1e-5))
    return None


@pytest.mark.parametrize("op", ["DIVIDE", "POWER", "LOGARITHM", "SQRT", "MODULO", "FLOORED_MODULO",
                                "WRAP", "PINGPONG", "SMOOTH_MIN", "COMPARE"])
def test01_math_matches_scalar_definitions(op, rng):
    vals = np.concatenate([rng.uniform(-3, 3, 200), [0.0, 1.0, -1.0, 2.0, 0.5]]).astype(np.float32)
    a, b, c = vals, np.roll(vals, 1), np.roll(vals, 2)
    b[:5] = 0.0        # division by zero and friends
    with np.errstate(all="ignore"):
        got = np.nan_to_num(MATH[op](a, b, c), nan=0.0, posinf=0.0, neginf=0.0)
    want = np.array([_scalar_math(op, float(x), float(y), float(z)) for x, y, z in zip(a, b, c)])
    assert np.allclose(got, want, rtol=1e-4, atol=1e-4), op


def test01_math_node_clamps_and_never_returns_nan():
    nodes = [Node("MATH", {"Value": -4.0, "Value_001": 0.5}, {"operation": "POWER", "use_clamp": False}),
             Node("MATH", {"Value": 3.0, "Value_001": 0.0}, {"operation": "DIVIDE", "use_clamp": True}),
             Node("MATH", {"Value": 0.7, "Value_001": 0.5}, {"operation": "ADD", "use_clamp": True})]
    assert run(nodes, 0, "Value") == 0.0
    assert run(nodes, 1, "Value") == 0.0
    assert run(nodes, 2, "Value") == 1.0


def _scalar_blend(mode, t, a, b):
    """Cycles' svm/color_util.h for one channel."""
    if mode == "MULTIPLY":
        return a * (1 - t + t * b)
    if mode == "SCREEN":
        return 1 - (1 - t + t * (1 - b)) * (1 - a)
    if mode == "OVERLAY":
        return a * (1 - t + 2 * t * b) if a < 0.5 else 1 - (1 - t + 2 * t * (1 - b)) * (1 - a)
    if mode == "DODGE":
        if a == 0:
            return a
        tmp = 1 - t * b
        return 1.0 if tmp <= 0 or a / tmp > 1 else a / tmp
    if mode == "BURN":
        tmp = (1 - t) + t * b
        return 0.0 if tmp <= 0 else min(max(1 - (1 - a) / tmp, 0), 1)
    if mode == "SOFT_LIGHT":
        scr = 1 - (1 - b) * (1 - a)
        return (1 - t) * a + t * ((1 - a) * b * a + a * scr)
    if mode == "LINEAR_LIGHT":
        return a + t * (2 * b - 1)
    if mode == "DIFFERENCE":
        return (1 - t) * a + t * abs(a - b)
    return None


@pytest.mark.parametrize("mode", ["MULTIPLY", "SCREEN", "OVERLAY", "DODGE", "BURN", "SOFT_LIGHT",
                                  "LINEAR_LIGHT", "DIFFERENCE"])
def test02_blend_modes_match_scalar_definitions(mode, rng):
    a = rng.uniform(0, 1, (100, 3)).astype(np.float32)
    b = rng.uniform(0, 1, (100, 3)).astype(np.float32)
    t = rng.uniform(0, 1, 100).astype(np.float32)
    got = blend(mode, t, a, b)
    want = np.array([[_scalar_blend(mode, float(t[i]), float(a[i, k]), float(b[i, k])) for k in range(3)]
                     for i in range(100)])
    assert np.allclose(got, want, atol=1e-5), mode


def test02_hsv_round_trip(rng):
    c = rng.uniform(0, 2, (500, 3)).astype(np.float32)
    assert np.allclose(hsv_to_rgb(rgb_to_hsv(c)), c, atol=1e-5)
    assert np.allclose(rgb_to_hsv(np.float32([[1, 0, 0], [0, 1, 0], [0, 0, 1]]))[:, 0], [0, 1 / 3, 2 / 3])


def test03_links_convert_as_blender_does():
    """Colour to float by Rec.709 luminance, vector to float by the mean,
    float to colour repeated."""
    nodes = [Node("RGB", props={"color": (1.0, 0.0, 0.0)}),
             Node("MATH", {"Value": Link(0, "Color", "RGBA", "VALUE"), "Value_001": 0.0}, {"operation": "ADD"}),
             Node("COMBXYZ", {"X": 1.0, "Y": 2.0, "Z": 6.0}),
             Node("MATH", {"Value": Link(2, "Vector", "VECTOR", "VALUE"), "Value_001": 0.0}, {"operation": "ADD"}),
             Node("INVERT", {"Fac": 1.0, "Color": Link(1, "Value", "VALUE", "RGBA")})]
    assert np.isclose(run(nodes, 1, "Value"), 0.2126)
    assert np.isclose(run(nodes, 3, "Value"), 3.0)
    assert np.allclose(run(nodes, 4, "Color"), 1 - 0.2126)


def test04_unknown_and_failing_nodes_warn_once_and_give_defaults():
    warnings = []
    nodes = [Node("TEX_MADE_UP", name="Odd"), Node("TEX_MADE_UP", name="Odd2"),
             Node("BSDF_PRINCIPLED", {"Base Color": Link(0, "Color")})]
    g = ShaderGraph(nodes=nodes, output=Link(2, "BSDF"), name="M")
    sh = CompiledShader(g, warn=warnings.append)
    closure = sh.closure(ONE)
    assert len([w for w in warnings if "TEX_MADE_UP" in w]) == 1
    assert np.allclose(closure.get("diffuse", 1), 0.0)     # the unknown colour is black
    # A node whose settings make it fail: a warning, never an exception.
    bad = [Node("VALTORGB", {"Fac": 0.5}, {"ramp": {"positions": "nonsense", "colors": None}})]
    warnings.clear()
    out = CompiledShader(ShaderGraph(nodes=bad), warn=warnings.append).outputs(ONE)
    assert warnings and out[0] == {}


def test05_principled_constant_graph_equals_the_material_table():
    rows = [{"base_color": (0.8, 0.3, 0.1), "metallic": 0.0, "roughness": 0.4, "ior": 1.45, "specular": 0.5},
            {"base_color": (0.9, 0.6, 0.2), "metallic": 1.0, "roughness": 0.2, "ior": 1.5, "specular": 0.5},
            {"base_color": (0.5, 0.5, 0.5), "metallic": 0.3, "roughness": 0.7, "ior": 2.0, "specular": 0.8},
            # Out of range, as Cycles takes it: the metal's f0 clamped to [0, 1], the diffuse only to >= 0.
            {"base_color": (5.0, -1.0, 0.5), "metallic": 1.0, "roughness": 0.3, "ior": 1.5, "specular": 0.5},
            {"base_color": (2.0, -1.0, 0.5), "metallic": 0.0, "roughness": 0.3, "ior": 1.5, "specular": 0.5}]
    table = principled.material_lobes(Materials.from_list(rows))
    assert np.allclose(table.f0[3], (1.0, 0.0, 0.5)) and np.allclose(table.diffuse[4], (2.0, 0.0, 0.5))
    for i, r in enumerate(rows):
        node_ = Node("BSDF_PRINCIPLED", {"Base Color": r["base_color"], "Metallic": r["metallic"],
                                         "Roughness": r["roughness"], "IOR": r["ior"],
                                         "Specular IOR Level": r["specular"]})
        c = CompiledShader(ShaderGraph(nodes=[node_], output=Link(0, "BSDF"))).closure(ONE)
        from restir_gi.core.materials.shading import params_of
        p = params_of(c, 1)
        for name in ("diffuse", "f0", "alpha", "p_spec"):
            assert np.allclose(getattr(p, name)[0], getattr(table, name)[i], atol=1e-6), (i, name)


def test06_mix_and_add_shader_weigh_lobes():
    nodes = [Node("BSDF_DIFFUSE", {"Color": (1.0, 0.0, 0.0)}),
             Node("BSDF_GLOSSY", {"Color": (0.0, 1.0, 0.0), "Roughness": 0.2}),
             Node("MIX_SHADER", {"Fac": 0.25, "Shader": Link(0, "BSDF"), "Shader_001": Link(1, "BSDF")}),
             Node("EMISSION", {"Color": (1.0, 1.0, 1.0), "Strength": 3.0}),
             Node("ADD_SHADER", {"Shader": Link(2, "Shader"), "Shader_001": Link(3, "Emission")})]
    c = CompiledShader(ShaderGraph(nodes=nodes, output=Link(4, "Shader"))).closure(ONE)
    assert np.allclose(c.get("diffuse", 1), [[0.75, 0, 0]])
    assert np.allclose(c.get("specular", 1), [[0, 0.25, 0]])
    assert np.allclose(c.averaged("spec_rough", 1, 0.5), 0.2)
    assert np.allclose(c.get("emission", 1), 3.0)
