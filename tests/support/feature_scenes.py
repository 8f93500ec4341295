"""Scenes for the renderer's features beyond shader nodes (issue 40: panoramic
cameras, point clouds, hair, volumes, motion blur), built by script on the example Cornell
box: the feature rows of bench/contact_sheet.py, ours beside Cycles. Each
builder takes the opened Cornell box scene and changes it so the feature
decides most of the image; the tests of each feature (tests/addon/export/test_panorama.py,
test_strands.py, test_volumes.py) compare their own, smaller scenes with
Cycles. The point cloud and hair builders are also those tests' objects.
"""

import math

import numpy as np


def _pano(scene, **props):
    cam = scene.camera
    cam.location = (0.0, -0.6, 1.0)
    cam.rotation_euler = (math.radians(90), 0.0, 0.0)
    cam.data.type = "PANO"
    cam.data.clip_start = 0.01
    for key, value in props.items():
        setattr(cam.data, key, value)


def panorama_equirectangular(scene):
    """An equirectangular camera inside the box, looking at the back wall."""
    _pano(scene, panorama_type="EQUIRECTANGULAR")


def panorama_fisheye(scene):
    """An equisolid fisheye (180 degrees) inside the box, looking at the back wall."""
    _pano(scene, panorama_type="FISHEYE_EQUISOLID", fisheye_fov=math.pi, fisheye_lens=8.0)


def point_cloud_object(name="Dots", zero_radius=False, centre=(0.0, 0.0, 0.0), scale=1.0):
    """A 5 x 5 grid of points turned into spheres of radii 0.05-0.25 by a
    geometry nodes Mesh to Points (a point cloud instance, as real files
    make them); zero_radius: every other point of radius 0."""
    import bpy
    from support.addon_util import add_mesh
    from support.blender_util import diffuse_material
    xs = np.linspace(-1.2, 1.2, 5)
    verts = [(x, y, 0.3 + 0.1 * i) for i, (x, y) in enumerate((x, y) for x in xs for y in xs)]
    ob = add_mesh(name, verts, [], mat=diffuse_material(name, (0.8, 0.3, 0.1)), location=centre)
    ob.scale = (scale,) * 3
    tree = bpy.data.node_groups.new(name, "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    gin, gout = tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")
    to_points = tree.nodes.new("GeometryNodeMeshToPoints")
    index, math_node = tree.nodes.new("GeometryNodeInputIndex"), tree.nodes.new("ShaderNodeMath")
    # radius = 0.05 + 0.008 * index, or 0 for odd indices with zero_radius
    math_node.operation = "MULTIPLY_ADD"
    math_node.inputs[1].default_value, math_node.inputs[2].default_value = 0.008, 0.05
    tree.links.new(index.outputs[0], math_node.inputs[0])
    radius = math_node.outputs[0]
    if zero_radius:
        mod = tree.nodes.new("ShaderNodeMath")
        mod.operation = "FLOORED_MODULO"
        mod.inputs[1].default_value = 2.0
        tree.links.new(index.outputs[0], mod.inputs[0])
        even = tree.nodes.new("ShaderNodeMath")
        even.operation = "MULTIPLY"
        sub = tree.nodes.new("ShaderNodeMath")
        sub.operation = "SUBTRACT"
        sub.inputs[0].default_value = 1.0
        tree.links.new(mod.outputs[0], sub.inputs[1])
        tree.links.new(sub.outputs[0], even.inputs[0])
        tree.links.new(radius, even.inputs[1])
        radius = even.outputs[0]
    tree.links.new(gin.outputs[0], to_points.inputs["Mesh"])
    tree.links.new(radius, to_points.inputs["Radius"])
    tree.links.new(to_points.outputs[0], gout.inputs[0])
    ob.modifiers.new("ToPoints", "NODES").node_group = tree
    return ob


def hair_object(name="Fur", material=None, counts=None, radius=(0.03, 0.004), centre=(0.0, 0.0, 0.0), scale=1.0):
    """Straight strands on a 6 x 6 grid, 8 points each, leaning a little,
    radius tapering from root to tip."""
    import bpy
    from support.blender_util import diffuse_material
    curves = bpy.data.hair_curves.new(name)
    grid = np.linspace(-1.0, 1.0, 6)
    roots = np.array([(x, y, 0.0) for x in grid for y in grid])
    counts = counts or [8] * len(roots)
    curves.add_curves(counts)
    pos, rad = [], []
    for root, k in zip(roots, counts):
        s = np.linspace(0.0, 1.0, k)
        pos.append(root + np.outer(s, (0.15, 0.1, 0.9)))
        rad.append(radius[0] + (radius[1] - radius[0]) * s)
    curves.position_data.foreach_set("vector", np.concatenate(pos).astype(np.float32).ravel())
    attr = curves.attributes.get("radius") or curves.attributes.new("radius", "FLOAT", "POINT")
    attr.data.foreach_set("value", np.concatenate(rad).astype(np.float32))
    curves.materials.append(material or diffuse_material(name, (0.2, 0.6, 0.9)))
    ob = bpy.data.objects.new(name, curves)
    ob.location, ob.scale = centre, (scale,) * 3
    bpy.context.scene.collection.objects.link(ob)
    return ob


def _clear_boxes():
    import bpy
    for name in ("TallBox", "ShortBox"):
        bpy.data.objects.remove(bpy.data.objects[name])


def point_cloud(scene):
    """Spheres of radii 0.05-0.25 x 0.6 (a geometry nodes Mesh to Points)
    in place of the boxes."""
    _clear_boxes()
    point_cloud_object(centre=(0.0, 0.1, 0.0), scale=0.6)


def hair(scene):
    """Tapering strands (Diffuse, 3D curves) in place of the boxes."""
    _clear_boxes()
    scene.cycles_curves.shape = "THICK"
    hair_object(centre=(0.0, 0.0, 0.0), scale=0.6, radius=(0.04, 0.01))


def _principled_volume(name, **inputs):
    """A material whose only output is a Principled Volume of these inputs."""
    import bpy
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    node = tree.nodes.new("ShaderNodeVolumePrincipled")
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    tree.links.new(node.outputs[0], tree.nodes["Material Output"].inputs["Volume"])
    return mat


def volume(scene):
    """A box of Principled Volume (density 2, warm colour, anisotropy 0.3)
    in place of the tall box; Cycles' Light Paths > Volume bounces 2."""
    import bpy
    tall = bpy.data.objects["TallBox"]
    mat = _principled_volume("Fog", Density=2.0, Color=(0.9, 0.7, 0.5, 1.0), Anisotropy=0.3)
    tall.data.materials.clear()
    tall.data.materials.append(mat)
    tall.location.z += 0.01         # off the floor: coplanar faces flicker between the two
    scene.cycles.volume_bounces = 2


def volume_object(scene):
    """A lumpy ball of smoke from a .vdb file (a volume object, Principled
    Volume of density 4) in place of the tall box; Volume bounces 2."""
    import os
    import tempfile
    import bpy
    from .volume_scenes import lumpy_ball, write_vdb
    path = write_vdb(os.path.join(tempfile.gettempdir(), "restir_gi_contact_ball.vdb"), {"density": lumpy_ball()},
                     voxel=1.0 / 40)
    bpy.data.objects.remove(bpy.data.objects["TallBox"])
    vol = bpy.data.volumes.new("Smoke")
    vol.filepath = path
    ob = bpy.data.objects.new("Smoke", vol)
    ob.location = (-0.9, -0.4, 0.0)
    scene.collection.objects.link(ob)
    vol.materials.append(_principled_volume("Smoke", Density=4.0, Color=(0.9, 0.8, 0.7, 1.0)))
    scene.cycles.volume_bounces = 2


def world_volume(scene):
    """Fog filling the world (Volume Scatter, density 0.25, anisotropy 0.2),
    around the box and inside it; Cycles' Light Paths > Volume bounces 2."""
    tree = scene.world.node_tree
    node = tree.nodes.new("ShaderNodeVolumeScatter")
    node.inputs["Density"].default_value = 0.25
    node.inputs["Anisotropy"].default_value = 0.2
    out = next(n for n in tree.nodes if n.type == "OUTPUT_WORLD")
    tree.links.new(node.outputs[0], out.inputs["Volume"])
    scene.cycles.volume_bounces = 2


def motion_blur(scene):
    """The short box sliding 0.8 and turning 30 degrees over the frame, the
    camera turning a little, shutter 0.5 around frame 1.5."""
    import math
    box, cam = scene.objects["ShortBox"], scene.camera
    x, yaw = box.location.x, box.rotation_euler.z
    for frame, dx, dyaw, cam_yaw in ((1, -0.4, -15.0, -1.5), (2, 0.4, 15.0, 1.5)):
        box.location.x, box.rotation_euler.z = x + dx, yaw + math.radians(dyaw)
        box.keyframe_insert("location", frame=frame)
        box.keyframe_insert("rotation_euler", frame=frame)
        cam.rotation_euler.z = math.radians(cam_yaw)
        cam.keyframe_insert("rotation_euler", frame=frame)
    scene.frame_set(1, subframe=0.5)
    scene.render.use_motion_blur = True
    scene.render.motion_blur_shutter = 0.5


FEATURES = {"panorama_equirectangular": panorama_equirectangular, "panorama_fisheye": panorama_fisheye,
            "point_cloud": point_cloud, "hair": hair, "volume": volume, "volume_object": volume_object,
            "world_volume": world_volume,
            "motion_blur": motion_blur}
