"""Image Texture projections against Cycles pixel by pixel: an emitter of a
generated colour grid on a turned UV sphere, seen by an orthographic
camera. Box blends three planar lookups by the object-space normal (with
and without Projection Blend, from Object coordinates); Sphere and Tube
wrap Generated coordinates around the object's z axis. Before, every
projection but Flat fell back to Flat (a warning)."""

import math

import pytest

SPP = 16
CASES = {"box": ("BOX", 0.0, "Object"), "box_blend": ("BOX", 0.35, "Object"),
         "sphere": ("SPHERE", 0.0, "Generated"), "tube": ("TUBE", 0.0, "Generated")}


def _material(projection, blend, coords):
    import bpy
    image = bpy.data.images.new("grid", 64, 64)
    image.generated_type = "COLOR_GRID"
    mat = bpy.data.materials.new("projected")
    tree = mat.node_tree
    tree.nodes.clear()
    out, emit = tree.nodes.new("ShaderNodeOutputMaterial"), tree.nodes.new("ShaderNodeEmission")
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image, tex.projection, tex.projection_blend = image, projection, blend
    tex.interpolation = "Closest"
    tree.links.new(tree.nodes.new("ShaderNodeTexCoord").outputs[coords], tex.inputs["Vector"])
    tree.links.new(tex.outputs["Color"], emit.inputs["Color"])
    tree.links.new(emit.outputs[0], out.inputs["Surface"])
    return mat


@pytest.mark.parametrize("case", list(CASES))
def test_image_projection_matches_cycles(addon, case):
    import bpy
    from support.addon_util import camera, fresh, world
    from support.blender_util import pixel_difference
    scene = fresh(96, 96, samples=SPP)
    world((0, 0, 0))
    camera(location=(0, 0, 6), rotation=(0, 0, math.radians(10)), type="ORTHO", ortho_scale=4.0)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.5, segments=48, ring_count=24, rotation=(0.7, 0.4, 0.3))
    ob = bpy.context.object
    bpy.ops.object.shade_smooth()
    ob.data.materials.append(_material(*CASES[case]))
    diff, noise = pixel_difference(scene, SPP)
    print(f"{case}: mean |ours - cycles| {diff:.4f}, noise {noise:.4f}")
    assert diff < 1.5 * noise + 2e-3, (diff, noise)
