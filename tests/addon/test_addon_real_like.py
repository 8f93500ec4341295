"""Scenes built the way real files are built, rendered in every mode through
Blender's render operator: what the engine meets in files made by others, where
hand-made test scenes of one feature each did not reach.

- an Environment Texture world (a generated Color Grid: what Blender shows for
  a missing image), seen behind the objects;
- an emissive material whose emission varies over the surface (an image on
  a screen), seen at its silhouette against that world;
- a node-group material with transparency (Mix Shader of a Transparent BSDF
  by an alpha, inside a group, as glTF importers build them);
- several materials on one mesh.

Each render must finish without an error report, with a finite image that is
not black, in Path Tracing and both ReSTIR modes.
"""

import numpy as np
import pytest

from support.addon_util import MODES, add_mesh, camera, fresh, read_passes, render_exr


def _grid_image(name="Missing Image", size=16):
    import bpy
    image = bpy.data.images.new(name, size, size)
    image.generated_type = "COLOR_GRID"
    return image


def _environment_world(strength=1.0):
    import bpy
    w = bpy.data.worlds.new("World")
    tree = w.node_tree
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = _grid_image("Missing HDRI")
    bg = tree.nodes["Background"]
    bg.inputs["Strength"].default_value = strength
    tree.links.new(env.outputs["Color"], bg.inputs["Color"])
    bpy.context.scene.world = w
    return w


def _textured_emitter(name="Screen"):
    """Principled BSDF whose base and emission colours come from an image."""
    import bpy
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    bsdf = tree.nodes["Principled BSDF"]
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = _grid_image("Screen Image")
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Emission Color"])
    bsdf.inputs["Emission Strength"].default_value = 2.0
    return mat


def _grouped_cutout(name="Cutout"):
    """A node group holding a Mix Shader of a Transparent BSDF and a Principled
    BSDF by an alpha input, fed by an image's alpha (glTF importers' layout)."""
    import bpy
    group = bpy.data.node_groups.new(name + " Group", "ShaderNodeTree")
    iface = group.interface
    iface.new_socket("Base Color", in_out="INPUT", socket_type="NodeSocketColor")
    iface.new_socket("Alpha", in_out="INPUT", socket_type="NodeSocketFloat")
    iface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")
    gin = group.nodes.new("NodeGroupInput")
    gout = group.nodes.new("NodeGroupOutput")
    transparent = group.nodes.new("ShaderNodeBsdfTransparent")
    principled = group.nodes.new("ShaderNodeBsdfPrincipled")
    mix = group.nodes.new("ShaderNodeMixShader")
    group.links.new(gin.outputs["Base Color"], principled.inputs["Base Color"])
    group.links.new(gin.outputs["Alpha"], mix.inputs["Fac"])
    group.links.new(transparent.outputs[0], mix.inputs[1])
    group.links.new(principled.outputs[0], mix.inputs[2])
    group.links.new(mix.outputs[0], gout.inputs["Shader"])

    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = _grid_image("Leaf Image")
    wave = tree.nodes.new("ShaderNodeTexChecker")      # an alpha that cuts holes
    tree.links.new(tex.outputs["Color"], node.inputs["Base Color"])
    tree.links.new(wave.outputs["Fac"], node.inputs["Alpha"])
    tree.links.new(node.outputs["Shader"], tree.nodes["Material Output"].inputs["Surface"])
    return mat


def _flat(name, color):
    import bpy
    mat = bpy.data.materials.new(name)
    mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (*color, 1.0)
    return mat


def _box(name, centre, half, mats):
    """An axis-aligned box whose six faces take the materials ``mats`` in turn."""
    c, h = np.asarray(centre, float), np.asarray(half, float)
    corners = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], float) * h + c
    faces = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    ob = add_mesh(name, corners, faces)
    for m in mats:
        ob.data.materials.append(m)
    for i, poly in enumerate(ob.data.polygons):
        poly.material_index = i % len(mats)
    return ob


SCENES = ["environment_world", "emitter_silhouette", "grouped_cutout", "several_materials"]


def _build(kind, mode):
    scene = fresh(32, 32, samples=4, mode=mode)
    scene.restir_gi.warmup_frames = 4
    scene.render.filter_size = 1.5          # Blender's default pixel filter: silhouettes get refined
    camera(location=(0, -6, 1.5), rotation=(1.35, 0, 0))
    _environment_world()
    if kind == "emitter_silhouette":
        _box("Screen", (0, 0, 1), (1.2, 0.1, 0.8), [_textured_emitter()])
    elif kind == "grouped_cutout":
        add_mesh("Leaf", [(-2, 0, 0), (2, 0, 0), (2, 0, 2.5), (-2, 0, 2.5)], [[0, 1, 2, 3]],
                 mat=_grouped_cutout())
    elif kind == "several_materials":
        _box("Crate", (0, 0, 1), (1, 1, 1), [_flat("Red", (0.8, 0.1, 0.1)), _flat("Green", (0.1, 0.8, 0.1)),
                                             _textured_emitter("Label")])
    add_mesh("Floor", [(-8, -8, 0), (8, -8, 0), (8, 8, 0), (-8, 8, 0)], [[0, 1, 2, 3]],
             mat=_flat("Floor", (0.5, 0.5, 0.5)))
    return scene


@pytest.mark.slow
@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("kind", SCENES)
def test_real_like_scene_renders(addon, reports, tmp_path, kind, mode):
    scene = _build(kind, mode)
    path = tmp_path / "frame.exr"
    render_exr(scene, path, multilayer=True)
    errors = reports.of("ERROR")
    assert errors == [], errors
    img = read_passes(path)["Combined"]
    assert img.shape[:2] == (32, 32)
    assert np.isfinite(img).all()
    assert img[..., :3].mean() > 0.01       # the world and the lit floor are seen


@pytest.mark.parametrize("mode", ["RESTIR_BIASED", "RESTIR_UNBIASED"])
def test_a_failing_stage_is_named_in_the_report(addon, reports, tmp_path, monkeypatch, mode):
    """An error that escapes a ReSTIR frame says in its report which stage
    it came from."""
    def broken(*args, **kwargs):
        raise IndexError("index 7 is out of bounds")
    monkeypatch.setattr(addon.core.restir.frame, "spatial_resample", broken)
    scene = _build("several_materials", mode)
    with pytest.raises(RuntimeError):       # Blender's operator raises on an error report
        render_exr(scene, tmp_path / "frame.exr", multilayer=True)
    errors = reports.of("ERROR")
    assert len(errors) == 1
    assert "IndexError: index 7 is out of bounds" in errors[0] and "stage: spatial reuse" in errors[0], errors
