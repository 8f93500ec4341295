"""Scenes, fixtures and steps shared by the viewport session's tests
(test_viewport.py, test_viewport_sync.py, test_viewport_materials.py).

bpy in background mode never calls view_update / view_draw, so the tests
build a scene from numpy arrays, edit it the way a user would, record what a
depsgraph_update_post handler sees in ``depsgraph.updates`` and feed that to
``ViewportSession.sync``. Their fixtures ``vp`` and ``recorder`` are in
conftest.py.
"""

import dataclasses

import numpy as np

W, H = 48, 32


# ---------------------------------------------------------------- scene helpers

def add_mesh(name, verts, faces, material=None, location=(0, 0, 0), scale=(1, 1, 1)):
    import bpy
    me = bpy.data.meshes.new(name)
    me.from_pydata(np.asarray(verts, float).tolist(), [], [[int(i) for i in f] for f in faces])
    me.update()
    if material is not None:
        me.materials.append(material)
    ob = bpy.data.objects.new(name, me)
    ob.location, ob.scale = location, scale
    bpy.context.scene.collection.objects.link(ob)
    return ob


def cube():
    v = np.array([[x, y, z] for z in (-0.5, 0.5) for y in (-0.5, 0.5) for x in (-0.5, 0.5)])
    f = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    return v, f


def grid(n, size):
    xs = np.linspace(-size / 2, size / 2, n + 1)
    gx, gy = np.meshgrid(xs, xs, indexing="xy")
    v = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1)
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    return v, np.stack([i, i + 1, i + n + 2, i + n + 1], axis=-1).reshape(-1, 4)


def principled(name, color):
    import bpy
    mat = bpy.data.materials.new(name)
    node = next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    node.inputs["Base Color"].default_value = (*color, 1.0)
    node.inputs["Roughness"].default_value = 1.0
    return mat


def look_at(obj, target):
    from mathutils import Vector
    direction = Vector(target) - obj.location
    obj.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()


def build_scene():
    """Floor, a box, a small box that moves, a point light, a grey world, a camera."""
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100
    floor = add_mesh("Floor", *grid(4, 6.0), material=principled("Grey", (0.6, 0.6, 0.6)))
    add_mesh("Box", *cube(), material=principled("Red", (0.7, 0.2, 0.1)), location=(0, 0, 0.5))
    add_mesh("Mover", *cube(), material=principled("Blue", (0.1, 0.2, 0.7)),
             location=(1.3, -0.6, 0.3), scale=(0.6, 0.6, 0.6))
    light = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    light.data.energy = 800.0
    light.data.shadow_soft_size = 0.2
    light.location = (0.5, -1.0, 3.0)
    scene.collection.objects.link(light)
    world = bpy.data.worlds.new("World")
    scene.world = world
    background = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    background.inputs["Color"].default_value = (0.1, 0.1, 0.12, 1.0)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (0.0, -5.5, 3.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    look_at(cam, (0.2, 0.0, 0.3))
    del floor
    bpy.context.view_layer.update()
    return scene


def depsgraph():
    import bpy
    return bpy.context.evaluated_depsgraph_get()


def new_session(vp, mode="PATH", scale="FULL", **kw):
    kw.setdefault("max_bounces", 2)
    kw.setdefault("threads", 1)
    session = vp.ViewportSession(mode=mode, scale=scale, **kw)
    session.sync(depsgraph())
    return session


def work_delta(before, after):
    """The counters that changed, and by how much."""
    a, b = dataclasses.asdict(before), dataclasses.asdict(after)
    return {k: b[k] - a[k] for k in a if b[k] != a[k]}


def keys(session):
    """The scene's (geometry, lighting) keys: what ReSTIR GI compares between
    frames to reuse visibility and to validate samples."""
    return session.scene.geometry_key(), session.scene.lighting_key()


def step(session, updates=None, frames=1):
    """sync the updates, render frames; return the counters that changed."""
    before = dataclasses.replace(session.work)
    if updates is not None:
        session.sync(depsgraph(), updates)
    for _ in range(frames):
        assert session.render_step()
    return work_delta(before, session.work)
