"""Animations through Blender's render operator: one file per frame, the
export's warnings once per animation, camera cuts (markers, or a camera
that jumps) restarting reuse (helpers and the ``reports`` fixture:
addon_util.py)."""

import glob
import math
import os

import numpy as np
import pytest

from support.addon_util import MODES, add_mesh, assert_valid, camera, emission, fresh, rect, world
from restir_gi.core.camera.film import read_exr


@pytest.mark.parametrize("mode", MODES)
def test_animation_writes_one_file_per_frame(addon, reports, tmp_path, mode):
    import bpy
    scene = fresh(32, 16, samples=2, mode=mode)
    scene.restir_gi.warmup_frames = 2
    camera(location=(0, 0, 5), type="ORTHO", ortho_scale=4.0)
    world((0, 0, 0))
    glow = add_mesh("Glow", *rect(-0.25, 0.25, -0.25, 0.25), mat=emission("Glow", 2.0))
    for frame, x in ((1, -1.2), (2, 0.0), (3, 1.2)):
        glow.location = (x, 0, 0)
        glow.keyframe_insert("location", frame=frame)
    # Out of view behind the camera, with a node the engine does not render:
    # the animation names it once, not with every frame.
    toon = bpy.data.materials.new("Cartoon")
    tree = toon.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    tree.links.new(tree.nodes.new("ShaderNodeBsdfToon").outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    add_mesh("Toon", *rect(-0.1, 0.1, -0.1, 0.1, z=9.0), mat=toon)
    scene.frame_start, scene.frame_end = 1, 3
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    scene.render.filepath = str(tmp_path / "frame_####")
    bpy.ops.render.render(animation=True)
    assert len([m for m in reports.of("WARNING") if "Toon BSDF" in m]) == 1, reports.log

    files = sorted(glob.glob(str(tmp_path / "frame_*.exr")))
    assert [os.path.basename(f) for f in files] == ["frame_0001.exr", "frame_0002.exr",
                                                     "frame_0003.exr"]
    centres = []
    for f in files:
        img = read_exr(f)
        assert_valid(img, (16, 32))
        lum = img.sum(axis=2)
        assert lum.sum() > 0
        centres.append(float((lum.sum(axis=0) * np.arange(32)).sum() / lum.sum()))
    # 4 m across 32 px: the emitter moves 1.2 m = 9.6 px per frame, left to right.
    np.testing.assert_allclose(np.diff(centres), [9.6, 9.6], atol=1.0)
    assert reports.of("ERROR") == []


def test_frame_step_continues_reuse(addon, reports, tmp_path):
    """With a Frame Step of 2 each written frame continues from the one
    written before it (one frame of resampling, no warm-up of the frames
    between), and the files are those of every second frame."""
    import bpy
    scene = fresh(16, 16, samples=1, mode="RESTIR_BIASED")
    scene.restir_gi.warmup_frames = 3
    world((0.5, 0.5, 0.5))
    add_mesh("Floor", *rect(-2, 2, -2, 2))
    cam = camera(location=(0, 0, 5), type="ORTHO", ortho_scale=4.0)
    for frame, x in ((1, 0.0), (7, 0.3)):
        cam.location = (x, 0, 5)
        cam.keyframe_insert("location", frame=frame)
    scene.frame_start, scene.frame_end, scene.frame_step = 1, 7, 2
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(tmp_path / "frame_####")
    stream = addon.restir_addon.state.stream_for(scene.name, bpy.context.view_layer.name)
    stream.restir.reset()
    bpy.ops.render.render(animation=True)
    files = sorted(os.path.basename(f) for f in glob.glob(str(tmp_path / "frame_*.exr")))
    assert files == ["frame_0001.exr", "frame_0003.exr", "frame_0005.exr", "frame_0007.exr"]
    for f in files:
        assert_valid(read_exr(str(tmp_path / f)), (16, 16))
    # Frame 1: 3 warm-up frames; 3, 5 and 7: one each.
    assert stream.last_frame == 7 and stream.restir.frames == 3 + 3
    assert reports.of("ERROR") == []


def test_camera_cut_restarts_reuse(addon, reports, tmp_path):
    """A marker switching to another camera resets the reservoirs (and warms
    up again); the frames after the cut continue from it."""
    import bpy
    scene = fresh(16, 16, samples=1, mode="RESTIR_BIASED")
    scene.restir_gi.warmup_frames = 3
    world((0.5, 0.5, 0.5))
    add_mesh("Floor", *rect(-2, 2, -2, 2))
    cam_a = camera(location=(0, 0, 5), type="ORTHO", ortho_scale=4.0)
    cam_b = camera(location=(0.5, 0, 5), type="ORTHO", ortho_scale=4.0)
    scene.camera = cam_a
    scene.timeline_markers.new("A", frame=1).camera = cam_a
    scene.timeline_markers.new("B", frame=3).camera = cam_b
    scene.frame_start, scene.frame_end = 1, 4
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(tmp_path / "frame_####")
    stream = addon.restir_addon.state.stream_for(scene.name, bpy.context.view_layer.name)
    stream.restir.reset()
    bpy.ops.render.render(animation=True)
    # Frames 1-2 (camera A): 3 warm-up + 1; the cut at 3 resets: 3 + 1 since.
    assert stream.last_frame == 4 and stream.last_camera == cam_b.name
    assert stream.restir.frames == 3 + 1
    assert reports.of("ERROR") == []

    bpy.context.scene.timeline_markers.clear()          # one camera throughout: no reset
    stream.restir.reset()
    bpy.ops.render.render(animation=True)
    assert stream.restir.frames == 3 + 3

    # One camera cut to another view by its keyframes (a jump of 40 degrees
    # from frame 2 to 3) is a cut too; a small move is not.
    scene.camera = cam_a
    for frame, angle in ((1, 0.0), (2, 0.0), (3, 40.0)):
        cam_a.rotation_euler = (math.radians(angle), 0, 0)
        cam_a.keyframe_insert("rotation_euler", frame=frame)
    stream.restir.reset()
    bpy.ops.render.render(animation=True)
    assert stream.restir.frames == 3 + 1
    from restir_gi.restir_addon.final import jumped
    from restir_gi.core import Camera
    a = Camera()
    b = Camera(to_world=np.array(a.to_world, np.float32).copy(), lens=60.0)
    b.to_world[0, 3] += 0.1
    assert not jumped(a, b, 10.0) and jumped(a, b, 0.1) and jumped(a, Camera(lens=120.0), 10.0)
