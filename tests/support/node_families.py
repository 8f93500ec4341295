"""Scenes for each family of shader nodes, built by script on the example
Cornell box: what tests/oracle/test_nodes_vs_cycles.py renders with both engines and
bench/contact_sheet.py lays out side by side.

Each builder takes the opened Cornell box scene and changes its materials (or
world) so one family of nodes decides most of the image, with the pieces of
cornell_box.py (and gltf_legacy.py's node group).
"""

import math
import os

import numpy as np

from support.cornell_box import assign, new_material, png, principled, spheres
from support.gltf_legacy import gltf_material


def image(scene):
    """Image Texture (UV, Linear and Closest) into Diffuse and Principled."""
    mat, tree, out = new_material("Textured")
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = png("pattern")
    bsdf = tree.nodes.new("ShaderNodeBsdfDiffuse")
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Color"])
    tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    assign(["BackWall", "Floor"], mat)
    mat2, tree2, out2 = new_material("TexturedBoxes")
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
    assign(["TallBox", "ShortBox"], mat2)


def noise(scene):
    """Noise Texture (fBM, distortion) through a Color Ramp, and its Color;
    Voronoi's cell colour and distance on the side walls."""
    mat, tree, out = new_material("Noisy")
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
    assign(["BackWall", "Floor"], mat)
    mat2, tree2, out2 = new_material("NoisyColor")
    tex2 = tree2.nodes.new("ShaderNodeTexNoise")
    d2 = tree2.nodes.new("ShaderNodeBsdfDiffuse")
    tree2.links.new(tex2.outputs["Color"], d2.inputs["Color"])
    tree2.links.new(d2.outputs[0], out2.inputs["Surface"])
    assign(["TallBox", "ShortBox"], mat2)
    mat3, tree3, out3 = new_material("Cells")
    vor = tree3.nodes.new("ShaderNodeTexVoronoi")
    vor.inputs["Scale"].default_value = 3.0
    d3 = tree3.nodes.new("ShaderNodeBsdfDiffuse")
    tree3.links.new(vor.outputs["Color"], d3.inputs["Color"])
    tree3.links.new(d3.outputs[0], out3.inputs["Surface"])
    assign(["LeftWall"], mat3)
    mat4, tree4, out4 = new_material("CellDistance")
    vor4 = tree4.nodes.new("ShaderNodeTexVoronoi")
    vor4.inputs["Scale"].default_value = 6.0
    d4 = tree4.nodes.new("ShaderNodeBsdfDiffuse")
    tree4.links.new(vor4.outputs["Distance"], d4.inputs["Color"])
    tree4.links.new(d4.outputs[0], out4.inputs["Surface"])
    assign(["RightWall"], mat4)


def procedural(scene):
    """Checker, Gradient, Color Ramp, Math, Mix (multiply), Map Range, Hue/Saturation."""
    mat, tree, out = new_material("Procedural")
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
    assign(["BackWall", "Floor", "TallBox", "ShortBox"], mat)


def brick(scene):
    """Brick Texture (offset rows, squashed rows, smooth mortar, bias) as
    colour, and its Fac as roughness."""
    mat, tree, out = new_material("Bricks")
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
    assign(["BackWall", "Floor", "TallBox"], mat)


def shaders(scene):
    """Mix Shader by Layer Weight, Add Shader, Glossy, Emission."""
    mat, tree, out = new_material("Mixed")
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
    assign(["TallBox", "ShortBox"], mat)
    mat2, tree2, out2 = new_material("Added")
    d2 = tree2.nodes.new("ShaderNodeBsdfDiffuse")
    d2.inputs["Color"].default_value = (0.5, 0.5, 0.5, 1)
    e2 = tree2.nodes.new("ShaderNodeEmission")
    e2.inputs["Strength"].default_value = 0.3
    e2.inputs["Color"].default_value = (0.2, 0.4, 1.0, 1)
    add = tree2.nodes.new("ShaderNodeAddShader")
    tree2.links.new(d2.outputs[0], add.inputs[0])
    tree2.links.new(e2.outputs[0], add.inputs[1])
    tree2.links.new(add.outputs[0], out2.inputs["Surface"])
    assign(["BackWall"], mat2)


def normals(scene):
    """Bump from a smooth height, and a tangent-space Normal Map of a constant colour."""
    mat, tree, out = new_material("Bumped")
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
    assign(["BackWall"], mat)
    mat2, tree2, out2 = new_material("NormalMapped")
    nm = tree2.nodes.new("ShaderNodeNormalMap")
    nm.inputs["Color"].default_value = (0.75, 0.5, 0.85, 1)
    d2 = tree2.nodes.new("ShaderNodeBsdfDiffuse")
    tree2.links.new(nm.outputs[0], d2.inputs["Normal"])
    tree2.links.new(d2.outputs[0], out2.inputs["Surface"])
    assign(["Floor"], mat2)


def attributes(scene):
    """Color Attribute on the boxes' corners (the short box's through an
    Attribute node without a name, which reads zero, added to grey), Object
    Info's Random through a ramp."""
    import bpy
    mat, tree, out = new_material("VertexColored")
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
    assign(["TallBox"], mat)
    mat1, tree1, out1 = new_material("UnnamedAttribute")
    unnamed = tree1.nodes.new("ShaderNodeAttribute")
    unnamed.attribute_name = ""
    add = tree1.nodes.new("ShaderNodeMix")
    add.data_type, add.blend_type = "RGBA", "ADD"
    add.inputs["Factor"].default_value = 1.0
    add.inputs["B"].default_value = (0.3, 0.3, 0.3, 1)
    tree1.links.new(unnamed.outputs["Color"], add.inputs["A"])
    d1 = tree1.nodes.new("ShaderNodeBsdfDiffuse")
    tree1.links.new(add.outputs["Result"], d1.inputs["Color"])
    tree1.links.new(d1.outputs[0], out1.inputs["Surface"])
    assign(["ShortBox"], mat1)
    mat2, tree2, out2 = new_material("ByObject")
    info = tree2.nodes.new("ShaderNodeObjectInfo")
    ramp = tree2.nodes.new("ShaderNodeValToRGB")
    tree2.links.new(info.outputs["Color"], ramp.inputs["Fac"])
    d2 = tree2.nodes.new("ShaderNodeBsdfDiffuse")
    tree2.links.new(ramp.outputs["Color"], d2.inputs["Color"])
    tree2.links.new(d2.outputs[0], out2.inputs["Surface"])
    for name, c in (("BackWall", (0.8, 0.8, 0.8, 1)), ("Floor", (0.4, 0.4, 0.4, 1))):
        bpy.data.objects[name].color = c
    assign(["BackWall", "Floor"], mat2)


def emission(scene):
    """Emission coloured by Blackbody, the ceiling light of the box."""
    mat, tree, out = new_material("Blackbody")
    bb = tree.nodes.new("ShaderNodeBlackbody")
    bb.inputs["Temperature"].default_value = 4000.0
    e = tree.nodes.new("ShaderNodeEmission")
    e.inputs["Strength"].default_value = 15.0
    tree.links.new(bb.outputs[0], e.inputs["Color"])
    tree.links.new(e.outputs[0], out.inputs["Surface"])
    assign(["CeilingLight"], mat)


def glass(scene):
    """Glass BSDF (rough) and Principled transmission, seen against the walls."""
    mat, tree, out = new_material("Glass")
    g = tree.nodes.new("ShaderNodeBsdfGlass")
    g.inputs["Roughness"].default_value = 0.15
    g.inputs["IOR"].default_value = 1.45
    g.inputs["Color"].default_value = (0.9, 0.95, 1.0, 1)
    tree.links.new(g.outputs[0], out.inputs["Surface"])
    assign(["TallBox"], mat)
    mat2, tree2, out2 = new_material("Transmissive")
    p = tree2.nodes.new("ShaderNodeBsdfPrincipled")
    p.inputs["Base Color"].default_value = (0.9, 0.6, 0.3, 1)
    p.inputs["Transmission Weight"].default_value = 1.0
    p.inputs["Roughness"].default_value = 0.3
    tree2.links.new(p.outputs[0], out2.inputs["Surface"])
    assign(["ShortBox"], mat2)
    import bpy
    for name in ("TallBox", "ShortBox"):     # off the floor: no faces shared with it
        bpy.data.objects[name].location.z += 0.002


def alpha(scene):
    """An alpha-clipped card (checker holes through Principled Alpha) casting a
    patterned shadow, and a box half transparent through a Mix with Transparent."""
    import bpy
    mat, tree, out = new_material("Cutout")
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
    mat2, tree2, out2 = new_material("HalfTransparent")
    d = tree2.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (0.8, 0.3, 0.3, 1)
    t = tree2.nodes.new("ShaderNodeBsdfTransparent")
    mix = tree2.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.5
    tree2.links.new(d.outputs[0], mix.inputs[1])
    tree2.links.new(t.outputs[0], mix.inputs[2])
    tree2.links.new(mix.outputs[0], out2.inputs["Surface"])
    assign(["TallBox"], mat2)
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


def sheen(scene):
    """Principled sheen (weight 1) on dark bases: two spheres of different
    Sheen Roughness and Tint, and a sheen on the grey floor, seen at grazing."""
    spheres([(0.45, (-0.4, 0.25), principled("Velvet", **{
                 "Base Color": (0.05, 0.05, 0.05, 1), "Sheen Weight": 1.0, "Sheen Roughness": 0.5})),
             (0.35, (0.45, -0.3), principled("Satin", **{
                 "Base Color": (0.12, 0.02, 0.02, 1), "Roughness": 0.4, "Sheen Weight": 1.0,
                 "Sheen Roughness": 0.2, "Sheen Tint": (1.0, 0.8, 0.6, 1)}))])
    assign(["Floor"], principled("SheenFloor", **{
        "Base Color": (0.3, 0.3, 0.3, 1), "Sheen Weight": 1.0, "Sheen Roughness": 0.8,
        "Sheen Tint": (0.6, 0.7, 1.0, 1)}))


def _sheen_node(name, distribution, color, roughness, under=None, mix=None):
    """A Sheen BSDF node of its own; under: the colour of a Diffuse BSDF it
    is added to; mix: the factor of a Mix Shader of that Diffuse and it."""
    mat, tree, out = new_material(name)
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
    spheres([(0.45, (-0.4, 0.25), _sheen_node("Microfiber", "MICROFIBER", (0.9, 0.35, 0.5), 0.4,
                                              under=(0.05, 0.05, 0.08))),
             (0.35, (0.45, -0.3), _sheen_node("Velvet", "ASHIKHMIN", (0.5, 0.7, 1.0), 0.35))])
    assign(["Floor"], _sheen_node("SheenFloor", "MICROFIBER", (0.8, 0.9, 0.6), 0.7, under=(0.4, 0.4, 0.4),
                                  mix=0.5))
    assign(["BackWall"], _sheen_node("VelvetWall", "ASHIKHMIN", (0.9, 0.8, 0.7), 0.8, under=(0.3, 0.3, 0.3)))


def anisotropic(scene):
    """Principled Anisotropic on metal spheres (the default tangent, around
    the object's z axis), approximated by the isotropic GGX of the same
    roughness (core/materials/shader/nodes_shader.py)."""
    spheres([(0.45, (-0.4, 0.25), principled("BrushedGold", **{
                 "Base Color": (0.9, 0.7, 0.35, 1), "Metallic": 1.0, "Roughness": 0.35, "Anisotropic": 0.8})),
             (0.35, (0.45, -0.3), principled("BrushedSteel", **{
                 "Base Color": (0.7, 0.7, 0.75, 1), "Metallic": 1.0, "Roughness": 0.5, "Anisotropic": 0.5,
                 "Anisotropic Rotation": 0.25}))])


def gltf_legacy(scene):
    """The legacy glTF importer's group (legacy_gltf_group) on the boxes and
    walls: a dielectric, a rough metal (its GGX Glossy scatters once, so it
    loses energy Multiscatter GGX would keep), and a wall half see-through
    (alpha blend) with a little emission."""
    assign(["TallBox"], gltf_material("glTFPlastic", BaseColorFactor=(0.8, 0.45, 0.2, 1.0),
                                      MetallicFactor=0.0, RoughnessFactor=0.5))
    assign(["ShortBox", "Floor"], gltf_material("glTFMetal", BaseColorFactor=(0.9, 0.8, 0.6, 1.0),
                                                RoughnessFactor=0.9))
    assign(["BackWall"], gltf_material("glTFBlend", BaseColorFactor=(0.3, 0.5, 0.8, 1.0),
                                       MetallicFactor=0.0, RoughnessFactor=0.7, Alpha=0.6,
                                       EmissiveFactor=(0.1, 0.05, 0.02, 1.0)))
    import bpy
    for name in ("TallBox", "ShortBox"):     # off the floor: no faces shared with it
        bpy.data.objects[name].location.z += 0.002


def principled_ior(scene):
    """Principled BSDFs by their IOR, as Cycles reads it: 0 on the boxes
    (older glTF imports wrote it; the specular layer then reflects
    everything, coat or not), 3 on the back wall (a normal reflectance of
    0.25, most of which the diffuse base below it loses)."""
    assign(["TallBox", "ShortBox"], principled("IORZero", **{"Base Color": (0.2, 0.6, 0.1, 1.0), "IOR": 0.0,
                                                            "Roughness": 0.5, "Coat Weight": 0.25}))
    assign(["BackWall"], principled("IORThree", **{"Base Color": (0.7, 0.3, 0.2, 1.0), "IOR": 3.0,
                                                   "Roughness": 0.4}))


FAMILIES = {"image": image, "procedural": procedural, "brick": brick, "noise": noise, "shaders": shaders, "normals": normals,
            "attributes": attributes, "emission": emission, "glass": glass, "alpha": alpha,
            "hdri": hdri, "sheen": sheen, "anisotropic": anisotropic, "gltf_legacy": gltf_legacy,
            "sheen_node": sheen_node, "principled_ior": principled_ior}
