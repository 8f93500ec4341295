"""Helpers of the export tests: empty scenes built from numpy arrays, and
views of the exported core.Scene."""

import math

import numpy as np

W, H = 32, 24


def fresh():
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100
    return scene


def add_mesh(name, verts, faces, collection=None, location=(0, 0, 0), rotation=(0, 0, 0),
             scale=(1, 1, 1)):
    import bpy
    verts = np.asarray(verts, np.float64).reshape(-1, 3)
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts.tolist(), [], [[int(i) for i in f] for f in faces])
    me.update()
    ob = bpy.data.objects.new(name, me)
    ob.location, ob.rotation_euler, ob.scale = location, rotation, scale
    (collection or bpy.context.scene.collection).objects.link(ob)
    return ob


def grid(nx, ny, size=1.0):
    """A flat nx x ny quad grid in the z = 0 plane, centred, side `size`."""
    xs = np.linspace(-size / 2, size / 2, nx + 1)
    ys = np.linspace(-size / 2, size / 2, ny + 1)
    gx, gy = np.meshgrid(xs, ys, indexing="xy")
    verts = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1)
    i = np.arange(ny)[:, None] * (nx + 1) + np.arange(nx)[None, :]
    faces = np.stack([i, i + 1, i + nx + 2, i + nx + 1], axis=-1).reshape(-1, 4)
    return verts, faces


QUAD = (np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float), [[0, 1, 2, 3]])
TRI = (np.array([[0, 0, 0], [0.5, 0, 0], [0, 0.25, 0]], float), [[0, 1, 2]])


def trs(location, rotation, scale):
    """4x4 matrix of Blender's loc/rot(XYZ Euler)/scale, built independently of bpy."""
    ax, ay, az = rotation
    rx = np.array([[1, 0, 0], [0, math.cos(ax), -math.sin(ax)], [0, math.sin(ax), math.cos(ax)]])
    ry = np.array([[math.cos(ay), 0, math.sin(ay)], [0, 1, 0], [-math.sin(ay), 0, math.cos(ay)]])
    rz = np.array([[math.cos(az), -math.sin(az), 0], [math.sin(az), math.cos(az), 0], [0, 0, 1]])
    m = np.eye(4)
    m[:3, :3] = rz @ ry @ rx @ np.diag(scale)
    m[:3, 3] = location
    return m


def apply(m, pts):
    return np.asarray(pts, float) @ m[:3, :3].T + m[:3, 3]


def material(name, node_type=None, **inputs):
    """A node material whose Surface is a new node of `node_type` (default: the
    Principled BSDF the material starts with), inputs set by socket name."""
    import bpy
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    out = next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")
    node = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    if node_type is not None:
        tree.nodes.remove(node)
        node = tree.nodes.new(node_type)
        tree.links.new(node.outputs[0], out.inputs["Surface"])
    for key, value in inputs.items():
        node.inputs[key.replace("_", " ")].default_value = value
    return mat


def export(addon, width=W, height=H):
    """core.Scene of the current (viewport-evaluated) depsgraph."""
    import bpy
    dg = bpy.context.evaluated_depsgraph_get()
    scene, has_camera = addon.restir_addon.export.export_scene(dg, width, height)
    return scene


def export_for_render(addon, monkeypatch):
    """core.Scene the engine builds in a real final render (render-mode depsgraph:
    render visibility, render subdivision levels)."""
    import bpy
    frame_scene = addon.restir_addon.sync.frame_scene
    captured = []
    real = frame_scene.FrameScene.update

    def spy(self, depsgraph, width, height, camera=None, camera_only=False):
        out = real(self, depsgraph, width, height, camera, camera_only)
        captured.append(self.scene)
        return out

    monkeypatch.setattr(frame_scene.FrameScene, "update", spy)
    scene = bpy.context.scene
    if scene.camera is None:
        cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
        cam.location = (0, 0, 10)
        scene.collection.objects.link(cam)
        scene.camera = cam
    scene.render.engine = "RESTIR_GI"
    scene.restir_gi.samples = 1
    scene.render.resolution_x = scene.render.resolution_y = 8
    bpy.ops.render.render()
    assert len(captured) == 1
    return captured[0]


def tri_counts(s):
    """{object name: triangle count} of an exported scene."""
    counts = np.bincount(s.object_ids, minlength=len(s.object_names))
    out = {}
    for i, name in enumerate(s.object_names):   # instances of one object share its name
        out[name] = out.get(name, 0) + int(counts[i])
    return out


def tri_points(s, name=None):
    """(T, 3, 3) world-space corners of the triangles (of one object)."""
    p = s.vertices[s.triangles]
    if name is not None:
        ids = [i for i, n in enumerate(s.object_names) if n == name]
        p = p[np.isin(s.object_ids, ids)]
    return p


def area(p):
    return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)


def row(s, name):
    """What the renderer shades the material called `name` with, as a dict:
    its lobes (core/materials/shading.py's table) and emission."""
    from restir_gi.core.materials.shading import shading
    i = s.materials.names.index(name)
    t = shading(s)
    return {"diffuse": t.table.diffuse[i], "f0": t.table.f0[i], "alpha": t.table.alpha[i],
            "emission": t.emission[i], "id": i}


def light(s, name):
    i = s.lights.names.index(name)
    L = s.lights
    return {k: getattr(L, k)[i] for k in ("kind", "position", "direction", "axis_u", "axis_v",
                                          "power", "radius", "spot_size", "spot_blend", "angle",
                                          "shape", "size_u", "size_v", "soft_falloff",
                                          "camera_visible")}


def add_light(name, kind, location=(0, 0, 0), rotation=(0, 0, 0), scale=(1, 1, 1), **props):
    import bpy
    data = bpy.data.lights.new(name, kind)
    for key, value in props.items():
        setattr(data, key, value)
    ob = bpy.data.objects.new(name, data)
    ob.location, ob.rotation_euler, ob.scale = location, rotation, scale
    bpy.context.scene.collection.objects.link(ob)
    return ob
