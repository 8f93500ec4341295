"""A shader node's settings and socket values as plain data
(restir_addon/export/node_values.py), read through translated materials: node
settings, Color Ramp and curve tables, the Texture Coordinate's object, and
constants converted between socket types as Blender converts them.
"""

from support.node_graph_util import approx, find, graph_of, modules, new_material


def test01_conversions(addon):
    convert = modules(addon)[1].convert
    assert convert((1.0, 0.0, 0.0), "RGBA", "VALUE") == approx(0.2126)          # luminance
    assert convert((0.3, 0.6, 0.9), "VECTOR", "VALUE") == approx(0.6)          # mean
    assert convert(0.25, "VALUE", "RGBA") == (0.25, 0.25, 0.25)
    assert convert((0.1, 0.2, 0.3), "VECTOR", "RGBA") == (0.1, 0.2, 0.3)
    assert convert(2.7, "VALUE", "INT") == 2.0 and convert(-2.7, "VALUE", "INT") == -2.0
    assert convert(0.2, "VALUE", "BOOLEAN") == 1.0 and convert(0.0, "VALUE", "BOOLEAN") == 0.0
    assert convert(0.5, "VALUE", "SHADER") == (0.5, 0.5, 0.5)                  # a colour for an RGB node


def test02_math_and_mix_settings(ng, Link):
    mat, tree, bsdf, _ = new_material("math mix")
    value = tree.nodes.new("ShaderNodeValue")
    value.outputs[0].default_value = 3.0
    math = tree.nodes.new("ShaderNodeMath")
    math.operation, math.use_clamp = "MULTIPLY", True
    math.inputs[0].default_value = 0.5
    mix = tree.nodes.new("ShaderNodeMix")
    mix.data_type, mix.blend_type, mix.clamp_result = "RGBA", "MULTIPLY", True
    mix.inputs["B"].default_value = (0.5, 0.25, 1.0, 1.0)   # by name: the enabled colour socket
    tree.links.new(value.outputs[0], math.inputs[1])
    tree.links.new(math.outputs[0], mix.inputs["A"])
    tree.links.new(mix.outputs["Result"], bsdf.inputs["Base Color"])
    graph = graph_of(ng, mat)
    (v, value_node), (m, math_node), (x, mix_node) = (find(graph, n) for n in ("Value", "Math", "Mix"))
    assert value_node.props == {"value": 3.0}
    assert math_node.props == {"operation": "MULTIPLY", "use_clamp": True}
    assert math_node.inputs["Value"] == approx(0.5) and math_node.inputs["Value_001"] == Link(v, "Value")
    assert {k: mix_node.props[k] for k in ("data_type", "blend_type", "clamp_result", "clamp_factor",
                                           "factor_mode")} == {
        "data_type": "RGBA", "blend_type": "MULTIPLY", "clamp_result": True, "clamp_factor": True,
        "factor_mode": "UNIFORM"}
    assert set(mix_node.inputs) == {"Factor_Float", "A_Color", "B_Color"}     # the enabled ones
    assert mix_node.inputs["A_Color"] == Link(m, "Value", "VALUE", "RGBA")
    assert mix_node.inputs["B_Color"] == approx((0.5, 0.25, 1.0))
    assert graph.nodes[-1].inputs["Base Color"] == Link(x, "Result_Color")


def test03_color_ramp(ng):
    mat, tree, bsdf, _ = new_material("ramp")
    node = tree.nodes.new("ShaderNodeValToRGB")
    ramp = node.color_ramp
    ramp.interpolation = "CONSTANT"
    ramp.elements[0].position, ramp.elements[0].color = 0.2, (1, 0, 0, 1)
    ramp.elements[1].position, ramp.elements[1].color = 0.8, (0, 0, 1, 0.5)
    ramp.elements.new(0.5).color = (0, 1, 0, 1)
    tree.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])
    props = graph_of(ng, mat).nodes[0].props["ramp"]
    assert props["interpolation"] == "CONSTANT" and props["color_mode"] == "RGB"
    assert props["positions"] == approx([0.2, 0.5, 0.8])
    assert props["colors"] == [(1, 0, 0, 1), (0, 1, 0, 1), (0, 0, 1, 0.5)]
    table = props["table"]
    assert len(table) == 256
    assert table[0] == (1, 0, 0, 1) and table[153] == (0, 1, 0, 1) and table[255] == (0, 0, 1, 0.5)


def test04_rgb_and_vector_curves(ng):
    mat, tree, bsdf, _ = new_material("curves")
    node = tree.nodes.new("ShaderNodeRGBCurve")
    combined, red = node.mapping.curves[3], node.mapping.curves[0]
    combined.points[1].location = (1.0, 0.5)
    red.points[0].location, red.points[1].location = (0.0, 1.0), (1.0, 0.0)
    node.mapping.update()
    tree.links.new(node.outputs[0], bsdf.inputs["Base Color"])
    props = graph_of(ng, mat).nodes[0].props
    c, r, g, b = props["curves"]                                        # C first
    assert props["range"] == (0.0, 1.0) and props["extend"] == "EXTRAPOLATED"
    assert (c[0], c[255]) == approx((0.0, 0.5)) and (r[0], r[255]) == approx((1.0, 0.0))
    assert g == approx([i / 255 for i in range(256)]) and b == g

    vector = tree.nodes.new("ShaderNodeVectorCurve")
    tree.links.new(vector.outputs[0], bsdf.inputs["Normal"])
    props = graph_of(ng, mat).nodes[1].props
    assert props["range"] == (-1.0, 1.0) and len(props["curves"]) == 3
    assert props["curves"][0][0] == approx(-1.0) and props["curves"][0][255] == approx(1.0)


def test05_texture_coordinate_object(ng):
    import bpy
    mat, tree, bsdf, _ = new_material("object coords")
    empty = bpy.data.objects.new("Projector", None)
    empty.location = (1.0, 2.0, 3.0)
    bpy.context.scene.collection.objects.link(empty)
    bpy.context.view_layer.update()
    coords = tree.nodes.new("ShaderNodeTexCoord")
    coords.object = empty
    tree.links.new(coords.outputs["Object"], bsdf.inputs["Base Color"])
    graph = graph_of(ng, mat)
    props = graph.nodes[0].props
    assert props["object"] == "Projector" and props["from_instancer"] is False
    inverse = props["object_matrix_inverse"]
    assert [row[3] for row in inverse] == approx([-1.0, -2.0, -3.0, 1.0])
    assert graph.needs == set()                                     # object space needs no mesh data
    tree.links.new(coords.outputs["UV"], bsdf.inputs["Emission Color"])
    assert graph_of(ng, mat).needs == {"uv:"}


def test06_constants_through_a_muted_converter(ng, Link):
    """A muted RGB to BW passes its colour input to its float output: a
    constant turns grey there (its luminance), a linked colour stays a colour."""
    mat, tree, bsdf, _ = new_material("muted converter")
    bw = tree.nodes.new("ShaderNodeRGBToBW")
    bw.inputs["Color"].default_value = (1.0, 0.0, 0.0, 1.0)
    bw.mute = True
    tree.links.new(bw.outputs[0], bsdf.inputs["Base Color"])
    graph = graph_of(ng, mat)
    assert graph.nodes[0].inputs["Base Color"] == approx((0.2126, 0.2126, 0.2126))   # Rec. 709 luminance
    tree.links.new(tree.nodes.new("ShaderNodeRGB").outputs[0], bw.inputs["Color"])
    assert graph_of(ng, mat).nodes[1].inputs["Base Color"] == Link(0, "Color")
