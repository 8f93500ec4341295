"""Shader graphs (core/shader/, core/materials/shading.py) end to end:
through ``surface_params`` on hits of a textured quad, where the expected
parameters are known in closed form. Node evaluators: test_shader.py.
"""

import math

import numpy as np
import pytest

from restir_gi.core import Camera, Lights, Materials, make_scene
from restir_gi.core.bsdfs import bsdf
from restir_gi.core.materials.shading import surface_params, triangle_emission
from restir_gi.core.materials.shader import CompiledShader, Link, Node, ShaderGraph, WorldGeometry
from restir_gi.core.geometry.interaction import SurfaceHits

ONE = WorldGeometry(np.array([[0.0, 0.0, 1.0]], np.float32))


# --- 2. graphs on hits of a textured quad -----------------------------------

def _quad_scene(graph, corner_data=None):
    """A unit quad in z = 0 with UV = (x, y); material 1 carries the graph."""
    v = np.float32([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    t = np.int32([[0, 1, 2], [0, 2, 3]])
    uvs = v[t][:, :, :2]
    scene = make_scene(v, t, material_ids=[1, 1], materials=Materials.from_list([{}, {}]),
                       lights=Lights.empty(), camera=Camera(), uvs=uvs)
    scene.shaders = [None, graph]
    scene.corner_data = corner_data or {}
    return scene


def _hits(scene, xy):
    """Hits seen from above at points (x, y) of the quad."""
    xy = np.asarray(xy, np.float32)
    n = len(xy)
    p = np.concatenate([xy, np.zeros((n, 1), np.float32)], axis=1)
    prim = np.where(xy[:, 1] <= xy[:, 0], 0, 1).astype(np.int32)
    up = np.tile(np.float32([0, 0, 1]), (n, 1))
    return SurfaceHits(p=p, ng=up, ns=up.copy(), wo=up, prim=prim,
                       material=np.ones(n, np.int32), front=np.ones(n, bool))


def test07_checker_on_uv_coordinates(rng):
    nodes = [Node("UVMAP", props={"uv_map": ""}),
             Node("TEX_CHECKER", {"Vector": Link(0, "UV"), "Color1": (1.0, 1.0, 1.0), "Color2": (0.0, 0.0, 0.0),
                                  "Scale": 4.0}),
             Node("BSDF_DIFFUSE", {"Color": Link(1, "Color")})]
    scene = _quad_scene(ShaderGraph(nodes=nodes, output=Link(2, "BSDF")))
    xy = rng.uniform(0.01, 0.99, (2000, 2)).astype(np.float32)
    params = surface_params(scene, _hits(scene, xy))
    cell = np.floor(xy * 4 + 1e-6).astype(int)
    # Cycles: Color1 where (xi % 2 == yi % 2) == zi % 2; at z = 0 (zi = 0) that
    # is where the x and y parities differ.
    white = (cell[:, 0] % 2) != (cell[:, 1] % 2)
    assert np.allclose(params.diffuse[white], 1.0)
    assert np.allclose(params.diffuse[~white], 0.0)


def test08_mapping_texture_inverts_point(rng):
    v = rng.uniform(-2, 2, (50, 3)).astype(np.float32)
    loc, rot, scale = (0.3, -1.0, 2.0), (0.4, -0.7, 1.2), (2.0, 0.5, 1.5)
    nodes = [Node("COMBXYZ", {"X": 0.0}),   # placeholder so links have a source
             Node("MAPPING", {"Vector": Link(0, "Vector"), "Location": loc, "Rotation": rot, "Scale": scale},
                  {"vector_type": "POINT"}),
             Node("MAPPING", {"Vector": Link(1, "Vector"), "Location": loc, "Rotation": rot, "Scale": scale},
                  {"vector_type": "TEXTURE"})]
    sh = CompiledShader(ShaderGraph(nodes=nodes))
    values = [{"Vector": v}]
    from restir_gi.core.materials.shader.evaluate import EVALUATORS, Inputs
    values.append(EVALUATORS["MAPPING"](Inputs(values, nodes[1], sh), ONE, nodes[1], sh))
    values.append(EVALUATORS["MAPPING"](Inputs(values, nodes[2], sh), ONE, nodes[2], sh))
    assert np.allclose(values[2]["Vector"], v, atol=1e-4)
    # Rotation about Z by 90 degrees takes +X to +Y (Blender's convention).
    nodes[1] = Node("MAPPING", {"Vector": Link(0, "Vector"), "Rotation": (0, 0, math.pi / 2), "Scale": (1, 1, 1)},
                    {"vector_type": "POINT"})
    values = [{"Vector": np.float32([[1, 0, 0]])}]
    out = EVALUATORS["MAPPING"](Inputs(values, nodes[1], sh), ONE, nodes[1], sh)["Vector"]
    assert np.allclose(out, [[0, 1, 0]], atol=1e-6)


def test09_bump_of_a_linear_height_tilts_the_normal(rng):
    """Height h = k x (Object coordinates) with distance d tilts the normal to
    (-d k, 0, 1) normalised."""
    k, d = 0.5, 0.8
    nodes = [Node("TEX_COORD"),
             Node("SEPXYZ", {"Vector": Link(0, "Object")}),
             Node("MATH", {"Value": Link(1, "X"), "Value_001": k}, {"operation": "MULTIPLY"}),
             Node("BUMP", {"Strength": 1.0, "Distance": d, "Height": Link(2, "Value")}),
             Node("BSDF_DIFFUSE", {"Color": (0.5, 0.5, 0.5), "Normal": Link(3, "Normal")})]
    scene = _quad_scene(ShaderGraph(nodes=nodes, output=Link(4, "BSDF")))
    scene.object_matrices = np.eye(4, dtype=np.float32)[None]
    hits = _hits(scene, rng.uniform(0.2, 0.8, (100, 2)))
    surface_params(scene, hits)
    want = np.float32([-d * k, 0, 1]) / np.linalg.norm([-d * k, 0, 1])
    assert np.allclose(hits.ns, want, atol=2e-3)


def test10_tangent_normal_map(rng):
    """(0.5, 0.5, 1) keeps the normal; a colour along +U tilts it to the
    tangent; strength 0 keeps it. A glossy surface's bent normal is raised
    toward ng until the view mirrors above the surface (Cycles' valid
    reflection); a diffuse one keeps the mapped normal."""
    n = 64
    tangents = np.zeros((2, 3, 4), np.float32)
    tangents[..., 0], tangents[..., 3] = 1.0, 1.0      # tangent +X, sign +1
    out = []
    for color, strength, bsdf_kind in (((0.5, 0.5, 1.0), 1.0, "BSDF_DIFFUSE"),
                                       ((1.0, 0.5, 0.5), 1.0, "BSDF_DIFFUSE"),
                                       ((1.0, 0.5, 0.5), 0.0, "BSDF_DIFFUSE"),
                                       ((1.0, 0.5, 0.5), 1.0, "BSDF_GLOSSY")):
        nodes = [Node("NORMAL_MAP", {"Strength": strength, "Color": color}, {"space": "TANGENT", "uv_map": ""}),
                 Node(bsdf_kind, {"Normal": Link(0, "Normal")})]
        scene = _quad_scene(ShaderGraph(nodes=nodes, output=Link(1, "BSDF")), {"tangent:": tangents})
        hits = _hits(scene, rng.uniform(0.1, 0.9, (n, 2)))
        surface_params(scene, hits)
        out.append(hits.ns)
    assert np.allclose(out[0], [0, 0, 1], atol=1e-5)
    assert np.allclose(out[1], [1, 0, 0], atol=1e-5)
    assert np.allclose(out[2], [0, 0, 1], atol=1e-5)
    assert (out[3][:, 0] > 0.5).all() and (out[3][:, 1] == 0).all()
    mirrored = 2 * out[3][:, 2:3] * out[3] - np.float32([0, 0, 1])
    assert (mirrored[:, 2] >= 0.0099).all()


def test11_textured_emission_per_triangle():
    """A graph emitting u x 4: each triangle emits its centre's value."""
    nodes = [Node("UVMAP"), Node("SEPXYZ", {"Vector": Link(0, "UV")}),
             Node("EMISSION", {"Color": (1.0, 1.0, 1.0), "Strength": Link(1, "X")}),
             Node("MATH", {"Value": 0.0})]
    scene = _quad_scene(ShaderGraph(nodes=nodes, output=Link(2, "Emission")))
    em = triangle_emission(scene)
    assert np.allclose(em[0], 2 / 3) and np.allclose(em[1], 1 / 3)


def test12_non_finite_inputs_give_finite_parameters(rng):
    nodes = [Node("UVMAP"), Node("SEPXYZ", {"Vector": Link(0, "UV")}),
             Node("MATH", {"Value": 1.0, "Value_001": Link(1, "X")}, {"operation": "DIVIDE"}),
             Node("MATH", {"Value": Link(2, "Value"), "Value_001": 1e30}, {"operation": "MULTIPLY"}),
             Node("BSDF_PRINCIPLED", {"Base Color": Link(3, "Value", "VALUE", "RGBA"),
                                      "Roughness": Link(3, "Value")})]
    scene = _quad_scene(ShaderGraph(nodes=nodes, output=Link(4, "BSDF")))
    xy = np.concatenate([[[0.0, 0.0]], rng.uniform(0, 1, (50, 2))]).astype(np.float32)
    params = surface_params(scene, _hits(scene, xy))
    for name in ("diffuse", "f0", "alpha", "p_spec"):
        assert np.isfinite(getattr(params, name)).all()


def test13_three_hits_are_not_a_colour():
    """A batch of exactly three hits keeps per-hit floats apart from constant colours."""
    from restir_gi.core.lights.world import world_environment
    nodes = [Node("TEX_COORD"), Node("SEPXYZ", {"Vector": Link(0, "Generated")}),
             Node("MATH", {"Value": Link(1, "Z"), "Value_001": 0.0}, {"operation": "MAXIMUM"}),
             Node("BACKGROUND", {"Color": Link(2, "Value", "VALUE", "RGBA"), "Strength": 2.0})]
    env = world_environment(ShaderGraph(nodes=nodes, output=Link(3, "Background")))
    got = env.radiance(np.float32([[0, 0, 1], [1, 0, 0], [0, 0, -1]]))
    assert np.allclose(got, [[2, 2, 2], [0, 0, 0], [0, 0, 0]])
    # A constant world graph is a constant Environment; a black one is none.
    const = [Node("BACKGROUND", {"Color": (0.2, 0.4, 0.6), "Strength": 0.5})]
    env = world_environment(ShaderGraph(nodes=const, output=Link(0, "Background")))
    assert env.constant is not None and np.allclose(env.constant, [0.1, 0.2, 0.3])
    const[0].inputs["Strength"] = 0.0
    assert world_environment(ShaderGraph(nodes=const, output=Link(0, "Background"))) is None


def test14_noise_is_gradient_noise(rng):
    """Perlin noise vanishes on the integer lattice, stays within [-1, 1], is
    continuous; normalised fBM lies in [0, 1] (the pattern itself is checked
    against Cycles in tests/oracle/test_nodes_vs_cycles.py)."""
    from restir_gi.core.materials.shader.nodes_noise import fbm, snoise
    lattice = rng.integers(-50, 50, (1000, 3)).astype(np.float32)
    assert np.allclose(snoise(lattice), 0.0, atol=1e-6)
    p = rng.uniform(-20, 20, (20000, 3)).astype(np.float32)
    n = snoise(p)
    assert np.isfinite(n).all() and np.abs(n).max() <= 1.0 and n.std() > 0.1
    step = snoise(p + np.float32(1e-3)) - n
    assert np.abs(step).max() < 0.05
    f = fbm(p, 3.5, 0.5, 2.0)
    assert (f >= 0).all() and (f <= 1).all() and abs(float(f.mean()) - 0.5) < 0.02


def test15_voronoi_cells(rng):
    """F1 distance is the distance to the nearest jittered cell point (checked
    against a brute-force search over 5x5x5 cells); randomness 0 puts the
    points on the lattice."""
    from restir_gi.core.materials.shader.nodes_voronoi import cell_random, voronoi_f1
    p = rng.uniform(-5, 5, (500, 3)).astype(np.float32)
    dist, colour, pos = voronoi_f1(p, 1.0)
    base = np.floor(p).astype(np.int32)
    best = np.full(len(p), np.inf)
    for off in np.stack(np.meshgrid(*[np.arange(-2, 3)] * 3, indexing="ij"), -1).reshape(-1, 3):
        cell = base + off
        point = cell + cell_random(cell)
        best = np.minimum(best, np.linalg.norm(point - p, axis=1))
    np.testing.assert_allclose(dist, best, atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(pos - p, axis=1), dist, atol=1e-5)
    assert (colour >= 0).all() and (colour <= 1).all()
    d0, _, _ = voronoi_f1(p, 0.0)
    np.testing.assert_allclose(d0, np.linalg.norm(p - np.round(p), axis=1), atol=1e-5)


def test16_single_scattering_ggx_is_not_compensated():
    """Cycles' GGX (older files' Glossy and Principled nodes) scatters once:
    no energy put back, unlike Multiscatter GGX; a mixture of both is put
    back in proportion, whether the graph is constant or per hit."""
    from restir_gi.core.materials.shading import params_of
    wo = np.float32([[0.0, 0.0, 1.0]])

    def f0(distribution, kind="BSDF_GLOSSY", mix=None):
        inputs = {"Color": (0.9, 0.9, 0.9), "Base Color": (0.9, 0.9, 0.9), "Metallic": 1.0, "Roughness": 1.0}
        nodes = [Node(kind, inputs, {"distribution": distribution})]
        if mix is not None:
            nodes += [Node(kind, inputs, {"distribution": mix}),
                      Node("MIX_SHADER", {"Fac": 0.5, "Shader": Link(0, "BSDF"), "Shader_001": Link(1, "BSDF")})]
        graph = ShaderGraph(nodes=nodes, output=Link(len(nodes) - 1, "BSDF" if mix is None else "Shader"))
        p = bsdf.at_view(params_of(CompiledShader(graph).closure(ONE), 1), wo)
        per_hit = surface_params(_quad_scene(graph), _hits(_quad_scene(graph), [[0.5, 0.2]]))
        bsdf.at_view(per_hit, wo)
        assert np.allclose(per_hit.f0, p.f0, rtol=1e-5)
        return float(p.f0[0, 0])

    for kind in ("BSDF_GLOSSY", "BSDF_PRINCIPLED"):
        single, multi = f0("GGX", kind), f0("MULTI_GGX", kind)
        assert single == pytest.approx(0.9, rel=1e-5) and multi > 1.5 * single
        assert f0("GGX", kind, mix="MULTI_GGX") == pytest.approx((single + multi) / 2, rel=1e-5)
    assert f0("BECKMANN") == pytest.approx(0.9, rel=1e-5)


def test17_partly_transparent_emitters_emit_all_their_light():
    """A ray stopping at a surface that lets a share t through stands for
    the rays passing it too: it sees the emission divided by 1 - t (Cycles
    adds the whole emission and continues through), constant or per hit.
    Light samples on the surface (the triangle's emission) see it undivided."""
    from restir_gi.core.lights.light_set import LightSet
    from restir_gi.core.materials.shading import surface_emission, transparency
    emit = Node("EMISSION", {"Color": (1.0, 0.5, 0.25), "Strength": 2.0})
    constant = [emit, Node("BSDF_TRANSPARENT"),
                Node("MIX_SHADER", {"Fac": 0.25, "Shader": Link(0, "Emission"), "Shader_001": Link(1, "BSDF")})]
    per_hit = [Node("UVMAP"), Node("SEPXYZ", {"Vector": Link(0, "UV")}), emit, Node("BSDF_TRANSPARENT"),
               Node("MIX_SHADER", {"Fac": Link(1, "X"), "Shader": Link(2, "Emission"),
                                   "Shader_001": Link(3, "BSDF")})]
    xy = np.float32([[0.6, 0.1], [0.9, 0.3], [0.3, 0.8]])
    for nodes in (constant, per_hit):
        scene = _quad_scene(ShaderGraph(nodes=nodes, output=Link(len(nodes) - 1, "Shader")))
        hits = _hits(scene, xy)
        t = transparency(scene, hits)
        assert (t > 0).all() and (t < 1).all()
        lights = LightSet(scene)
        np.testing.assert_allclose(surface_emission(scene, hits, lights), np.tile([2.0, 1.0, 0.5], (3, 1)),
                                   rtol=1e-5)
    # The constant one's triangles, as light samples see them: three quarters.
    np.testing.assert_allclose(triangle_emission(_quad_scene(ShaderGraph(nodes=constant, output=Link(2, "Shader")))),
                               np.tile([1.5, 0.75, 0.375], (2, 1)), rtol=1e-5)


def test18_light_falloff_outside_lights_is_at_distance_one():
    """Light Falloff on a surface (no ray length here): its outputs at
    distance 1, with one warning where the distance would matter; in a
    light's tree (a ray length given) Cycles' law in d."""
    def falloff(output, smooth=0.0, ray_length=None):
        warned = []
        nodes = [Node("LIGHT_FALLOFF", {"Strength": 3.0, "Smooth": smooth}),
                 Node("EMISSION", {"Color": (1.0, 1.0, 1.0), "Strength": Link(0, output)})]
        geom = WorldGeometry(np.float32([[0, 0, 1]] * 3))
        if ray_length is not None:
            geom.ray_length = np.float32(ray_length)
        c = CompiledShader(ShaderGraph(nodes=nodes, output=Link(1, "Emission")), warn=warned.append).closure(geom)
        return c.get("emission", 3)[:, 0], warned

    got, warned = falloff("Quadratic")
    assert np.allclose(got, 3.0) and not warned
    got, warned = falloff("Linear")
    assert np.allclose(got, 3.0) and len(warned) == 1 and "distance 1" in warned[0]
    got, warned = falloff("Constant", smooth=2.0, ray_length=[0.5, 1.0, 4.0])
    d = np.float32([0.5, 1.0, 4.0])
    assert np.allclose(got, 3.0 * d ** 2 * d ** 2 / (2.0 + d ** 2)) and not warned


def test19_sheen_node_per_hit_equals_constant():
    """The Sheen BSDF node (Ashikhmin velvet and Microfiber) in a graph that
    varies over the surface gives, at each hit, the parameters of the same
    graph made constant with that hit's values."""
    from restir_gi.core.materials.shading import params_of
    xy = np.float32([[0.7, 0.2], [0.9, 0.6], [0.2, 0.9]])
    for distribution in ("ASHIKHMIN", "MICROFIBER"):
        def graph(fac):
            nodes = [Node("UVMAP"), Node("SEPXYZ", {"Vector": Link(0, "UV")}),
                     Node("BSDF_SHEEN", {"Color": (0.9, 0.5, 0.3), "Roughness": 0.4},
                          {"distribution": distribution}),
                     Node("BSDF_DIFFUSE", {"Color": (0.2, 0.3, 0.4)}),
                     Node("MIX_SHADER", {"Fac": fac, "Shader": Link(2, "BSDF"), "Shader_001": Link(3, "BSDF")})]
            return ShaderGraph(nodes=nodes, output=Link(4, "Shader"))
        scene = _quad_scene(graph(Link(1, "X")))
        per_hit = surface_params(scene, _hits(scene, xy))
        for i, x in enumerate(xy[:, 0]):
            one = params_of(CompiledShader(graph(float(x))).closure(ONE), 1)
            for name in ("diffuse", "p_spec", "velvet", "velvet_sigma", "sheen", "sheen_rough", "sheen_free"):
                a, b = getattr(per_hit, name), getattr(one, name)
                assert (a is None) == (b is None), (distribution, name)
                if a is not None:
                    np.testing.assert_allclose(a[i], b[0], rtol=1e-5, atol=1e-7, err_msg=(distribution, name))
