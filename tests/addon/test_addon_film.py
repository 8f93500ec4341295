"""Film > Transparent: the world seen directly is left out and Combined's
alpha is each pixel's coverage by geometry, in every mode; the world still
lights the scene."""

import numpy as np
import pytest

from support.addon_util import MODES, FakeEngine, add_mesh, camera, fresh, rect, world


def render(addon):
    """Combined (H, W, 4) of a final render through the engine's code."""
    import bpy
    engine = FakeEngine(["Combined", "Depth", "Normal", "Denoising Albedo"])
    engine.is_animation = False
    addon.restir_addon.final.render(engine, bpy.context.evaluated_depsgraph_get())
    assert not [m for k, m in engine.log if k == "ERROR"], engine.log
    return engine.pixels["Combined"].reshape(16, 16, 4)


@pytest.mark.parametrize("mode", MODES)
def test_transparent_film_alpha_is_coverage(addon, mode):
    scene = fresh(16, 16, samples=4, mode=mode)
    scene.render.film_transparent = True
    camera()
    world((0.5, 0.5, 0.5))
    add_mesh("Half", *rect(-10, 0, -10, 10))         # covers the left half of the view
    rgba = render(addon)
    assert np.isfinite(rgba).all()
    left, right = rgba[:, :6], rgba[:, 10:]
    assert np.allclose(left[..., 3], 1.0) and np.allclose(right[..., 3], 0.0)
    assert np.allclose(right[..., :3], 0.0)                   # no world seen directly
    assert (left[..., :3].mean() > 0.1)                         # but it lights the plane
    edge = rgba[:, 7:9, 3]
    assert ((edge > 0.0) & (edge < 1.0)).any()                  # filtered coverage at the edge
    scene.render.film_transparent = False
    rgba = render(addon)
    assert np.allclose(rgba[..., 3], 1.0) and np.allclose(rgba[:, 10:, :3], 0.5, atol=1e-3)


@pytest.mark.parametrize("mode", MODES)
def test_holdout_cuts_out_the_object(addon, mode):
    """A Holdout material leaves a transparent black hole where the camera sees
    it, with or without Film > Transparent."""
    import bpy
    fresh(16, 16, samples=4, mode=mode)
    camera()
    world((0.5, 0.5, 0.5))
    mat = bpy.data.materials.new("Cut")
    tree = mat.node_tree
    out = next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")
    tree.links.new(tree.nodes.new("ShaderNodeHoldout").outputs[0], out.inputs["Surface"])
    add_mesh("Hole", *rect(-10, 0, -10, 10), mat=mat)
    rgba = render(addon)
    left, right = rgba[:, :6], rgba[:, 10:]
    assert np.allclose(left, 0.0)                                   # cut out: black, alpha 0
    assert np.allclose(right[..., 3], 1.0) and np.allclose(right[..., :3], 0.5, atol=1e-3)


@pytest.mark.parametrize("how", ["material", "object", "collection"])
def test_holdout_in_a_mirror_as_cycles(addon, how):
    """A holdout box on a mirror floor with Film > Transparent: cut out where
    the camera sees it, not in its reflection (reflected paths leave
    Cycles' transparent background too): alpha and colour as Cycles'. The
    box is a holdout by its material (its reflection black), or as an object
    or a collection (Object > Visibility > Holdout, the view layer's
    collection Holdout: its reflection keeps its own material)."""
    import os
    import tempfile

    import OpenEXR
    from support.blender_util import open_example, set_resolution, setup_cycles, setup_restir
    from support.cornell_box import assign, new_material, principled
    import bpy
    scene = open_example("cornell_box.blend")
    set_resolution(scene, 48, 48)
    assign(["Floor"], principled("Mirror", **{"Base Color": (0.9, 0.9, 0.9, 1), "Metallic": 1.0,
                                               "Roughness": 0.02}))
    box = bpy.data.objects["ShortBox"]
    if how == "material":
        mat, tree, out = new_material("Hold")
        tree.links.new(tree.nodes.new("ShaderNodeHoldout").outputs[0], out.inputs["Surface"])
        assign(["ShortBox"], mat)
    elif how == "object":
        box.is_holdout = True
    else:
        held = bpy.data.collections.new("Held")
        scene.collection.children.link(held)
        for owner in list(box.users_collection):
            owner.objects.unlink(box)
        held.objects.link(box)
        bpy.context.view_layer.layer_collection.children["Held"].holdout = True
    scene.render.film_transparent = True
    s = scene.render.image_settings
    s.file_format, s.color_depth, s.color_mode = "OPEN_EXR", "32", "RGBA"
    result = {}
    for name, setup in (("ours", setup_restir), ("cycles", setup_cycles)):
        setup(scene, 32, 1, 4)
        fd, path = tempfile.mkstemp(suffix=".exr")
        os.close(fd)
        try:
            scene.render.filepath = path
            bpy.ops.render.render(write_still=True)
            with OpenEXR.File(path, separate_channels=True) as f:
                ch = f.parts[0].channels
                result[name] = np.stack([ch[k].pixels for k in "RGBA"], -1)
        finally:
            os.unlink(path)
    ours, cycles = result["ours"], result["cycles"]
    cut = cycles[..., 3] < 0.5
    assert 0.03 < cut.mean() < 0.3                              # the box is cut out...
    assert abs((ours[..., 3] < 0.5).mean() - cut.mean()) < 0.01   # ... in the same pixels
    assert abs(ours[..., 3].mean() - cycles[..., 3].mean()) < 0.005
    assert abs(np.minimum(ours[..., :3], 1).mean() / np.minimum(cycles[..., :3], 1).mean() - 1) < 0.03
