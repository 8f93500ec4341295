"""Scenes for each family of shader nodes, built by script on the example
Cornell box: what tests/oracle/test_nodes_vs_cycles.py renders with both engines and
bench/contact_sheet.py lays out side by side.

Each builder takes the opened Cornell box scene and changes its materials (or
world) so one family of nodes decides most of the image.
"""

import math
import os
import tempfile

import numpy as np


def _tree(mat):
    tree = mat.node_tree
    for n in list(tree.nodes):
        if n.type != "OUTPUT_MATERIAL":
            tree.nodes.remove(n)
    out = next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")
    return tree, out


def _new_material(name):
    import bpy
    mat = bpy.data.materials.new(name)
    return mat, *_tree(mat)


def _assign(obj_names, mat):
    import bpy
    for name in obj_names:
        ob = bpy.data.objects[name]
        ob.data.materials.clear()
        ob.data.materials.append(mat)
        if not ob.data.uv_layers:
            ob.data.uv_layers.new(name="UVMap")


def _png(name, size=32):
    """A colourful 8-bit sRGB PNG written to a temporary folder and loaded
    from there as a file image."""
    import bpy
    y, x = np.mgrid[0:size, 0:size] / size
    rgba = np.ones((size, size, 4), np.float32)
    rgba[..., 0] = 0.15 + 0.8 * (((x * 4).astype(int) + (y * 4).astype(int)) % 2)
    rgba[..., 1] = 0.2 + 0.7 * y
    rgba[..., 2] = 0.9 - 0.7 * x
    img = bpy.data.images.new(name, size, size)
    img.pixels.foreach_set(rgba.ravel())
    path = os.path.join(tempfile.mkdtemp(prefix="restir-tex-"), f"{name}.png")
    img.filepath_raw = path
    img.file_format = "PNG"
    img.save()
    bpy.data.images.remove(img)
    return bpy.data.images.load(path)


def image(scene):
    """Image Texture (UV, Linear and Closest) into Diffuse and Principled."""
    mat, tree, out = _new_material("Textured")
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = _png("pattern")
    bsdf = tree.nodes.new("ShaderNodeBsdfDiffuse")
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Color"])
    tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    _assign(["BackWall", "Floor"], mat)
    mat2, tree2, out2 = _new_material("TexturedBoxes")
    tex2 = tree2.nodes.new("ShaderNodeTexImage")
    tex2.image = tex.image
    tex2.interpolation = "Closest"
    mapping = tree2.nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (2.0, 2.0, 1.0)
    coords = tree2.nodes.new("ShaderNodeTexCoord")
    tree2.links.new(coords.outputs["UV"], mapping.inputs["Vector"])
    tree2.links.new(mapping.outputs["Vector"], tex2.inputs["Vector"])
    p = tree2.nodes.new("ShaderNodeBsdfPrincipled")
    p.inputs["Roughness"].default_value = 0.6
    tree2.links.new(tex2.outputs["Color"], p.inputs["Base Color"])
    tree2.links.new(p.outputs[0], out2.inputs["Surface"])
    _assign(["TallBox", "ShortBox"], mat2)


def noise(scene):
    """Noise Texture (fBM, distortion) through a Color Ramp, and its Color;
    Voronoi's cell colour and distance on the side walls."""
    mat, tree, out = _new_material("Noisy")
    tex = tree.nodes.new("ShaderNodeTexNoise")
    tex.inputs["Scale"].default_value = 4.0
    tex.inputs["Detail"].default_value = 3.5
    tex.inputs["Distortion"].default_value = 0.3
    ramp = tree.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].position = 0.4
    ramp.color_ramp.elements[1].position = 0.6
    tree.links.new(tex.outputs["Fac"], ramp.inputs["Fac"])
    d = tree.nodes.new("ShaderNodeBsdfDiffuse")
    tree.links.new(ramp.outputs["Color"], d.inputs["Color"])
    tree.links.new(d.outputs[0], out.inputs["Surface"])
    _assign(["BackWall", "Floor"], mat)
    mat2, tree2, out2 = _new_material("NoisyColor")
    tex2 = tree2.nodes.new("ShaderNodeTexNoise")
    d2 = tree2.nodes.new("ShaderNodeBsdfDiffuse")
    tree2.links.new(tex2.outputs["Color"], d2.inputs["Color"])
    tree2.links.new(d2.outputs[0], out2.inputs["Surface"])
    _assign(["TallBox", "ShortBox"], mat2)
    mat3, tree3, out3 = _new_material("Cells")
    vor = tree3.nodes.new("ShaderNodeTexVoronoi")
    vor.inputs["Scale"].default_value = 3.0
    d3 = tree3.nodes.new("ShaderNodeBsdfDiffuse")
    tree3.links.new(vor.outputs["Color"], d3.inputs["Color"])
    tree3.links.new(d3.outputs[0], out3.inputs["Surface"])
    _assign(["LeftWall"], mat3)
    mat4, tree4, out4 = _new_material("CellDistance")
    vor4 = tree4.nodes.new("ShaderNodeTexVoronoi")
    vor4.inputs["Scale"].default_value = 6.0
    d4 = tree4.nodes.new("ShaderNodeBsdfDiffuse")
    tree4.links.new(vor4.outputs["Distance"], d4.inputs["Color"])
    tree4.links.new(d4.outputs[0], out4.inputs["Surface"])
    _assign(["RightWall"], mat4)


def procedural(scene):
    """Checker, Gradient, Color Ramp, Math, Mix (multiply), Map Range, Hue/Saturation."""
    mat, tree, out = _new_material("Procedural")
    coords = tree.nodes.new("ShaderNodeTexCoord")
    checker = tree.nodes.new("ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 3.0
    tree.links.new(coords.outputs["Generated"], checker.inputs["Vector"])
    ramp = tree.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.9, 0.3, 0.1, 1)
    ramp.color_ramp.elements[1].color = (0.1, 0.4, 0.8, 1)
    tree.links.new(checker.outputs["Fac"], ramp.inputs["Fac"])
    gradient = tree.nodes.new("ShaderNodeTexGradient")
    tree.links.new(coords.outputs["Object"], gradient.inputs["Vector"])
    mix = tree.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.blend_type = "MULTIPLY"
    mix.inputs["Factor"].default_value = 0.7
    tree.links.new(ramp.outputs["Color"], mix.inputs["A"])
    tree.links.new(gradient.outputs["Color"], mix.inputs["B"])
    hsv = tree.nodes.new("ShaderNodeHueSaturation")
    hsv.inputs["Hue"].default_value = 0.6
    tree.links.new(mix.outputs["Result"], hsv.inputs["Color"])
    maprange = tree.nodes.new("ShaderNodeMapRange")
    maprange.inputs["To Min"].default_value = 0.3
    maprange.inputs["To Max"].default_value = 0.8
    tree.links.new(gradient.outputs["Fac"], maprange.inputs["Value"])
    p = tree.nodes.new("ShaderNodeBsdfPrincipled")
    tree.links.new(hsv.outputs["Color"], p.inputs["Base Color"])
    tree.links.new(maprange.outputs["Result"], p.inputs["Roughness"])
    tree.links.new(p.outputs[0], out.inputs["Surface"])
    _assign(["BackWall", "Floor", "TallBox", "ShortBox"], mat)


def brick(scene):
    """Brick Texture (offset rows, squashed rows, smooth mortar, bias) as
    colour, and its Fac as roughness."""
    mat, tree, out = _new_material("Bricks")
    coords = tree.nodes.new("ShaderNodeTexCoord")
    b = tree.nodes.new("ShaderNodeTexBrick")
    b.offset, b.offset_frequency, b.squash, b.squash_frequency = 0.3, 3, 1.6, 2
    for name, value in (("Scale", 4.0), ("Mortar Size", 0.04), ("Mortar Smooth", 0.3), ("Bias", 0.2),
                        ("Brick Width", 0.6), ("Row Height", 0.3)):
        b.inputs[name].default_value = value
    b.inputs["Color1"].default_value = (0.7, 0.25, 0.1, 1)
    b.inputs["Color2"].default_value = (0.3, 0.6, 0.8, 1)
    b.inputs["Mortar"].default_value = (0.9, 0.9, 0.85, 1)
    tree.links.new(coords.outputs["Generated"], b.inputs["Vector"])
    p = tree.nodes.new("ShaderNodeBsdfPrincipled")
    tree.links.new(b.outputs["Color"], p.inputs["Base Color"])
    tree.links.new(b.outputs["Fac"], p.inputs["Roughness"])
    tree.links.new(p.outputs[0], out.inputs["Surface"])
    _assign(["BackWall", "Floor", "TallBox"], mat)


def shaders(scene):
    """Mix Shader by Layer Weight, Add Shader, Glossy, Emission."""
    mat, tree, out = _new_material("Mixed")
    d = tree.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (0.8, 0.5, 0.2, 1)
    g = tree.nodes.new("ShaderNodeBsdfGlossy")
    g.inputs["Roughness"].default_value = 0.35
    g.inputs["Color"].default_value = (0.7, 0.7, 0.9, 1)
    lw = tree.nodes.new("ShaderNodeLayerWeight")
    lw.inputs["Blend"].default_value = 0.4
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(lw.outputs["Facing"], mix.inputs["Fac"])
    tree.links.new(d.outputs[0], mix.inputs[1])
    tree.links.new(g.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], out.inputs["Surface"])
    _assign(["TallBox", "ShortBox"], mat)
    mat2, tree2, out2 = _new_material("Added")
    d2 = tree2.nodes.new("ShaderNodeBsdfDiffuse")
    d2.inputs["Color"].default_value = (0.5, 0.5, 0.5, 1)
    e2 = tree2.nodes.new("ShaderNodeEmission")
    e2.inputs["Strength"].default_value = 0.3
    e2.inputs["Color"].default_value = (0.2, 0.4, 1.0, 1)
    add = tree2.nodes.new("ShaderNodeAddShader")
    tree2.links.new(d2.outputs[0], add.inputs[0])
    tree2.links.new(e2.outputs[0], add.inputs[1])
    tree2.links.new(add.outputs[0], out2.inputs["Surface"])
    _assign(["BackWall"], mat2)


def normals(scene):
    """Bump from a smooth height, and a tangent-space Normal Map of a constant colour."""
    mat, tree, out = _new_material("Bumped")
    coords = tree.nodes.new("ShaderNodeTexCoord")
    sep = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(coords.outputs["Object"], sep.inputs["Vector"])
    mul = tree.nodes.new("ShaderNodeMath")
    mul.operation = "MULTIPLY"
    mul.inputs[1].default_value = 6.0
    tree.links.new(sep.outputs["X"], mul.inputs[0])
    sine = tree.nodes.new("ShaderNodeMath")
    sine.operation = "SINE"
    tree.links.new(mul.outputs[0], sine.inputs[0])
    bump = tree.nodes.new("ShaderNodeBump")
    bump.inputs["Distance"].default_value = 0.1
    tree.links.new(sine.outputs[0], bump.inputs["Height"])
    d = tree.nodes.new("ShaderNodeBsdfDiffuse")
    tree.links.new(bump.outputs[0], d.inputs["Normal"])
    tree.links.new(d.outputs[0], out.inputs["Surface"])
    _assign(["BackWall"], mat)
    mat2, tree2, out2 = _new_material("NormalMapped")
    nm = tree2.nodes.new("ShaderNodeNormalMap")
    nm.inputs["Color"].default_value = (0.75, 0.5, 0.85, 1)
    d2 = tree2.nodes.new("ShaderNodeBsdfDiffuse")
    tree2.links.new(nm.outputs[0], d2.inputs["Normal"])
    tree2.links.new(d2.outputs[0], out2.inputs["Surface"])
    _assign(["Floor"], mat2)


def attributes(scene):
    """Color Attribute on the boxes' corners, Object Info's Random through a ramp."""
    import bpy
    mat, tree, out = _new_material("VertexColored")
    attr = tree.nodes.new("ShaderNodeVertexColor")
    attr.layer_name = "Col"
    d = tree.nodes.new("ShaderNodeBsdfDiffuse")
    tree.links.new(attr.outputs["Color"], d.inputs["Color"])
    tree.links.new(d.outputs[0], out.inputs["Surface"])
    rng = np.random.default_rng(7)
    for name in ("TallBox", "ShortBox"):
        me = bpy.data.objects[name].data
        col = me.color_attributes.new("Col", "FLOAT_COLOR", "CORNER")
        values = np.ones((len(col.data), 4), np.float32)
        values[:, :3] = rng.uniform(0.05, 0.9, (len(col.data), 3))
        col.data.foreach_set("color", values.ravel())
    _assign(["TallBox", "ShortBox"], mat)
    mat2, tree2, out2 = _new_material("ByObject")
    info = tree2.nodes.new("ShaderNodeObjectInfo")
    ramp = tree2.nodes.new("ShaderNodeValToRGB")
    tree2.links.new(info.outputs["Color"], ramp.inputs["Fac"])
    d2 = tree2.nodes.new("ShaderNodeBsdfDiffuse")
    tree2.links.new(ramp.outputs["Color"], d2.inputs["Color"])
    tree2.links.new(d2.outputs[0], out2.inputs["Surface"])
    for name, c in (("BackWall", (0.8, 0.8, 0.8, 1)), ("Floor", (0.4, 0.4, 0.4, 1))):
        bpy.data.objects[name].color = c
    _assign(["BackWall", "Floor"], mat2)


def emission(scene):
    """Emission coloured by Blackbody, the ceiling light of the box."""
    mat, tree, out = _new_material("Blackbody")
    bb = tree.nodes.new("ShaderNodeBlackbody")
    bb.inputs["Temperature"].default_value = 4000.0
    e = tree.nodes.new("ShaderNodeEmission")
    e.inputs["Strength"].default_value = 15.0
    tree.links.new(bb.outputs[0], e.inputs["Color"])
    tree.links.new(e.outputs[0], out.inputs["Surface"])
    _assign(["CeilingLight"], mat)


def glass(scene):
    """Glass BSDF (rough) and Principled transmission, seen against the walls."""
    mat, tree, out = _new_material("Glass")
    g = tree.nodes.new("ShaderNodeBsdfGlass")
    g.inputs["Roughness"].default_value = 0.15
    g.inputs["IOR"].default_value = 1.45
    g.inputs["Color"].default_value = (0.9, 0.95, 1.0, 1)
    tree.links.new(g.outputs[0], out.inputs["Surface"])
    _assign(["TallBox"], mat)
    mat2, tree2, out2 = _new_material("Transmissive")
    p = tree2.nodes.new("ShaderNodeBsdfPrincipled")
    p.inputs["Base Color"].default_value = (0.9, 0.6, 0.3, 1)
    p.inputs["Transmission Weight"].default_value = 1.0
    p.inputs["Roughness"].default_value = 0.3
    tree2.links.new(p.outputs[0], out2.inputs["Surface"])
    _assign(["ShortBox"], mat2)
    import bpy
    for name in ("TallBox", "ShortBox"):     # off the floor: no faces shared with it
        bpy.data.objects[name].location.z += 0.002


def alpha(scene):
    """An alpha-clipped card (checker holes through Principled Alpha) casting a
    patterned shadow, and a box half transparent through a Mix with Transparent."""
    import bpy
    mat, tree, out = _new_material("Cutout")
    coords = tree.nodes.new("ShaderNodeTexCoord")
    checker = tree.nodes.new("ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 4.0
    tree.links.new(coords.outputs["UV"], checker.inputs["Vector"])
    p = tree.nodes.new("ShaderNodeBsdfPrincipled")
    p.inputs["Base Color"].default_value = (0.2, 0.7, 0.2, 1)
    tree.links.new(checker.outputs["Fac"], p.inputs["Alpha"])
    tree.links.new(p.outputs[0], out.inputs["Surface"])
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(0.3, -0.3, 1.3), rotation=(0.3, 0.0, 0.4))
    card = bpy.context.object
    card.data.materials.append(mat)
    mat2, tree2, out2 = _new_material("HalfTransparent")
    d = tree2.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (0.8, 0.3, 0.3, 1)
    t = tree2.nodes.new("ShaderNodeBsdfTransparent")
    mix = tree2.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.5
    tree2.links.new(d.outputs[0], mix.inputs[1])
    tree2.links.new(t.outputs[0], mix.inputs[2])
    tree2.links.new(mix.outputs[0], out2.inputs["Surface"])
    _assign(["TallBox"], mat2)
    bpy.data.objects["TallBox"].location.z += 0.002    # no face shared with the floor


def hdri(scene, name="sunset.exr"):
    """An HDRI world (Environment Texture through Mapping), the box opened to it."""
    import bpy
    for obj in ("Ceiling", "CeilingLight", "LeftWall"):
        bpy.data.objects.remove(bpy.data.objects[obj])
    world = bpy.data.worlds.new("HDRI")
    scene.world = world
    tree = world.node_tree
    bg = next(n for n in tree.nodes if n.type == "BACKGROUND")
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
    env.image = bpy.data.images.load(os.path.join(folder, name))
    mapping = tree.nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(60))
    coords = tree.nodes.new("ShaderNodeTexCoord")
    tree.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    tree.links.new(env.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = 1.5


def _spheres(specs):
    """Smooth UV spheres in place of the two boxes: (radius, (x, y), material)."""
    import bpy
    for name in ("TallBox", "ShortBox"):
        bpy.data.objects.remove(bpy.data.objects[name])
    for radius, (x, y), mat in specs:
        bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=radius,
                                             location=(x, y, radius + 0.002))
        ob = bpy.context.object
        ob.data.shade_smooth()
        ob.data.materials.append(mat)


def _principled(name, **inputs):
    mat, tree, out = _new_material(name)
    p = tree.nodes.new("ShaderNodeBsdfPrincipled")
    for key, value in inputs.items():
        p.inputs[key].default_value = value
    tree.links.new(p.outputs[0], out.inputs["Surface"])
    return mat


def sheen(scene):
    """Principled sheen (weight 1) on dark bases: two spheres of different
    Sheen Roughness and Tint, and a sheen on the grey floor, seen at grazing."""
    _spheres([(0.45, (-0.4, 0.25), _principled("Velvet", **{
                  "Base Color": (0.05, 0.05, 0.05, 1), "Sheen Weight": 1.0, "Sheen Roughness": 0.5})),
              (0.35, (0.45, -0.3), _principled("Satin", **{
                  "Base Color": (0.12, 0.02, 0.02, 1), "Roughness": 0.4, "Sheen Weight": 1.0,
                  "Sheen Roughness": 0.2, "Sheen Tint": (1.0, 0.8, 0.6, 1)}))])
    _assign(["Floor"], _principled("SheenFloor", **{
        "Base Color": (0.3, 0.3, 0.3, 1), "Sheen Weight": 1.0, "Sheen Roughness": 0.8,
        "Sheen Tint": (0.6, 0.7, 1.0, 1)}))


def _sheen_node(name, distribution, color, roughness, under=None, mix=None):
    """A Sheen BSDF node of its own; under: the colour of a Diffuse BSDF it
    is added to; mix: the factor of a Mix Shader of that Diffuse and it."""
    mat, tree, out = _new_material(name)
    node = tree.nodes.new("ShaderNodeBsdfSheen")
    node.distribution = distribution
    node.inputs["Color"].default_value = (*color, 1.0)
    node.inputs["Roughness"].default_value = roughness
    shader = node.outputs[0]
    if under is not None:
        diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Color"].default_value = (*under, 1.0)
        both = tree.nodes.new("ShaderNodeAddShader" if mix is None else "ShaderNodeMixShader")
        first = 0 if mix is None else 1
        if mix is not None:
            both.inputs["Fac"].default_value = mix
        tree.links.new(diffuse.outputs[0], both.inputs[first])
        tree.links.new(shader, both.inputs[first + 1])
        shader = both.outputs[0]
    tree.links.new(shader, out.inputs["Surface"])
    return mat


def sheen_node(scene):
    """The Sheen BSDF node (Velvet before 4.0): Microfiber added to a dark
    diffuse (which it does not dim, unlike the Principled sheen), Ashikhmin
    (Cycles' velvet) on its own, and a Microfiber mixed with grey on the
    floor, seen at grazing."""
    _spheres([(0.45, (-0.4, 0.25), _sheen_node("Microfiber", "MICROFIBER", (0.9, 0.35, 0.5), 0.4,
                                               under=(0.05, 0.05, 0.08))),
              (0.35, (0.45, -0.3), _sheen_node("Velvet", "ASHIKHMIN", (0.5, 0.7, 1.0), 0.35))])
    _assign(["Floor"], _sheen_node("SheenFloor", "MICROFIBER", (0.8, 0.9, 0.6), 0.7, under=(0.4, 0.4, 0.4),
                                   mix=0.5))
    _assign(["BackWall"], _sheen_node("VelvetWall", "ASHIKHMIN", (0.9, 0.8, 0.7), 0.8, under=(0.3, 0.3, 0.3)))


def anisotropic(scene):
    """Principled Anisotropic on metal spheres (the default tangent, around
    the object's z axis), approximated by the isotropic GGX of the same
    roughness (core/materials/shader/nodes_shader.py)."""
    _spheres([(0.45, (-0.4, 0.25), _principled("BrushedGold", **{
                  "Base Color": (0.9, 0.7, 0.35, 1), "Metallic": 1.0, "Roughness": 0.35, "Anisotropic": 0.8})),
              (0.35, (0.45, -0.3), _principled("BrushedSteel", **{
                  "Base Color": (0.7, 0.7, 0.75, 1), "Metallic": 1.0, "Roughness": 0.5, "Anisotropic": 0.5,
                  "Anisotropic Rotation": 0.25}))])


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


def _gltf_material(name, **inputs):
    mat, tree, out = _new_material(name)
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = legacy_gltf_group()
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    tree.links.new(node.outputs[0], out.inputs["Surface"])
    return mat


def gltf_legacy(scene):
    """The legacy glTF importer's group (legacy_gltf_group) on the boxes and
    walls: a dielectric, a rough metal (its GGX Glossy scatters once, so it
    loses energy Multiscatter GGX would keep), and a wall half see-through
    (alpha blend) with a little emission."""
    _assign(["TallBox"], _gltf_material("glTFPlastic", BaseColorFactor=(0.8, 0.45, 0.2, 1.0),
                                        MetallicFactor=0.0, RoughnessFactor=0.5))
    _assign(["ShortBox", "Floor"], _gltf_material("glTFMetal", BaseColorFactor=(0.9, 0.8, 0.6, 1.0),
                                                  RoughnessFactor=0.9))
    _assign(["BackWall"], _gltf_material("glTFBlend", BaseColorFactor=(0.3, 0.5, 0.8, 1.0),
                                         MetallicFactor=0.0, RoughnessFactor=0.7, Alpha=0.6,
                                         EmissiveFactor=(0.1, 0.05, 0.02, 1.0)))
    import bpy
    for name in ("TallBox", "ShortBox"):     # off the floor: no faces shared with it
        bpy.data.objects[name].location.z += 0.002


FAMILIES = {"image": image, "procedural": procedural, "brick": brick, "noise": noise, "shaders": shaders, "normals": normals,
            "attributes": attributes, "emission": emission, "glass": glass, "alpha": alpha,
            "hdri": hdri, "sheen": sheen, "anisotropic": anisotropic, "gltf_legacy": gltf_legacy,
            "sheen_node": sheen_node}
