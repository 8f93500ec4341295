"""A lit floor with one object per kind of edit over frames 1-4 (keyframes,
a world's strength, a modifier, a frame-change handler adding and deleting
objects), for the tests of animation renders."""

import pytest

from support.addon_util import add_mesh, camera, fresh, rect, world

FRAMES = (1, 2, 3, 4)


def principled(name, color):
    import bpy
    mat = bpy.data.materials.new(name)
    mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (*color, 1.0)
    return mat


def add_box(name, location, size=0.4, mat=None):
    s = size / 2
    verts = [[x, y, z] for z in (0, size) for y in (-s, s) for x in (-s, s)]
    faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    return add_mesh(name, verts, faces, location=location, mat=mat)


def edits_by_frame(scene, *_args):
    """Stands in for a driver or script: 'Added' exists from frame 3 on,
    'Doomed' until frame 3 (deleted at 4)."""
    import bpy
    f = scene.frame_current
    added = bpy.data.objects.get("Added")
    if f >= 3 and added is None:
        add_box("Added", (1.6, 1.6, 0.0), mat=principled("AddedMat", (0.1, 0.2, 0.9)))
    elif f < 3 and added is not None:
        bpy.data.objects.remove(added)
    doomed = bpy.data.objects.get("Doomed")
    if f >= 4 and doomed is not None:
        bpy.data.objects.remove(doomed)
    elif f < 4 and doomed is None:
        add_box("Doomed", (-1.6, 1.6, 0.0), mat=principled("DoomedMat", (0.9, 0.9, 0.1)))


def build_scene(persistent, mode="PATH"):
    """A lit floor with one object per kind of edit, frames 1-4."""
    import bpy
    scene = fresh(32, 24, samples=2, mode=mode)
    scene.restir_gi.warmup_frames = 2
    scene.render.use_persistent_data = persistent
    sky = world((0.05, 0.05, 0.05))
    cam = camera(location=(0, 0, 6), type="ORTHO", ortho_scale=6.0)
    add_mesh("Floor", *rect(-3, 3, -3, 3), mat=principled("FloorMat", (0.8, 0.8, 0.8)))
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 2.0
    sun_obj = bpy.data.objects.new("Sun", sun)
    sun_obj.rotation_euler = (0.4, 0.2, 0.0)
    scene.collection.objects.link(sun_obj)
    lamp = bpy.data.lights.new("Lamp", "POINT")
    lamp_obj = bpy.data.objects.new("Lamp", lamp)
    lamp_obj.location = (1.0, -1.0, 1.5)
    scene.collection.objects.link(lamp_obj)

    def key(target, path, values):
        for frame, value in zip(FRAMES, values):
            setattr(target, path, value)
            target.keyframe_insert(path, frame=frame)

    key(lamp, "energy", (300.0, 300.0, 0.0, 0.0))                   # switched off at 3
    key(cam, "location", [(0.1 * f, 0.0, 6.0) for f in FRAMES])    # camera moving
    mover = add_box("Mover", (0, 0, 0), mat=principled("MoverMat", (0.9, 0.3, 0.2)))
    key(mover, "location", [(-1.5 + 0.6 * f, -1.2, 0.0) for f in FRAMES])
    hider = add_box("Hider", (1.6, 0.0, 0.0), mat=principled("HiderMat", (0.2, 0.9, 0.2)))
    key(hider, "hide_render", (False, False, True, True))         # hidden for render at 3
    bent = add_mesh("Bent", *rect(-2.4, -1.2, -0.6, 0.6, z=0.3),
                    mat=principled("BentMat", (0.7, 0.7, 0.9)))
    bent.shape_key_add(name="Basis")
    raised = bent.shape_key_add(name="Raised")
    raised.data[0].co.z = 1.5
    key(raised, "value", (0.0, 0.3, 0.6, 1.0))                    # deforming mesh
    tinted = principled("Tinted", (0.9, 0.1, 0.1))
    rows = add_box("Rows", (0.0, 1.4, 0.0), size=0.3, mat=tinted)
    array = rows.modifiers.new("Array", "ARRAY")
    key(array, "count", (1, 2, 3, 4))                             # vertex count changes every frame
    color = tinted.node_tree.nodes["Principled BSDF"].inputs["Base Color"]
    key(color, "default_value", [(0.9, 0.1, 0.1, 1.0), (0.1, 0.9, 0.1, 1.0)] * 2)  # material animated
    key(sky.node_tree.nodes["Background"].inputs["Strength"], "default_value",
        (1.0, 4.0, 4.0, 12.0))                                    # world animated
    scene.frame_start, scene.frame_end = FRAMES[0], FRAMES[-1]
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    bpy.app.handlers.frame_change_pre.append(edits_by_frame)
    edits_by_frame(scene)
    return scene


@pytest.fixture
def edits_handler():
    import bpy
    yield
    if edits_by_frame in bpy.app.handlers.frame_change_pre:
        bpy.app.handlers.frame_change_pre.remove(edits_by_frame)
