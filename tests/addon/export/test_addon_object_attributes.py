"""The Attribute node's Object and Instancer types
(restir_addon/export/object_attributes.py): per-object values from custom
properties of the object or its data, or a property path, as Cycles reads
them; Instancer from the instancing object; a keyframed property changes
the next frame of an animation.

Squares glow with the attribute as their emission colour (black world, no
lights), seen straight down by an orthographic camera, so each square's
centre pixel is the colour read.
"""

import numpy as np

from support.addon_util import add_mesh, camera, fresh, rect, world
from restir_gi.core.camera.film import read_exr

SIZE = 48


def glow_by_attribute(kind, name):
    """An Emission shader whose colour is an Attribute node's Color output."""
    import bpy
    mat = bpy.data.materials.new(f"Attr_{kind}_{name}")
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    emit = nodes.new("ShaderNodeEmission")
    attr = nodes.new("ShaderNodeAttribute")
    attr.attribute_type, attr.attribute_name = kind, name
    links.new(attr.outputs["Color"], emit.inputs["Color"])
    links.new(emit.outputs["Emission"], out.inputs["Surface"])
    return mat


def square(name, x, y, mat, size=0.8):
    h = size / 2
    return add_mesh(name, *rect(x - h, x + h, y - h, y + h), mat=mat)


def pixel(img, x, y):
    """Pixel at world (x, y) for the camera of ``scene_with`` (ortho 4 m wide, bottom row first)."""
    col = int((x + 2.0) / 4.0 * SIZE)
    row = int((y + 2.0) / 4.0 * SIZE)
    return img[row, col]


def scene_with(mode="PATH"):
    scene = fresh(SIZE, SIZE, samples=4, mode=mode)
    world((0, 0, 0))
    camera(location=(0, 0, 5), type="ORTHO", ortho_scale=4.0)
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    return scene


def render(scene, path):
    import bpy
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return read_exr(path)


def test_object_attributes_are_read_as_cycles_reads_them(addon, reports, tmp_path):
    scene = scene_with()
    tint = glow_by_attribute("OBJECT", "tint")
    own = square("Own", -1.0, 1.0, tint)
    own["tint"] = [0.9, 0.2, 0.1]                       # the object's custom property
    from_data = square("FromData", 1.0, 1.0, tint)
    from_data.data["tint"] = 0.5                        # its mesh's, a number: grey
    square("Without", -1.0, -1.0, tint)                 # none: zero
    by_path = square("ByPath", 1.0, -1.0, glow_by_attribute("OBJECT", "color"))
    by_path.color = (0.2, 0.6, 0.3, 1.0)                # a property path of the object
    img = render(scene, tmp_path / "attrs.exr")
    assert np.allclose(pixel(img, -1.0, 1.0), (0.9, 0.2, 0.1), atol=1e-3)
    assert np.allclose(pixel(img, 1.0, 1.0), (0.5, 0.5, 0.5), atol=1e-3)
    assert np.allclose(pixel(img, -1.0, -1.0), 0.0, atol=1e-6)
    assert np.allclose(pixel(img, 1.0, -1.0), (0.2, 0.6, 0.3), atol=1e-3)
    assert reports.of("ERROR") == []


def test_instancer_attributes_come_from_the_instancing_object(addon, reports, tmp_path):
    import bpy
    scene = scene_with()
    child = square("Child", 0.0, 0.0, glow_by_attribute("INSTANCER", "tint"), size=0.5)
    child["tint"] = [0.1, 0.1, 0.8]
    parent = add_mesh("Parent", [[-1, 1, 0], [1, 1, 0]], [], location=(0, 0, 0))
    parent["tint"] = [0.8, 0.4, 0.1]
    parent.instance_type = "VERTS"
    child.parent = parent
    child.location = (0.0, -1.0, 0.0)       # the original, not instanced: renders at (0, -1)
    bpy.context.view_layer.update()
    img = render(scene, tmp_path / "instancer.exr")
    # Instances sit at the parent's vertices (child offset kept): (-1, 0) and (1, 0).
    for x in (-1.0, 1.0):
        assert np.allclose(pixel(img, x, 0.0), (0.8, 0.4, 0.1), atol=1e-3), pixel(img, x, 0.0)
    assert reports.of("ERROR") == []


def test_a_keyframed_property_changes_the_next_frame(addon, reports, tmp_path):
    import bpy
    scene = scene_with()
    ob = square("Animated", 0.0, 0.0, glow_by_attribute("OBJECT", "tint"), size=1.5)
    for frame, value in ((1, 0.2), (2, 0.9)):
        ob["tint"] = value
        ob.keyframe_insert('["tint"]', frame=frame)
    scene.frame_start, scene.frame_end = 1, 2
    scene.render.filepath = str(tmp_path / "anim_####")
    bpy.ops.render.render(animation=True)
    first, second = (read_exr(tmp_path / f"anim_{f:04d}.exr") for f in (1, 2))
    assert np.allclose(pixel(first, 0.0, 0.0), 0.2, atol=1e-3)
    assert np.allclose(pixel(second, 0.0, 0.0), 0.9, atol=1e-3)
    assert reports.of("ERROR") == []
