"""Export of materials and worlds: every material becomes a shader graph
(restir_addon/export/node_graph.py) that the core evaluates; here the lobes
and emission it shades with are checked against values computed from the
numbers the scene was built with."""

import numpy as np
import pytest

from restir_gi.core.bsdfs.principled import principled_lobes
from support.export_util import QUAD, add_mesh, export, fresh, grid, material, row, tri_points


def test_material_slots_map_per_triangle(addon):
    fresh()
    verts, faces = grid(3, 1)
    ob = add_mesh("obj", verts, faces)
    red = material("red", "ShaderNodeBsdfDiffuse", Color=(1, 0, 0, 1))
    blue = material("blue", "ShaderNodeBsdfDiffuse", Color=(0, 0, 1, 1))
    green = material("green", "ShaderNodeBsdfDiffuse", Color=(0, 1, 0, 1))
    ob.data.materials.append(red)
    ob.data.materials.append(blue)
    ob.data.materials.append(blue)
    ob.material_slots[2].link = "OBJECT"           # the object's own material wins
    ob.material_slots[2].material = green
    ob.data.polygons.foreach_set("material_index", [1, 0, 2])
    ob.data.update()
    s = export(addon)

    assert s.triangle_count == 6
    centre_x = tri_points(s).mean(axis=1)[:, 0]
    from restir_gi.core.materials.shading import shading
    colour = shading(s).table.diffuse[s.material_ids]
    for x, want in ((-1 / 3, (0, 0, 1)), (0, (1, 0, 0)), (1 / 3, (0, 1, 0))):
        sel = np.abs(centre_x - x) < 1 / 6
        assert sel.sum() == 2
        np.testing.assert_allclose(colour[sel], [want, want])
    assert s.warnings == []


def test_shader_nodes_read(addon):
    fresh()
    mats = [
        material("principled", Base_Color=(0.2, 0.3, 0.4, 1), Metallic=0.7, Roughness=0.25,
                 IOR=1.45, Specular_IOR_Level=0.6, Emission_Color=(1, 0.5, 0.25, 1),
                 Emission_Strength=2.0),
        material("diffuse", "ShaderNodeBsdfDiffuse", Color=(0.1, 0.6, 0.2, 1)),
        material("glossy", "ShaderNodeBsdfGlossy", Color=(0.9, 0.8, 0.7, 1), Roughness=0.15),
        material("emission", "ShaderNodeEmission", Color=(1, 0.5, 0.25, 1), Strength=4.0),
    ]
    for i, mat in enumerate(mats):
        add_mesh(mat.name, *QUAD, location=(2 * i, 0, 0)).data.materials.append(mat)
    s = export(addon)
    assert s.warnings == []

    p = row(s, "principled")
    diffuse, f0, rough, layer_f0 = principled_lobes(np.float32([0.2, 0.3, 0.4]), np.float32(0.7), np.float32(0.25),
                                          np.float32(1.45), np.float32(0.6))
    np.testing.assert_allclose(p["diffuse"], diffuse.ravel(), rtol=1e-5)
    np.testing.assert_allclose(p["f0"], f0.ravel(), rtol=1e-5)
    np.testing.assert_allclose(p["alpha"], 0.25 ** 2, rtol=1e-5)
    np.testing.assert_allclose(p["emission"], (2, 1, 0.5), rtol=1e-6)

    d = row(s, "diffuse")
    np.testing.assert_allclose(d["diffuse"], (0.1, 0.6, 0.2), rtol=1e-6)
    np.testing.assert_allclose(d["f0"], 0)                  # pure Lambert
    np.testing.assert_allclose(d["emission"], 0)

    g = row(s, "glossy")
    np.testing.assert_allclose(g["f0"], (0.9, 0.8, 0.7), rtol=1e-6)
    np.testing.assert_allclose(g["diffuse"], 0)
    np.testing.assert_allclose(g["alpha"], 0.15 ** 2, rtol=1e-5)

    e = row(s, "emission")
    np.testing.assert_allclose(e["emission"], (4, 2, 1), rtol=1e-6)
    np.testing.assert_allclose(e["diffuse"], 0)
    np.testing.assert_allclose(e["f0"], 0)

    # Triangles point at their own object's material.
    for name in ("principled", "diffuse", "glossy", "emission"):
        ids = s.material_ids[s.object_ids == s.object_names.index(name)]
        assert (ids == row(s, name)["id"]).all()


@pytest.mark.parametrize("node_type, label", [("ShaderNodeBsdfToon", "Toon BSDF"),
                                              ("ShaderNodeBsdfRayPortal", "Ray Portal BSDF")])
def test_unsupported_node_warns_once(addon, node_type, label):
    """An unknown BSDF renders as a grey diffuse surface (of its Color input,
    where it has one), with one warning naming the material and the node."""
    fresh()
    mat = material("odd", node_type)
    for i in range(3):                 # three users, two slots on one of them
        ob = add_mesh(f"obj{i}", *QUAD, location=(2 * i, 0, 0))
        ob.data.materials.append(mat)
    ob.data.materials.append(mat)
    s = export(addon)

    naming = [w for w in s.warnings if label in w or node_type[10:].upper() in w.upper()]
    assert len(naming) == 1, s.warnings
    assert "odd" in naming[0]
    assert len(s.warnings) == 1, s.warnings
    r = row(s, "odd")
    node = next(n for n in mat.node_tree.nodes if n.bl_idname == node_type)
    color = node.inputs["Color"].default_value[:3] if "Color" in node.inputs else (0.8, 0.8, 0.8)
    np.testing.assert_allclose(r["diffuse"], color, rtol=1e-5)
    np.testing.assert_allclose(r["emission"], 0)


def test_subsurface_says_it_renders_as_diffuse(addon):
    """Subsurface scattering (a Principled BSDF's weight, or its own node)
    renders as diffuse reflection and says so once, naming the material;
    a Principled BSDF without it says nothing. Every material warning
    starts with the material's name the same way."""
    fresh()
    for i, mat in enumerate((material("skin", Subsurface_Weight=0.5), material("plain"),
                             material("wax", "ShaderNodeSubsurfaceScattering"))):
        ob = add_mesh(f"obj{i}", *QUAD, location=(2 * i, 0, 0))
        ob.data.materials.append(mat)
    s = export(addon)
    assert sorted(s.warnings) == [
        "Material 'skin': node 'Principled BSDF': subsurface scattering renders as diffuse reflection of "
        "its colour",
        "Material 'wax': node 'Subsurface Scattering': subsurface scattering renders as diffuse "
        "reflection of its colour"], s.warnings


def test_textured_inputs_are_evaluated(addon):
    """A texture feeding an input is evaluated on the hits: the material is no
    longer one row, and nothing warns about it."""
    fresh()
    mat = material("textured", Base_Color=(0.3, 0.2, 0.1, 1))
    tree = mat.node_tree
    checker = tree.nodes.new("ShaderNodeTexChecker")
    tree.links.new(checker.outputs["Color"], tree.nodes["Principled BSDF"].inputs["Base Color"])
    add_mesh("obj", *QUAD).data.materials.append(mat)
    s = export(addon)
    from restir_gi.core.materials.shading import shading
    assert s.warnings == []
    assert shading(s).varying == [row(s, "textured")["id"]]
    assert "generated" in s.corner_data


def test_world_colour_times_strength(addon):
    import bpy
    scene = fresh()
    assert scene.world is None
    assert export(addon).environment is None

    world = bpy.data.worlds.new("World")
    scene.world = world
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.2, 0.4, 0.6, 1)
    bg.inputs["Strength"].default_value = 2.5
    s = export(addon)
    np.testing.assert_allclose(s.environment.constant, (0.5, 1.0, 1.5), rtol=1e-6)
    assert s.warnings == []

    sky = world.node_tree.nodes.new("ShaderNodeTexSky")
    world.node_tree.links.new(sky.outputs[0], bg.inputs["Color"])
    s = export(addon)
    assert s.environment is not None and s.environment.constant is None
    assert s.warnings == [] and s.environment.sun_pmf > 0     # the default sky, its sun sampled apart
    sky.sky_type = "HOSEK_WILKIE"       # no sun disc: the map alone
    s = export(addon)
    assert s.environment is not None and s.environment.sun_pmf == 0 and s.warnings == []


@pytest.mark.slow
def test_materials_showcase_exports_and_renders(addon, tmp_path):
    """The bundled materials example (example_blends/make_materials.py):
    textures, a normal map, glass, an alpha card and an HDRI world, all read
    without a warning, and a small render is finite and lit."""
    import bpy
    from support.blender_util import open_example, render_image, set_resolution
    from restir_gi.core.materials.shading import shading
    scene = open_example("materials_showcase.blend")
    s, has_camera = addon.restir_addon.export.export_scene(bpy.context.evaluated_depsgraph_get(), 64, 36)
    assert has_camera and s.warnings == []
    assert {"tiles_color", "tiles_normal", "leaf_mask", "sunset.exr"} <= set(s.images)
    assert s.environment is not None and s.environment.constant is None and s.environment.width == 1024
    names = [s.materials.names[i] for i in shading(s).varying]
    assert {"Tiles", "Glass", "BrushedMetal", "Leaf", "PaintedBox"} <= set(names)
    assert {"uv:", "tangent:", "color:Paint"} <= set(s.corner_data)
    set_resolution(scene, 48, 27)
    scene.restir_gi.warmup_frames = 2
    img = render_image(scene)
    assert np.isfinite(img).all() and 0.05 < img.mean() < 5.0


def test_tangents_follow_the_instance(addon):
    """Normal-map tangents are read in object space and placed with each
    instance: a quad turned 90 degrees about z has its U tangent along +y."""
    import math
    fresh()
    mat = material("mapped", "ShaderNodeBsdfDiffuse")
    tree = mat.node_tree
    nm = tree.nodes.new("ShaderNodeNormalMap")
    tree.links.new(nm.outputs["Normal"], tree.nodes["Diffuse BSDF"].inputs["Normal"])
    ob = add_mesh("turned", *QUAD, rotation=(0, 0, math.pi / 2))
    ob.data.uv_layers.new(name="UVMap").data.foreach_set("uv", np.float32([0, 0, 1, 0, 1, 1, 0, 1]))
    ob.data.materials.append(mat)
    s = export(addon)
    t = s.corner_data["tangent:"]
    np.testing.assert_allclose(t[..., :3].reshape(-1, 3), np.tile([0, 1, 0], (t.shape[0] * 3, 1)), atol=1e-5)


def test_negative_emission_emits_nothing_and_says_so(addon):
    """Cycles subtracts the light of a negative emission strength; the engine
    leaves it out (the emitter stays dark) and warns, once."""
    fresh()
    mat = material("sink", "ShaderNodeEmission", Color=(1, 0.5, 0.25, 1), Strength=-3.0)
    add_mesh("sink", *QUAD).data.materials.append(mat)
    s = export(addon)
    np.testing.assert_allclose(row(s, "sink")["emission"], 0)
    assert [w for w in s.warnings if "negative emission" in w] == [
        "Material 'sink': negative emission is not supported; it emits no light"], s.warnings


def _light_path_mix(tree, shader_0, shader_1, out):
    """Mix Shader of shader_0 / shader_1 by Light Path > Is Camera Ray, into `out`."""
    mix = tree.nodes.new("ShaderNodeMixShader")
    path = tree.nodes.new("ShaderNodeLightPath")
    tree.links.new(path.outputs["Is Camera Ray"], mix.inputs[0])
    tree.links.new(shader_0.outputs[0], mix.inputs[1])
    tree.links.new(shader_1.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], out)


@pytest.mark.parametrize("mode", ["PATH", "RESTIR_BIASED", "RESTIR_UNBIASED"])
def test_light_path_is_camera_ray_seen_by_the_camera(addon, mode):
    """An emitter only the camera sees (Is Camera Ray picks Emission over a
    Diffuse BSDF) shows its emission and lights nothing; a world whose
    background differs for the camera shows it and lights with the other."""
    import bpy
    from support.addon_util import add_mesh as add, camera, fresh as fresh_scene, rect, world
    from support.blender_util import diffuse_material, render_image
    scene = fresh_scene(32, 24, 4, mode)
    camera()
    w = world((0.5, 0.5, 0.5))
    tree = w.node_tree
    red = tree.nodes.new("ShaderNodeBackground")
    red.inputs["Color"].default_value = (1, 0, 0, 1)
    _light_path_mix(tree, tree.nodes["Background"], red, tree.nodes["World Output"].inputs["Surface"])
    mat = bpy.data.materials.new("camera only")
    t = mat.node_tree
    t.nodes.remove(t.nodes["Principled BSDF"])
    glow = t.nodes.new("ShaderNodeEmission")
    glow.inputs["Strength"].default_value = 2.0
    _light_path_mix(t, t.nodes.new("ShaderNodeBsdfDiffuse"), glow, t.nodes["Material Output"].inputs["Surface"])
    add("Glow", *rect(-0.3, 0.3, -0.3, 0.3, 1.0), mat=mat)
    add("Floor", *rect(-1, 1, -1, 1), mat=diffuse_material("grey", (0.8, 0.8, 0.8)))
    img = render_image(scene)[..., :3]
    assert np.isfinite(img).all()
    np.testing.assert_allclose(img[12, 16], 2.0, rtol=0.02)          # the emitter, as the camera sees it
    np.testing.assert_allclose(img[0, 0], (1, 0, 0), atol=1e-3)       # the camera's background
    # The floor beside the emitter: lit by the grey world only (at most
    # 0.8 x 0.5, less what the emitter's quad hides of the sky), neither by
    # the emitter nor by the red background. With 4 samples a pixel, path
    # tracing measured 0.408-0.429 over four seeds (64 samples: 0.391-0.400);
    # the emitter's light would add about 1.
    floor = img[12, 9]
    assert 0.3 < floor.mean() < 0.45
    assert abs(floor[0] - floor[2]) < 0.02


def test_object_info_object_index_is_the_pass_index(addon):
    """Object Info > Object Index is the object's Pass Index (Cycles), read
    again when it changes between renders; it was 0 for every object."""
    import bpy
    from support.addon_util import add_mesh as add, camera, fresh as fresh_scene, rect, world
    from support.blender_util import render_image
    scene = fresh_scene(32, 24, 2, "PATH")
    camera()
    world((1.0, 1.0, 1.0))
    mat = bpy.data.materials.new("by index")
    t = mat.node_tree
    t.nodes.remove(t.nodes["Principled BSDF"])
    info, quarter = t.nodes.new("ShaderNodeObjectInfo"), t.nodes.new("ShaderNodeMath")
    quarter.operation, quarter.inputs[1].default_value = "MULTIPLY", 0.25
    glow = t.nodes.new("ShaderNodeEmission")
    t.links.new(info.outputs["Object Index"], quarter.inputs[0])
    t.links.new(quarter.outputs[0], glow.inputs["Strength"])
    t.links.new(glow.outputs[0], t.nodes["Material Output"].inputs["Surface"])
    left = add("Left", *rect(-2, 0, -2, 2), mat=mat)
    right = add("Right", *rect(0, 2, -2, 2), mat=mat)
    left.pass_index, right.pass_index = 1, 3
    img = render_image(scene)[..., :3]
    np.testing.assert_allclose(img[12, 4], 0.25, rtol=1e-3)
    np.testing.assert_allclose(img[12, 27], 0.75, rtol=1e-3)
    right.pass_index = 2
    img = render_image(scene)[..., :3]
    np.testing.assert_allclose(img[12, 27], 0.5, rtol=1e-3)
    s = export(addon)
    assert sorted(s.object_info["Object Index"]) == [1, 2]


def test_object_info_material_index_is_the_material_pass_index(addon):
    """Object Info > Material Index is the material's Pass Index (Cycles);
    it was 0 for every material."""
    import bpy
    from support.addon_util import add_mesh as add, camera, fresh as fresh_scene, rect, world
    from support.blender_util import render_image
    scene = fresh_scene(32, 24, 2, "PATH")
    camera()
    world((0.0, 0.0, 0.0))
    group = bpy.data.node_groups.new("glow by material index", "ShaderNodeTree")
    group.interface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")
    info, glow = group.nodes.new("ShaderNodeObjectInfo"), group.nodes.new("ShaderNodeEmission")
    out = group.nodes.new("NodeGroupOutput")
    group.links.new(info.outputs["Material Index"], glow.inputs["Strength"])
    group.links.new(glow.outputs[0], out.inputs[0])
    for name, x0, index in (("A", -2, 1), ("B", 0, 3)):     # one node group, two materials
        mat = bpy.data.materials.new(name)
        t = mat.node_tree
        t.nodes.remove(t.nodes["Principled BSDF"])
        node = t.nodes.new("ShaderNodeGroup")
        node.node_tree = group
        t.links.new(node.outputs[0], t.nodes["Material Output"].inputs["Surface"])
        mat.pass_index = index
        add(name, *rect(x0, x0 + 2, -2, 2), mat=mat)
    img = render_image(scene)[..., :3]
    np.testing.assert_allclose(img[12, 4], 1.0, rtol=1e-3)
    np.testing.assert_allclose(img[12, 27], 3.0, rtol=1e-3)
