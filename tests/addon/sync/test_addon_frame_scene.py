"""Animation renders keep the exported scene between frames
(restir_addon/sync/frame_scene.py): what changed between two frames is seen, and
only that is read again.

Each kind of edit is animated (keyframes, a world's strength, a modifier, a frame-change handler
standing in for a driver that adds and deletes objects); every frame of the
animation must match a render of that frame from scratch, with Persistent
Data off (changes found by comparison) and on (Blender's update flags).
"""

import glob
import os
import re

import numpy as np
import pytest

from support.addon_util import add_mesh, assert_valid, camera, fresh, rect, world
from restir_gi.core.camera.film import read_exr
from support.animated_scene import (  # noqa: F401 (edits_handler: a fixture)
    FRAMES, add_box, build_scene, edits_by_frame, edits_handler, principled)


def _render_animation(addon, scene, tmp_path, name):
    import bpy
    work = {}
    stream = addon.restir_addon.state.stream_for(scene.name, bpy.context.view_layer.name)

    def post(sc, *_):
        w = stream.frame_scene.work
        work[sc.frame_current] = (w.mesh_exports, w.accel_static_builds, w.full_exports)

    scene.render.filepath = str(tmp_path / f"{name}_####")
    bpy.app.handlers.render_post.append(post)
    try:
        bpy.ops.render.render(animation=True)
    finally:
        bpy.app.handlers.render_post.remove(post)
    return {f: read_exr(tmp_path / f"{name}_{f:04d}.exr") for f in FRAMES}, work


@pytest.mark.parametrize("persistent", [False, True], ids=["compare", "persistent"])
def test_every_edit_between_frames_is_seen(addon, reports, tmp_path, edits_handler, persistent):  # noqa: F811
    import bpy
    scene = build_scene(persistent)
    addon.restir_addon.state.clear()
    animation, work = _render_animation(addon, scene, tmp_path, "anim")
    for f in FRAMES:
        addon.restir_addon.state.clear()        # a render of frame f from scratch
        scene.frame_set(f)
        scene.render.filepath = str(tmp_path / f"still_{f}.exr")
        bpy.ops.render.render(write_still=True)
        still = read_exr(tmp_path / f"still_{f}.exr")
        assert_valid(animation[f], (24, 32))
        # Same pixels up to float differences of the two-part Embree scene.
        diff = np.abs(animation[f] - still)
        assert diff.mean() < 1e-3 * still.mean(), (f, diff.mean(), still.mean())
    # The edits did change the picture from frame to frame.
    assert np.abs(animation[3] - animation[2]).mean() > 0.05 * animation[2].mean()
    # Only frame 1 read everything.
    assert all(w[2] == work[1][2] for w in work.values()), work
    assert reports.of("ERROR") == []


def test_camera_and_object_motion_read_no_mesh(addon, reports, tmp_path):
    """Frames where only the camera and an object's matrix change read no mesh
    data and build no new static Embree scene."""
    for persistent in (False, True):
        scene = fresh(24, 16, samples=1, mode="RESTIR_BIASED")
        scene.restir_gi.warmup_frames = 1
        scene.render.use_persistent_data = persistent
        world((0.5, 0.5, 0.5))
        add_mesh("Floor", *rect(-2, 2, -2, 2))
        cam = camera(location=(0, 0, 5), type="ORTHO", ortho_scale=4.0)
        box = add_box("Box", (0, 0, 0))
        for f in FRAMES:
            cam.location.x = 0.1 * f
            cam.keyframe_insert("location", frame=f)
            box.location.y = 0.2 * f
            box.keyframe_insert("location", frame=f)
        scene.frame_start, scene.frame_end = FRAMES[0], FRAMES[-1]
        scene.render.image_settings.file_format = "OPEN_EXR"
        addon.restir_addon.state.clear()
        images, work = _render_animation(addon, scene, tmp_path, f"motion{int(persistent)}")
        first = work[FRAMES[0]]
        assert all(w[:2] == first[:2] for w in work.values()), (persistent, work)
        for img in images.values():
            assert_valid(img, (16, 24))
    assert reports.of("ERROR") == []


def test_lights_are_kept_while_only_other_objects_move(addon, reports, tmp_path):
    """The light set is built again only in frames where an emitter moved;
    the scene's bounds, kept per object, are those of its vertices."""
    import bpy
    from restir_gi.core.scene import column_bounds
    scene = fresh(24, 16, samples=1, mode="RESTIR_BIASED")
    scene.restir_gi.warmup_frames = 1
    world((0.1, 0.1, 0.1))
    add_mesh("Floor", *rect(-2, 2, -2, 2))
    camera(location=(0, 0, 5), type="ORTHO", ortho_scale=4.0)
    glow = bpy.data.materials.new("Glow")
    glow.node_tree.nodes["Principled BSDF"].inputs["Emission Strength"].default_value = 5.0
    glow.node_tree.nodes["Principled BSDF"].inputs["Emission Color"].default_value = (1, 1, 1, 1)
    box, lamp = add_box("Box", (0, 0, 0)), add_box("Lamp", (1, 1, 0), size=0.2, mat=glow)
    for f in FRAMES:
        box.location = (0.6 * f, -0.5, 0.0)             # out of the floor's bounds at frame 4
        box.keyframe_insert("location", frame=f)
        lamp.location = (1.0, 1.0, 0.5 * (f >= 3))      # the emitter moves at frame 3 only
        lamp.keyframe_insert("location", frame=f)
    scene.frame_start, scene.frame_end = FRAMES[0], FRAMES[-1]
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(tmp_path / "lights_####")
    addon.restir_addon.state.clear()
    stream = addon.restir_addon.state.stream_for(scene.name, bpy.context.view_layer.name)
    seen = {}

    def post(sc, *_):
        kept = stream.frame_scene.scene
        bounds = np.array(kept.bounds()), np.array(column_bounds(kept.vertices))
        seen[sc.frame_current] = (stream.frame_scene.context.lights, bounds)

    bpy.app.handlers.render_post.append(post)
    try:
        bpy.ops.render.render(animation=True)
    finally:
        bpy.app.handlers.render_post.remove(post)
    sets = [seen[f][0] for f in FRAMES]
    assert sets[0] is sets[1] and sets[1] is not sets[2] and sets[2] is sets[3], sets
    for f in FRAMES:
        assert np.array_equal(*seen[f][1]), (f, seen[f][1])
    assert seen[4][1][0][1, 0] > 2.0            # the box's move did grow the bounds
    assert reports.of("ERROR") == []


def test_kept_scene_is_freed_after_the_job(addon, tmp_path):
    """Without Persistent Data the kept scene is freed when the render ends;
    with it, the next render starts from it."""
    import bpy
    scene = fresh(16, 16, samples=1)
    world((0.5, 0.5, 0.5))
    add_mesh("Floor", *rect(-2, 2, -2, 2))
    camera(location=(0, 0, 5), type="ORTHO", ortho_scale=4.0)
    scene.render.image_settings.file_format = "OPEN_EXR"
    stream = addon.restir_addon.state.stream_for(scene.name, bpy.context.view_layer.name)
    for persistent in (False, True):
        scene.render.use_persistent_data = persistent
        scene.render.filepath = str(tmp_path / f"still{int(persistent)}.exr")
        bpy.ops.render.render(write_still=True)
        assert (stream.frame_scene.scene is not None) == persistent
    full = stream.frame_scene.work.full_exports
    bpy.ops.render.render(write_still=True)
    assert stream.frame_scene.work.full_exports == full
    assert glob.glob(str(tmp_path / "still*.exr")) and os.path.isfile(tmp_path / "still1.exr")


def test_too_many_instances_stop_with_a_clear_report(addon, reports, tmp_path):
    """10,000 instances of a 10k-triangle object (100M triangles once placed)
    on a 24 GB machine: refused before anything is placed, with the numbers,
    and a valid black image."""
    import bpy
    scene = fresh(16, 16, samples=1)
    world((0.5, 0.5, 0.5))
    camera(location=(0, 0, 50), type="ORTHO", ortho_scale=40.0)
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=71, y_subdivisions=71, size=0.3)
    child = bpy.context.object                              # 70 x 70 quads: 9,800 triangles
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=100, y_subdivisions=100, size=30)
    parent = bpy.context.object                             # 10,000 vertices
    parent.instance_type = "VERTS"
    child.parent = parent
    stream = addon.restir_addon.state.stream_for(scene.name, bpy.context.view_layer.name)
    stream.frame_scene.release()
    stream.frame_scene._available_memory = 24 * 1024 ** 3
    scene.render.image_settings.file_format = "OPEN_EXR"
    try:
        with pytest.raises(RuntimeError):           # bpy raises on an ERROR report
            render_still(scene, tmp_path / "many.exr")
    finally:
        stream.frame_scene._available_memory = None
    errors = reports.of("ERROR")
    assert len(errors) == 1 and "GB" in errors[0], errors
    triangles = int(re.search(r"has ([\d,]+) triangles", errors[0]).group(1).replace(",", ""))
    assert triangles > 90_000_000, errors
    assert stream.frame_scene.scene is None


def render_still(scene, path):
    import bpy
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)


def test_placed_face_normals_follow_any_matrix(addon, rng):
    """Face normals placed from the object-space ones (rotation, non-uniform
    scale, mirror) equal those computed from the placed triangles."""
    from restir_gi.restir_addon.export.mesh import MeshData
    from restir_gi.restir_addon.sync.objects import _clean_mesh, _face_normals, Instance, placed_instance
    n = 200
    pos = rng.normal(size=(n * 3, 3)).astype(np.float32)
    tris = np.arange(n * 3, dtype=np.int32).reshape(-1, 3)
    mesh = _clean_mesh(MeshData(pos, tris, np.zeros((n, 3, 3), np.float32), np.zeros((n, 3, 2), np.float32),
                                np.zeros(n, np.int32)))
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    for scale in ((1, 1, 1), (2.0, 0.5, 3.0), (-1.0, 1.0, 1.0)):
        m = np.eye(4)
        m[:3, :3] = q @ np.diag(scale)
        m[:3, 3] = rng.normal(size=3)
        placed, _, fn, tris, _ = placed_instance(Instance(mesh, m, np.zeros(1, np.int32)))
        np.testing.assert_allclose(fn, _face_normals(placed, tris), atol=2e-4)
