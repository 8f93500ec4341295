"""Blender node trees to plain shader graphs (restir_addon/export/node_graph.py):
output choice, groups, reroutes, muted nodes and links, pruning and order,
the per-hit data a graph reads.

Every test builds a material or world with the node_tree API and checks the
graph against the values it was built with; every graph is also checked for
evaluation order (each link points to an earlier node). Node settings and
constant conversions: test_addon_node_values.py.
"""

import os
import tempfile
from types import SimpleNamespace

from support.node_graph_util import (approx, assert_topological, find, graph_of, group_node, kinds, new_group,
                             new_material)


# ---------------------------------------------------------------- single nodes

def test01_principled_constants(ng, Link):
    mat, _, bsdf, _ = new_material("constants")
    bsdf.inputs["Base Color"].default_value = (0.2, 0.3, 0.4, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.25
    graph = graph_of(ng, mat)
    assert kinds(graph) == ["BSDF_PRINCIPLED"]
    assert graph.output == Link(0, "BSDF")
    inputs = graph.nodes[0].inputs
    assert inputs["Base Color"] == approx((0.2, 0.3, 0.4))          # alpha dropped
    assert inputs["Roughness"] == approx(0.25)
    assert inputs["IOR"] == approx(1.5)
    assert "Weight" not in inputs                                     # unavailable in materials
    assert "Normal" not in inputs and "Tangent" not in inputs         # implicit: shading normal
    assert graph.nodes[0].props["distribution"] == "MULTI_GGX"
    assert graph.nodes[0].name == "Principled BSDF"
    assert graph.warnings == [] and graph.needs == set()


def test02_image_texture_links_and_key(ng, Link):
    import bpy
    mat, tree, bsdf, _ = new_material("image")
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = bpy.data.images.new("checker.png", 4, 4)
    tex.interpolation = "Closest"
    tex.extension = "CLIP"
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    tree.links.new(tex.outputs["Alpha"], bsdf.inputs["Alpha"])
    graph = graph_of(ng, mat)
    assert kinds(graph) == ["TEX_IMAGE", "BSDF_PRINCIPLED"]
    assert graph.nodes[1].inputs["Base Color"] == Link(0, "Color")
    assert graph.nodes[1].inputs["Alpha"] == Link(0, "Alpha")
    props = graph.nodes[0].props
    assert (props["image"], props["interpolation"], props["extension"]) == ("checker.png", "Closest", "CLIP")
    assert "Vector" not in graph.nodes[0].inputs and graph.needs == {"uv:"}   # the default UV map

    class Cache:
        frame = 1

        def key(self, image, image_user=None, scene_frame=1):
            return f"key of {image.name}"
    assert graph_of(ng, mat, Cache()).nodes[0].props["image"] == "key of checker.png"

    coords = tree.nodes.new("ShaderNodeTexCoord")
    tree.links.new(coords.outputs["Generated"], tex.inputs["Vector"])
    graph = graph_of(ng, mat)
    assert graph.nodes[1].inputs["Vector"] == Link(0, "Generated")
    assert graph.needs == {"generated"}


def test03_colour_into_float_records_the_conversion(ng, Link):
    mat, tree, bsdf, _ = new_material("colour to float")
    rgb = tree.nodes.new("ShaderNodeRGB")
    rgb.outputs[0].default_value = (0.1, 0.6, 0.3, 1.0)
    tree.links.new(rgb.outputs[0], bsdf.inputs["Metallic"])
    graph = graph_of(ng, mat)
    assert graph.nodes[0].props["color"] == approx((0.1, 0.6, 0.3))
    assert graph.nodes[1].inputs["Metallic"] == Link(0, "Color", "RGBA", "VALUE")


# ---------------------------------------------------------------- groups

def test04_group_used_twice_maps_inputs_and_outputs(ng, Link):
    group, gin, gout = new_group("Tint", [("Fac", "NodeSocketFloat"), ("Col", "NodeSocketColor")],
                                 [("Result", "NodeSocketColor")])
    math = group.nodes.new("ShaderNodeMath")                 # Fac + 1
    math.inputs[1].default_value = 1.0
    mix = group.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    group.links.new(gin.outputs["Fac"], math.inputs[0])
    group.links.new(math.outputs[0], mix.inputs["Factor"])
    group.links.new(gin.outputs["Col"], mix.inputs["A"])
    group.links.new(mix.outputs["Result"], gout.inputs["Result"])

    mat, tree, bsdf, _ = new_material("group twice")
    rgb, value = tree.nodes.new("ShaderNodeRGB"), tree.nodes.new("ShaderNodeValue")
    rgb.name, value.name = "RGB", "Value"
    first, second = group_node(tree, group, "First"), group_node(tree, group, "Second")
    first.inputs["Fac"].default_value = 0.6
    tree.links.new(value.outputs[0], second.inputs["Fac"])
    for node in (first, second):                              # one RGB node read by both
        tree.links.new(rgb.outputs[0], node.inputs["Col"])
    tree.links.new(first.outputs[0], bsdf.inputs["Base Color"])
    tree.links.new(first.outputs[0], bsdf.inputs["Coat Tint"])      # same instance, read twice
    tree.links.new(second.outputs[0], bsdf.inputs["Emission Color"])
    graph = graph_of(ng, mat)

    assert sorted(kinds(graph)) == sorted(["RGB", "VALUE", "MATH", "MIX", "MATH", "MIX", "BSDF_PRINCIPLED"])
    r, _ = find(graph, "RGB")
    v, _ = find(graph, "Value")
    (m1, math1), (x1, mix1) = find(graph, "First > Math"), find(graph, "First > Mix")
    (m2, math2), (x2, mix2) = find(graph, "Second > Math"), find(graph, "Second > Mix")
    assert math1.inputs["Value"] == approx(0.6)                # the group node's own value
    assert math2.inputs["Value"] == Link(v, "Value")           # what feeds the group node
    assert math1.inputs["Value_001"] == approx(1.0)
    assert mix1.inputs["A_Color"] == mix2.inputs["A_Color"] == Link(r, "Color")
    assert mix1.inputs["Factor_Float"] == Link(m1, "Value")
    assert mix2.inputs["Factor_Float"] == Link(m2, "Value")     # each instance its own nodes
    bsdf_inputs = graph.nodes[-1].inputs
    assert bsdf_inputs["Base Color"] == bsdf_inputs["Coat Tint"] == Link(x1, "Result_Color")
    assert bsdf_inputs["Emission Color"] == Link(x2, "Result_Color")


def test05_nested_groups_and_pass_through(ng, Link):
    inner, iin, iout = new_group("Inner", [("C", "NodeSocketColor")], [("C", "NodeSocketColor")])
    inner.links.new(iin.outputs[0], iout.inputs[0])                  # straight through
    outer, oin, oout = new_group("Outer", [("In", "NodeSocketColor")], [("Out", "NodeSocketColor")])
    nested = group_node(outer, inner, "Nested")
    outer.links.new(oin.outputs[0], nested.inputs[0])
    outer.links.new(nested.outputs[0], oout.inputs[0])

    mat, tree, bsdf, _ = new_material("nested")
    rgb, node = tree.nodes.new("ShaderNodeRGB"), group_node(tree, outer, "Outer")
    tree.links.new(node.outputs[0], bsdf.inputs["Base Color"])
    node.inputs[0].default_value = (0.1, 0.2, 0.3, 1.0)
    graph = graph_of(ng, mat)
    assert kinds(graph) == ["BSDF_PRINCIPLED"]
    assert graph.nodes[0].inputs["Base Color"] == approx((0.1, 0.2, 0.3))

    tree.links.new(rgb.outputs[0], node.inputs[0])
    graph = graph_of(ng, mat)
    assert kinds(graph) == ["RGB", "BSDF_PRINCIPLED"]
    assert graph.nodes[1].inputs["Base Color"] == Link(0, "Color")


def test06_values_through_groups_convert_like_blender(ng, Link):
    """A constant is converted at each socket it passes; a linked value keeps
    its source type (one conversion, by the evaluator)."""
    group, gin, gout = new_group("Float", [("V", "NodeSocketFloat")], [("V", "NodeSocketFloat")])
    group.links.new(gin.outputs[0], gout.inputs[0])
    mat, tree, bsdf, _ = new_material("conversions")
    node = group_node(tree, group, "Float")
    node.inputs[0].default_value = 0.5
    tree.links.new(node.outputs[0], bsdf.inputs["Base Color"])
    graph = graph_of(ng, mat)
    assert graph.nodes[0].inputs["Base Color"] == approx((0.5, 0.5, 0.5))

    rgb = tree.nodes.new("ShaderNodeRGB")
    tree.links.new(rgb.outputs[0], node.inputs[0])
    graph = graph_of(ng, mat)
    # Not grey: for linked values Blender 5 skips the float socket in between.
    assert graph.nodes[1].inputs["Base Color"] == Link(0, "Color")


def test07_constant_into_an_implicit_socket_becomes_a_node(ng, Link):
    group, gin, gout = new_group("Coords", [("Vec", "NodeSocketVector")], [("Col", "NodeSocketColor")])
    tex = group.nodes.new("ShaderNodeTexImage")
    group.links.new(gin.outputs[0], tex.inputs["Vector"])
    group.links.new(tex.outputs["Color"], gout.inputs[0])
    mat, tree, bsdf, _ = new_material("implicit")
    node = group_node(tree, group, "Coords")
    node.inputs[0].default_value = (0.5, 0.25, 0.0)
    tree.links.new(node.outputs[0], bsdf.inputs["Base Color"])
    graph = graph_of(ng, mat)
    assert kinds(graph) == ["COMBXYZ", "TEX_IMAGE", "BSDF_PRINCIPLED"]
    assert graph.nodes[0].inputs == approx({"X": 0.5, "Y": 0.25, "Z": 0.0})
    assert graph.nodes[1].inputs["Vector"] == Link(0, "Vector")
    assert "uv:" not in graph.needs                     # fixed coordinates, not the UV map


def test08_group_without_output_is_zero_with_a_warning(ng):
    group, _, gout = new_group("Hollow", [], [("Col", "NodeSocketColor")])
    group.nodes.remove(gout)
    mat, tree, bsdf, _ = new_material("hollow")
    tree.links.new(group_node(tree, group, "Hollow").outputs[0], bsdf.inputs["Base Color"])
    graph = graph_of(ng, mat)
    assert graph.nodes[0].inputs["Base Color"] == (0.0, 0.0, 0.0)      # Blender's fallback
    assert any("Hollow" in w and "Group Output" in w for w in graph.warnings)


def test09_library_linked_group(ng, Link):
    import bpy
    group, gin, gout = new_group("Shared", [("C", "NodeSocketColor")], [("C", "NodeSocketColor")])
    invert = group.nodes.new("ShaderNodeInvert")
    group.links.new(gin.outputs[0], invert.inputs["Color"])
    group.links.new(invert.outputs[0], gout.inputs[0])
    path = os.path.join(tempfile.mkdtemp(), "library.blend")
    bpy.data.libraries.write(path, {group})
    with bpy.data.libraries.load(path, link=True) as (_, into):
        into.node_groups = ["Shared"]
    linked = into.node_groups[0]
    assert linked.library is not None
    mat, tree, bsdf, _ = new_material("linked group")
    tree.links.new(group_node(tree, linked, "Shared").outputs[0], bsdf.inputs["Base Color"])
    graph = graph_of(ng, mat)
    assert kinds(graph) == ["INVERT", "BSDF_PRINCIPLED"]
    assert graph.nodes[1].inputs["Base Color"] == Link(0, "Color")


class _Sockets(list):
    def get(self, identifier):
        return next((s for s in self if s.identifier == identifier), None)


class _Socket:
    """Stands in for a bpy socket: Blender refuses (or crashes on) a group
    that contains itself, so that case is built from stand-ins."""
    enabled, is_unavailable, hide_value = True, False, False

    def __init__(self, node, identifier, socket_type):
        self.node, self.identifier, self.name, self.type = node, identifier, identifier, socket_type

    def as_pointer(self):
        return id(self)


class _Node:
    label, mute, is_active_output, target, internal_links = "", False, True, "ALL", ()

    def __init__(self, tree, kind, name, inputs=(), outputs=(), node_tree=None):
        self.type, self.name, self.node_tree = kind, name, node_tree
        self.inputs = _Sockets(_Socket(self, i, t) for i, t in inputs)
        self.outputs = _Sockets(_Socket(self, i, t) for i, t in outputs)
        tree.nodes.append(self)


class _Tree:
    is_missing = False

    def __init__(self, name):
        self.name, self.nodes, self.links = name, [], []

    def as_pointer(self):
        return id(self)

    def link(self, from_socket, to_socket):
        self.links.append(SimpleNamespace(is_valid=True, is_muted=False, from_socket=from_socket,
                                          to_socket=to_socket))


def test10_group_containing_itself_warns(ng):
    loop = _Tree("Loop")
    again = _Node(loop, "GROUP", "Again", outputs=[("Shader", "SHADER")], node_tree=loop)
    out = _Node(loop, "GROUP_OUTPUT", "Group Output", inputs=[("Shader", "SHADER")])
    loop.link(again.outputs[0], out.inputs[0])
    material = _Tree("Material")
    node = _Node(material, "GROUP", "Loop", outputs=[("Shader", "SHADER")], node_tree=loop)
    output = _Node(material, "OUTPUT_MATERIAL", "Material Output", inputs=[("Surface", "SHADER")])
    material.link(node.outputs[0], output.inputs[0])
    graph = ng.translate(material)
    assert graph.output is None and graph.nodes == []
    assert any("'Loop' contains itself" in w for w in graph.warnings), graph.warnings


# ---------------------------------------------------------------- pass-through and pruning

def test11_reroute_chains(ng, Link):
    mat, tree, bsdf, _ = new_material("reroutes")
    rgb = tree.nodes.new("ShaderNodeRGB")
    source = rgb.outputs[0]
    for _ in range(3):
        reroute = tree.nodes.new("NodeReroute")
        tree.links.new(source, reroute.inputs[0])
        source = reroute.outputs[0]
    tree.links.new(source, bsdf.inputs["Base Color"])
    tree.links.new(source, bsdf.inputs["Roughness"])
    graph = graph_of(ng, mat)
    assert kinds(graph) == ["RGB", "BSDF_PRINCIPLED"]
    assert graph.nodes[1].inputs["Base Color"] == Link(0, "Color")
    assert graph.nodes[1].inputs["Roughness"] == Link(0, "Color", "RGBA", "VALUE")


def test12_muted_nodes_pass_their_first_input(ng, Link):
    mat, tree, bsdf, _ = new_material("muted")
    value, math = tree.nodes.new("ShaderNodeValue"), tree.nodes.new("ShaderNodeMath")
    math.inputs[0].default_value, math.inputs[1].default_value = 0.3, 5.0
    math.mute = True
    tree.links.new(math.outputs[0], bsdf.inputs["Roughness"])
    graph = graph_of(ng, mat)
    assert kinds(graph) == ["BSDF_PRINCIPLED"]
    assert graph.nodes[0].inputs["Roughness"] == approx(0.3)

    tree.links.new(value.outputs[0], math.inputs[0])
    graph = graph_of(ng, mat)
    assert kinds(graph) == ["VALUE", "BSDF_PRINCIPLED"]
    assert graph.nodes[1].inputs["Roughness"] == Link(0, "Value")

    coords = tree.nodes.new("ShaderNodeTexCoord")             # no input to pass: zero
    coords.mute = True
    tree.links.new(coords.outputs["Generated"], bsdf.inputs["Emission Color"])
    assert graph_of(ng, mat).nodes[-1].inputs["Emission Color"] == (0.0, 0.0, 0.0)


def test13_muted_and_invalid_links_count_as_unlinked(ng, Link):
    mat, tree, bsdf, _ = new_material("muted link")
    value = tree.nodes.new("ShaderNodeValue")
    link = tree.links.new(value.outputs[0], bsdf.inputs["Roughness"])
    link.is_muted = True
    a, b = tree.nodes.new("ShaderNodeMath"), tree.nodes.new("ShaderNodeMath")
    a.name, b.name = "A", "B"
    tree.links.new(b.outputs[0], a.inputs[0])
    assert not tree.links.new(a.outputs[0], b.inputs[0]).is_valid      # Blender breaks the loop
    tree.links.new(a.outputs[0], bsdf.inputs["Metallic"])
    graph = graph_of(ng, mat)
    assert kinds(graph) == ["MATH", "MATH", "BSDF_PRINCIPLED"]
    assert graph.nodes[-1].inputs["Roughness"] == approx(0.5)           # the socket's own value
    assert find(graph, "A")[1].inputs["Value"] == Link(find(graph, "B")[0], "Value")
    assert find(graph, "B")[1].inputs["Value"] == approx(0.5)


def test14_only_used_nodes_in_dependency_order(ng, Link):
    mat, tree, bsdf, _ = new_material("pruned")
    tree.nodes.new("ShaderNodeTexNoise")
    tree.nodes.new("ShaderNodeBsdfDiffuse")
    chain = [tree.nodes.new("ShaderNodeMath") for _ in range(5)]
    for i, node in enumerate(chain):
        node.name = f"M{i}"
    for earlier, later in zip(chain, chain[1:]):
        tree.links.new(earlier.outputs[0], later.inputs[1])
    tree.links.new(chain[2].outputs[0], chain[4].inputs[0])           # a diamond
    tree.links.new(chain[-1].outputs[0], bsdf.inputs["Roughness"])
    graph = graph_of(ng, mat)
    assert [n.name for n in graph.nodes] == ["M0", "M1", "M2", "M3", "M4", "Principled BSDF"]
    assert graph.nodes[4].inputs["Value"] == Link(2, "Value")
    assert graph.needs == set()


# ---------------------------------------------------------------- per-hit data

def test15_needs(ng):
    mat, tree, bsdf, _ = new_material("needs")
    uv, nmap = tree.nodes.new("ShaderNodeUVMap"), tree.nodes.new("ShaderNodeNormalMap")
    uv.uv_map, nmap.uv_map = "Second", "Detail"
    colour, attribute = tree.nodes.new("ShaderNodeVertexColor"), tree.nodes.new("ShaderNodeAttribute")
    colour.layer_name, attribute.attribute_name = "Paint", "Dirt"
    checker = tree.nodes.new("ShaderNodeTexChecker")
    tree.links.new(uv.outputs[0], bsdf.inputs["Tangent"])
    tree.links.new(nmap.outputs[0], bsdf.inputs["Normal"])
    tree.links.new(colour.outputs[0], bsdf.inputs["Base Color"])
    tree.links.new(attribute.outputs["Fac"], bsdf.inputs["Roughness"])
    tree.links.new(checker.outputs["Fac"], bsdf.inputs["Metallic"])
    graph = graph_of(ng, mat)
    assert graph.needs == {"uv:Second", "uv:Detail", "tangent:Detail", "color:Paint", "color:Dirt",
                           "generated"}


# ---------------------------------------------------------------- outputs and worlds

def test16_world_environment(ng, Link):
    import bpy
    world = bpy.data.worlds.new("sky")
    tree = world.node_tree
    background = tree.nodes["Background"]
    background.inputs["Strength"].default_value = 2.0
    env, mapping = tree.nodes.new("ShaderNodeTexEnvironment"), tree.nodes.new("ShaderNodeMapping")
    env.image = bpy.data.images.new("sky.hdr", 8, 4, float_buffer=True)
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, 1.0)
    coords = tree.nodes.new("ShaderNodeTexCoord")
    tree.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs[0], env.inputs["Vector"])
    tree.links.new(env.outputs["Color"], background.inputs["Color"])
    graph = ng.world_graph(world)
    assert_topological(graph)
    assert kinds(graph) == ["TEX_COORD", "MAPPING", "TEX_ENVIRONMENT", "BACKGROUND"]
    assert graph.output == Link(3, "Background") and graph.name == "sky"
    assert graph.nodes[1].props["vector_type"] == "POINT"
    assert graph.nodes[1].inputs["Rotation"] == approx((0.0, 0.0, 1.0))
    assert graph.nodes[1].inputs["Vector"] == Link(0, "Generated")
    assert (graph.nodes[2].props["image"], graph.nodes[2].props["projection"]) == ("sky.hdr", "EQUIRECTANGULAR")
    assert graph.nodes[3].inputs == {"Color": Link(2, "Color"), "Strength": approx(2.0)}
    assert graph.needs == {"generated"}
    assert ng.world_graph(None).output is None


def test17_no_output_node_or_nothing_linked(ng):
    mat, tree, bsdf, output = new_material("no output")
    tree.links.remove(output.inputs["Surface"].links[0])
    graph = graph_of(ng, mat)
    assert graph.output is None and graph.nodes == [] and graph.warnings == []
    tree.nodes.remove(output)
    graph = graph_of(ng, mat)
    assert graph.output is None and graph.nodes == []
    assert graph.warnings == ["no output node"]


def test18_output_choice_follows_cycles(ng, Link):
    mat, tree, bsdf, output = new_material("outputs")
    emission = tree.nodes.new("ShaderNodeEmission")
    eevee = tree.nodes.new("ShaderNodeOutputMaterial")
    eevee.target = "EEVEE"
    tree.links.new(emission.outputs[0], eevee.inputs["Surface"])
    tree.nodes.active = eevee
    eevee.is_active_output = True
    assert kinds(graph_of(ng, mat)) == ["BSDF_PRINCIPLED"]              # EEVEE's output is not Cycles'

    cycles = tree.nodes.new("ShaderNodeOutputMaterial")
    cycles.target = "CYCLES"
    tree.links.new(emission.outputs[0], cycles.inputs["Surface"])
    output.is_active_output = True
    assert kinds(graph_of(ng, mat)) == ["EMISSION"]                     # Cycles' own beats All

    for node in (output, cycles):
        tree.nodes.remove(node)
    graph = graph_of(ng, mat)
    assert graph.output is None and graph.warnings == ["only outputs for other render engines"]
