"""The node group "glTF Metallic Roughness" of older versions of Blender's
glTF importer, built node for node (legacy_gltf_group), and a material of
it (gltf_material): the gltf_legacy family of node_families.py."""

from support.cornell_box import new_material


def _shader_group(name, inputs=(), outputs=()):
    """A shader node group: its interface ((name, socket type, default) in,
    (name, socket type) out), Group Input and Group Output nodes."""
    import bpy
    group = bpy.data.node_groups.new(name, "ShaderNodeTree")
    for socket_name, socket_type, default in inputs:
        item = group.interface.new_socket(socket_name, in_out="INPUT", socket_type=f"NodeSocket{socket_type}")
        if default is not None:
            item.default_value = default
    for socket_name, socket_type in outputs:
        group.interface.new_socket(socket_name, in_out="OUTPUT", socket_type=f"NodeSocket{socket_type}")
    return group, group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")


def _math(tree, operation, a=None, b=None, clamp=False):
    """A Math node; a and b: output sockets to link, or constants."""
    m = tree.nodes.new("ShaderNodeMath")
    m.operation, m.use_clamp = operation, clamp
    for i, value in enumerate((a, b)):
        if isinstance(value, (int, float)):
            m.inputs[i].default_value = value
        elif value is not None:
            tree.links.new(value, m.inputs[i])
    return m.outputs[0]


def _multiply_colors(tree, a, b, fac=1.0):
    """A Mix node (colour, Multiply) of a and b (output sockets or colours)."""
    mix = tree.nodes.new("ShaderNodeMix")
    mix.data_type, mix.blend_type = "RGBA", "MULTIPLY"
    for name, value in (("A", a), ("B", b), ("Factor", fac)):
        socket = next(s for s in mix.inputs if s.name == name and s.enabled)
        if isinstance(value, (tuple, float, int)):
            socket.default_value = value
        else:
            tree.links.new(value, socket)
    return next(s for s in mix.outputs if s.name == "Result" and s.enabled)


def _sub_group(tree, group, **links):
    """A group node of ``group`` in tree, its inputs linked (output sockets)
    or set (constants) by name."""
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    for name, value in links.items():
        socket = node.inputs[name]
        if isinstance(value, (tuple, float, int)):
            socket.default_value = value
        else:
            tree.links.new(value, socket)
    return node.outputs[0]


def legacy_gltf_group():
    """The node group "glTF Metallic Roughness" older versions of Blender's
    glTF importer made (built here node for node from one of their files):
    nested groups for Fresnel, Lambert, Specular, Occlusion, Emissive and the
    alpha modes, Mix Shaders with Transparent BSDFs, a GGX (single
    scattering) Glossy BSDF, Geometry, RGB to BW, Separate Color, Normal Map
    and Math nodes."""
    import bpy
    existing = bpy.data.node_groups.get("glTF Metallic Roughness")
    if existing is not None:
        return existing
    white, black = (1.0, 1.0, 1.0, 1.0), (0.0, 0.0, 0.0, 1.0)

    fresnel, fi, fo = _shader_group("Fresnel", [("F0", "Float", 0.04)], [("Fresnel", "Float")])
    geo = fresnel.nodes.new("ShaderNodeNewGeometry")
    dot = fresnel.nodes.new("ShaderNodeVectorMath")
    dot.operation = "DOT_PRODUCT"
    fresnel.links.new(geo.outputs["Normal"], dot.inputs[0])
    fresnel.links.new(geo.outputs["Incoming"], dot.inputs[1])
    schlick = _math(fresnel, "MULTIPLY", _math(fresnel, "SUBTRACT", 1.0, fi.outputs["F0"]),
                    _math(fresnel, "POWER", _math(fresnel, "SUBTRACT", 1.0, dot.outputs["Value"]), 5.0))
    fresnel.links.new(_math(fresnel, "ADD", fi.outputs["F0"], schlick), fo.inputs["Fresnel"])

    lambert, li, lo = _shader_group("Lambert", [("Color", "Color", white), ("Normal", "Vector", (0, 1, 0)),
                                                ("Metallic", "Float", 0.0)], [("Shader", "Shader")])
    diffuse = lambert.nodes.new("ShaderNodeBsdfDiffuse")
    lambert.links.new(_multiply_colors(lambert, li.outputs["Color"], white,
                                       _math(lambert, "SUBTRACT", 1.0, li.outputs["Metallic"])),
                      diffuse.inputs["Color"])
    lambert.links.new(li.outputs["Normal"], diffuse.inputs["Normal"])
    lambert.links.new(diffuse.outputs[0], lo.inputs["Shader"])

    specular, si, so = _shader_group("Specular", [("Normal", "Vector", (0, 0, 0)), ("Roughness", "Float", 0.0)],
                                     [("Shader", "Shader")])
    glossy = specular.nodes.new("ShaderNodeBsdfGlossy")
    glossy.distribution = "GGX"
    glossy.inputs["Color"].default_value = white
    specular.links.new(_math(specular, "POWER", _math(specular, "POWER", si.outputs["Roughness"], 2.0, True), 0.5),
                       glossy.inputs["Roughness"])
    specular.links.new(si.outputs["Normal"], glossy.inputs["Normal"])
    specular.links.new(glossy.outputs[0], so.inputs["Shader"])

    occlusion, oi, oo = _shader_group("Occlusion", [("Shader", "Shader", None), ("Normal", "Vector", (0, 1, 0)),
                                                    ("Occlusion", "Float", 1.0), ("Strength", "Float", 0.0)],
                                      [("Shader", "Shader")])
    dark = occlusion.nodes.new("ShaderNodeBsdfDiffuse")
    dark.inputs["Color"].default_value = black
    occlusion.links.new(oi.outputs["Normal"], dark.inputs["Normal"])
    occluded = occlusion.nodes.new("ShaderNodeMixShader")
    occlusion.links.new(oi.outputs["Occlusion"], occluded.inputs["Fac"])
    occlusion.links.new(oi.outputs["Shader"], occluded.inputs[1])
    occlusion.links.new(dark.outputs[0], occluded.inputs[2])
    by_strength = occlusion.nodes.new("ShaderNodeMixShader")
    occlusion.links.new(oi.outputs["Strength"], by_strength.inputs["Fac"])
    occlusion.links.new(occluded.outputs[0], by_strength.inputs[1])
    occlusion.links.new(oi.outputs["Shader"], by_strength.inputs[2])
    occlusion.links.new(by_strength.outputs[0], oo.inputs["Shader"])

    emissive, ei, eo = _shader_group("Emissive", [("Color", "Color", (0.8, 0.8, 0.8, 1.0)),
                                                  ("Factor", "Color", black)], [("Emission", "Shader")])
    emit = emissive.nodes.new("ShaderNodeEmission")
    emissive.links.new(_multiply_colors(emissive, ei.outputs["Color"], ei.outputs["Factor"]), emit.inputs["Color"])
    emissive.links.new(emit.outputs[0], eo.inputs["Emission"])

    blend, bi, bo = _shader_group("AlphaBlend", [("Shader", "Shader", None), ("Alpha", "Float", 1.0)],
                                  [("Shader", "Shader")])
    clear = blend.nodes.new("ShaderNodeBsdfTransparent")
    mix = blend.nodes.new("ShaderNodeMixShader")
    blend.links.new(bi.outputs["Alpha"], mix.inputs["Fac"])
    blend.links.new(clear.outputs[0], mix.inputs[1])
    blend.links.new(bi.outputs["Shader"], mix.inputs[2])
    blend.links.new(mix.outputs[0], bo.inputs["Shader"])

    mask, mi, mo = _shader_group("AlphaMask", [("Shader", "Shader", None), ("Alpha", "Float", 1.0),
                                               ("AlphaCutoff", "Float", 0.5)], [("Shader", "Shader")])
    clear = mask.nodes.new("ShaderNodeBsdfTransparent")
    mix = mask.nodes.new("ShaderNodeMixShader")
    mask.links.new(_math(mask, "LESS_THAN", mi.outputs["Alpha"], mi.outputs["AlphaCutoff"]), mix.inputs["Fac"])
    mask.links.new(mi.outputs["Shader"], mix.inputs[1])
    mask.links.new(clear.outputs[0], mix.inputs[2])
    mask.links.new(mix.outputs[0], mo.inputs["Shader"])

    g, gi, go = _shader_group("glTF Metallic Roughness", [
        ("BaseColor", "Color", white), ("BaseColorFactor", "Color", white), ("MetallicRoughness", "Color", white),
        ("MetallicFactor", "Float", 1.0), ("RoughnessFactor", "Float", 1.0),
        ("Normal", "Color", (0.5, 0.5, 1.0, 1.0)), ("NormalScale", "Float", 1.0),
        ("Occlusion", "Color", white), ("OcclusionStrength", "Float", 1.0),
        ("Emissive", "Color", white), ("EmissiveFactor", "Color", black), ("Alpha", "Float", 1.0),
        ("AlphaCutoff", "Float", 0.5), ("AlphaMode", "Float", 0.0), ("DoubleSided", "Float", 0.0),
        ("Use COLOR_0", "Float", 0.0), ("COLOR_0", "Color", black)], [("Shader", "Shader")])
    i = gi.outputs
    rgb = g.nodes.new("ShaderNodeRGB")
    rgb.outputs[0].default_value = white
    vertex = _multiply_colors(g, rgb.outputs[0], i["COLOR_0"], _math(g, "GREATER_THAN", i["Use COLOR_0"], 0.4, True))
    base = _multiply_colors(g, i["BaseColor"], _multiply_colors(g, i["BaseColorFactor"], vertex))
    mr = g.nodes.new("ShaderNodeSeparateColor")
    g.links.new(i["MetallicRoughness"], mr.inputs[0])
    metallic = _math(g, "MULTIPLY", mr.outputs["Blue"], i["MetallicFactor"], True)
    roughness = _math(g, "MULTIPLY", mr.outputs["Green"], i["RoughnessFactor"], True)
    normal_map = g.nodes.new("ShaderNodeNormalMap")
    g.links.new(i["Normal"], normal_map.inputs["Color"])
    xyz = g.nodes.new("ShaderNodeSeparateXYZ")
    g.links.new(normal_map.outputs[0], xyz.inputs[0])
    combine = g.nodes.new("ShaderNodeCombineXYZ")
    g.links.new(_math(g, "MULTIPLY", xyz.outputs["X"], i["NormalScale"]), combine.inputs["X"])
    g.links.new(_math(g, "MULTIPLY", xyz.outputs["Y"], i["NormalScale"]), combine.inputs["Y"])
    g.links.new(xyz.outputs["Z"], combine.inputs["Z"])
    normalize = g.nodes.new("ShaderNodeVectorMath")
    normalize.operation = "NORMALIZE"
    g.links.new(combine.outputs[0], normalize.inputs[0])
    normal = normalize.outputs["Vector"]
    occlusion_map = g.nodes.new("ShaderNodeSeparateColor")
    g.links.new(i["Occlusion"], occlusion_map.inputs[0])
    diffuse = _sub_group(g, occlusion, Shader=_sub_group(g, lambert, Color=base, Normal=normal, Metallic=metallic),
                         Normal=normal, Occlusion=occlusion_map.outputs["Red"], Strength=i["OcclusionStrength"])
    bw = g.nodes.new("ShaderNodeRGBToBW")
    g.links.new(base, bw.inputs[0])
    metal_fresnel = _sub_group(g, fresnel, F0=bw.outputs[0])
    dielectric_fresnel = _sub_group(g, fresnel, F0=0.04)
    fac = _math(g, "ADD", _math(g, "MULTIPLY", dielectric_fresnel, _math(g, "SUBTRACT", 1.0, metallic)),
                _math(g, "MULTIPLY", metal_fresnel, metallic))
    lobes = g.nodes.new("ShaderNodeMixShader")
    g.links.new(fac, lobes.inputs["Fac"])
    g.links.new(diffuse, lobes.inputs[1])
    g.links.new(_sub_group(g, specular, Normal=normal, Roughness=roughness), lobes.inputs[2])
    add = g.nodes.new("ShaderNodeAddShader")
    g.links.new(lobes.outputs[0], add.inputs[0])
    g.links.new(_sub_group(g, emissive, Color=i["Emissive"], Factor=i["EmissiveFactor"]), add.inputs[1])
    modes = g.nodes.new("ShaderNodeMixShader")
    g.links.new(_math(g, "GREATER_THAN", i["AlphaMode"], 0.5, True), modes.inputs["Fac"])
    g.links.new(_sub_group(g, blend, Shader=add.outputs[0], Alpha=i["Alpha"]), modes.inputs[1])
    g.links.new(_sub_group(g, mask, Shader=add.outputs[0], Alpha=i["Alpha"], AlphaCutoff=i["AlphaCutoff"]),
                modes.inputs[2])
    # Back faces of single-sided materials: a mask group of alpha 0 (nothing linked to its shader).
    sides = g.nodes.new("ShaderNodeMixShader")
    geo = g.nodes.new("ShaderNodeNewGeometry")
    g.links.new(_math(g, "MAXIMUM", _math(g, "GREATER_THAN", i["DoubleSided"], 0.5, True),
                      _math(g, "SUBTRACT", 1.0, geo.outputs["Backfacing"], True), True), sides.inputs["Fac"])
    g.links.new(_sub_group(g, mask, Alpha=0.0, AlphaCutoff=0.5), sides.inputs[1])
    g.links.new(modes.outputs[0], sides.inputs[2])
    g.links.new(sides.outputs[0], go.inputs["Shader"])
    return g


def gltf_material(name, **inputs):
    """A material of legacy_gltf_group, its inputs set by name (BaseColorFactor=...)."""
    mat, tree, out = new_material(name)
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = legacy_gltf_group()
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    tree.links.new(node.outputs[0], out.inputs["Surface"])
    return mat
