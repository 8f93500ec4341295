"""The viewport reads the corner data its materials need (named UV maps,
colour attributes, normal-map tangents), as the final render does."""

import numpy as np

from support.viewport_util import build_scene, new_session, step


def test_viewport_reads_colour_attributes_and_tangents(vp):
    import bpy
    build_scene()
    box = bpy.data.objects["Box"]
    col = box.data.color_attributes.new("Paint", "FLOAT_COLOR", "CORNER")
    col.data.foreach_set("color", np.tile(np.float32([0.9, 0.1, 0.1, 1.0]), len(col.data)))
    box.data.uv_layers.new(name="UVMap")
    mat = bpy.data.materials["Red"]
    tree = mat.node_tree
    p = tree.nodes["Principled BSDF"]
    attr = tree.nodes.new("ShaderNodeVertexColor")
    attr.layer_name = "Paint"
    tree.links.new(attr.outputs["Color"], p.inputs["Base Color"])
    nm = tree.nodes.new("ShaderNodeNormalMap")
    tree.links.new(nm.outputs["Normal"], p.inputs["Normal"])
    session = new_session(vp, mode="RESTIR_BIASED")
    step(session)
    scene = session.scene
    assert {"color:Paint", "tangent:"} <= set(scene.corner_data)
    for data in scene.corner_data.values():
        assert len(data) == scene.triangle_count
    boxes = scene.object_ids == scene.object_keys.index(("Box", ()))
    assert np.allclose(scene.corner_data["color:Paint"][boxes][..., :3], [0.9, 0.1, 0.1], atol=1e-6)
    assert np.isfinite(session.frame).all()
    session.close()
