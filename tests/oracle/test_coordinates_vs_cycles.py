"""Texture coordinates Cycles derives from the object, against Cycles pixel by
pixel: each case an emitter whose colour is the coordinate (x 0.5 + 0.5),
seen by an orthographic camera, so every pixel is the coordinate itself and
only anti-aliasing noise at the silhouette differs.

- The Geometry node's Tangent: Cycles' radial tangent around the object's Z
  axis through the centre of its Generated coordinates (without it, the UV
  tangent: godot-blender-exporter's material_geometry.blend was 0.61x).
- Generated coordinates of a deformed mesh: those of the mesh before its
  deformation (a shape key here; an armature's pose in
  material_generated_tex_coord.blend, 1.20x before).
- Texture Coordinate's Camera (camera space, z along the view; scaled by
  0.1 here) and Window (the frame's [0, 1]^2, through a perspective camera):
  both read zero before (material_cycle.blend).
"""

import math

import pytest

SPP = 16


def _emitter(name, output, scale=0.5):
    """A material emitting ``output(tree)`` x scale + 0.5."""
    import bpy
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    tree.nodes.clear()
    out, emit = tree.nodes.new("ShaderNodeOutputMaterial"), tree.nodes.new("ShaderNodeEmission")
    factor = scale
    scale = tree.nodes.new("ShaderNodeVectorMath")
    scale.operation = "MULTIPLY_ADD"
    scale.inputs[1].default_value = (factor,) * 3
    scale.inputs[2].default_value = (0.5, 0.5, 0.5)
    tree.links.new(output(tree), scale.inputs[0])
    tree.links.new(scale.outputs[0], emit.inputs["Color"])
    tree.links.new(emit.outputs[0], out.inputs["Surface"])
    return mat


def _tangent(tree):
    return tree.nodes.new("ShaderNodeNewGeometry").outputs["Tangent"]


def _generated(tree):
    return tree.nodes.new("ShaderNodeTexCoord").outputs["Generated"]


def _sphere(mat):
    import bpy
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.5, segments=48, ring_count=24, location=(0.2, 0.0, 0.0),
                                         rotation=(0.4, 0.3, 0.2))
    ob = bpy.context.object
    bpy.ops.object.shade_smooth()
    ob.data.materials.append(mat)
    ob.scale = (1.0, 1.3, 0.9)


def _shape_keyed_cube(mat):
    """A cube whose only shape key, at full value, shears and stretches it:
    its Generated coordinates stay those of the cube."""
    import bpy
    bpy.ops.mesh.primitive_cube_add(size=2.0, rotation=(0.5, 0.4, 0.3))
    ob = bpy.context.object
    ob.data.materials.append(mat)
    ob.shape_key_add(name="Basis")
    key = ob.shape_key_add(name="Shear")
    for point in key.data:
        x, y, z = point.co
        point.co = (x * 0.8 + 0.5 * z, y * 1.2, z + 0.3 * x)
    key.value = 1.0


def _coordinate(name):
    return lambda tree: tree.nodes.new("ShaderNodeTexCoord").outputs[name]


# case: (coordinate, object, scale of the coordinate, orthographic camera)
CASES = {"geometry_tangent": (_tangent, _sphere, 0.5, True),
         "generated_of_a_deformed_mesh": (_generated, _shape_keyed_cube, 0.5, True),
         "camera": (_coordinate("Camera"), _sphere, 0.1, True),
         "window": (_coordinate("Window"), _sphere, 0.5, False)}


@pytest.mark.parametrize("case", list(CASES))
def test_coordinate_matches_cycles(addon, case):
    from support.addon_util import camera, fresh, world
    from support.blender_util import pixel_difference
    output, shape, scale, ortho = CASES[case]
    scene = fresh(96, 96, samples=SPP)
    world((0, 0, 0))
    lens = dict(type="ORTHO", ortho_scale=5.0) if ortho else dict(lens=35.0)
    camera(location=(0, 0, 6), rotation=(0, 0, math.radians(10)), **lens)
    shape(_emitter(case, output, scale))
    diff, noise = pixel_difference(scene, SPP)
    print(f"{case}: mean |ours - cycles| {diff:.4f}, noise {noise:.4f}")
    assert diff < 1.5 * noise + 2e-3, (diff, noise)
