"""Motion blur (core/camera/motion.py, core/object_motion.py,
restir_addon/motion_blur.py) against Cycles, in Path Tracing, and bad input:
a moving camera, and a moving object under a still camera.

The scene: a box of coloured bars seen by a camera that turns 12 degrees and
moves sideways between frames 1 and 2 (linear keyframes), shutter 0.5 around
frame 1.5: the bars blur into streaks. Mean within 2 % and block chi < 2.5;
the same render without motion blur is far from Cycles' blurred one.
"""

import math

import numpy as np
import pytest

SAMPLES = 64
BOUNCES = 2


def _scene(width=64, height=48, shutter=0.5, position="CENTER"):
    import bpy
    from support.addon_util import add_mesh, camera, fresh, rect, world
    from support.blender_util import diffuse_material
    scene = fresh(width, height)
    world((0.3, 0.3, 0.3))
    add_mesh("Floor", *rect(-6, 6, -2, 8), mat=diffuse_material("Floor", (0.5, 0.5, 0.5)))
    colours = [(0.9, 0.1, 0.1), (0.1, 0.8, 0.1), (0.1, 0.2, 0.9), (0.9, 0.8, 0.1), (0.8, 0.2, 0.8)]
    for i, c in enumerate(colours):
        x = -2.0 + i
        add_mesh(f"Bar{i}", [(x, 3, 0), (x + 0.3, 3, 0), (x + 0.3, 3, 2.5), (x, 3, 2.5)], [[0, 1, 2, 3]],
                 mat=diffuse_material(f"Bar{i}", c))
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 3.0
    ob = bpy.data.objects.new("Sun", sun)
    ob.rotation_euler = (math.radians(30), 0, math.radians(20))
    scene.collection.objects.link(ob)
    cam = camera(location=(0, -3, 1.2), rotation=(math.radians(85), 0, 0), lens=35)
    for frame, (x, yaw) in ((1, (-0.2, 6.0)), (2, (0.2, -6.0))):
        cam.location.x, cam.rotation_euler.z = x, math.radians(yaw)
        cam.keyframe_insert("location", frame=frame)
        cam.keyframe_insert("rotation_euler", frame=frame)
    _linear(cam)
    scene.frame_set(1, subframe=0.5)
    scene.render.use_motion_blur = shutter is not None
    if shutter is not None:
        scene.render.motion_blur_shutter = shutter
        scene.render.motion_blur_position = position
    return scene


def _linear(ob):
    """Linear interpolation of every keyframe (layered actions of 4.4+ or not)."""
    action = ob.animation_data.action
    curves = getattr(action, "fcurves", None)
    if not curves:
        curves = [c for layer in action.layers for strip in layer.strips
                  for bag in strip.channelbags for c in bag.fcurves]
    for c in curves:
        for k in c.keyframe_points:
            k.interpolation = "LINEAR"


def _compare(scene, label):
    """Ours against Cycles at SAMPLES: finite, mean within 2 %, block chi < 2.5."""
    from support.blender_util import compare_with_cycles
    r = compare_with_cycles(scene, SAMPLES, BOUNCES, block=8)
    assert np.isfinite(r["ours"]).all()
    print(f"{label}: mean ours {r['ours_mean']:.4f} cycles {r['cycles_mean']:.4f} "
          f"ratio {r['ratio']:.4f} block chi {r['chi']:.2f}")
    assert abs(r["ratio"] - 1.0) < 0.02
    assert r["chi"] < 2.5


@pytest.mark.parametrize("position", ["CENTER", "START"])
def test_camera_motion_blur_matches_cycles(addon, position):
    _compare(_scene(position=position), f"motion blur ({position.lower()})")


def test_motion_blur_can_fail(addon):
    """Without the blur, ours is far from Cycles' blurred frame."""
    from support.blender_util import block_means, render_image, setup_cycles, setup_restir
    scene = _scene()
    setup_cycles(scene, SAMPLES, 1, BOUNCES)
    cycles = block_means(render_image(scene), 8)
    setup_restir(scene, SAMPLES, 1, BOUNCES)
    blurred = block_means(render_image(scene), 8)
    scene.render.use_motion_blur = False
    sharp = block_means(render_image(scene), 8)
    right, wrong = np.abs(blurred - cycles).mean(), np.abs(sharp - cycles).mean()
    print(f"block error against Cycles' blurred frame: blurred {right:.4f}, sharp {wrong:.4f}")
    assert wrong > 2.5 * right


def _moving_object_scene(width=64, height=48):
    """A still camera; a red box sliding 1.2 along x and turning 40 degrees
    over the frame (linear keyframes), shutter 0.5 around frame 1.5."""
    from support.addon_util import add_mesh
    from support.blender_util import diffuse_material
    scene = _scene(width, height, shutter=0.5)
    cam = scene.camera
    cam.animation_data_clear()
    cam.location, cam.rotation_euler = (0, -3, 1.2), (math.radians(85), 0, 0)
    corners = [(x, y, z) for x in (-0.3, 0.3) for y in (-0.3, 0.3) for z in (0.0, 0.6)]
    faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    box = add_mesh("Slider", corners, faces, mat=diffuse_material("Slider", (0.9, 0.2, 0.1)))
    for frame, (x, yaw) in ((1, (-0.6, -20.0)), (2, (0.6, 20.0))):
        box.location = (x, 1.0, 0.3)
        box.rotation_euler.z = math.radians(yaw)
        box.keyframe_insert("location", frame=frame)
        box.keyframe_insert("rotation_euler", frame=frame)
    _linear(box)
    scene.frame_set(1, subframe=0.5)
    return scene


def test_object_motion_blur_matches_cycles(addon):
    """A box sliding and turning over the shutter: each sample at its own
    time slice (core/object_motion.py) against Cycles' object motion."""
    _compare(_moving_object_scene(), "object motion blur")


def _deforming_scene(width=64, height=48, tilt=False):
    """A still camera; a red panel of 6 x 6 quads whose shape key shears its
    top 1.5 sideways over the frame (linear keyframes), or with ``tilt``
    leans it back about its bottom edge (its normals turn): deformation blur."""
    import bpy
    from support.addon_util import add_mesh
    from support.blender_util import diffuse_material
    scene = _scene(width, height, shutter=0.5)
    cam = scene.camera
    cam.animation_data_clear()
    cam.location, cam.rotation_euler = (0, -3, 1.2), (math.radians(85), 0, 0)
    n = 6
    verts = [(-0.8 + 1.2 * i / n, 1.0, 0.1 + 1.6 * j / n) for j in range(n + 1) for i in range(n + 1)]
    faces = [[j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1, (j + 1) * (n + 1) + i]
             for j in range(n) for i in range(n)]
    panel = add_mesh("Panel", verts, faces, mat=diffuse_material("Panel", (0.9, 0.2, 0.1)))
    panel.shape_key_add(name="Basis")
    sheared = panel.shape_key_add(name="Sheared")
    for k, v in enumerate(verts):
        lean = (v[2] - 0.1) / 1.6
        sheared.data[k].co = (v[0], v[1] + 1.2 * lean, v[2] - 0.5 * lean) if tilt else \
            (v[0] + 1.5 * lean, v[1], v[2])
    for frame, value in ((1, 0.0), (2, 1.0)):
        sheared.value = value
        sheared.keyframe_insert("value", frame=frame)
    _linear(panel.data.shape_keys)
    bpy.context.view_layer.update()
    scene.frame_set(1, subframe=0.5)
    return scene, panel


@pytest.mark.parametrize("tilt", [False, True])
def test_deformation_blur_matches_cycles(addon, tilt):
    """A shape key shearing or tilting a panel over the shutter: each time
    slice puts its triangles and their normals between the shutter's steps
    (core/object_motion.py)."""
    _compare(_deforming_scene(tilt=tilt)[0], f"deformation blur ({'tilt' if tilt else 'shear'})")


def test_deformation_blur_can_fail(addon):
    """With the object's Deformation blur off, ours is far from Cycles' blurred
    panel."""
    from support.blender_util import block_means, render_image, setup_cycles, setup_restir
    scene, panel = _deforming_scene()
    setup_cycles(scene, SAMPLES, 1, BOUNCES)
    cycles = block_means(render_image(scene), 8)
    setup_restir(scene, SAMPLES, 1, BOUNCES)
    right = np.abs(block_means(render_image(scene), 8) - cycles).mean()
    panel.cycles.use_deform_motion = False
    wrong = np.abs(block_means(render_image(scene), 8) - cycles).mean()
    print(f"block error against Cycles' blurred panel: blurred {right:.4f}, sharp {wrong:.4f}")
    assert wrong > 2.5 * right


def test_motion_blur_bad_input(addon, reports, tmp_path):
    """A zero shutter renders sharp, a ReSTIR mode says it blurs only the
    camera; never NaN, and the scene is left at its frame."""
    from support.addon_util import render_exr
    from restir_gi.core.camera.film import read_exr
    scene = _scene(32, 24, shutter=0.0)
    render_exr(scene, tmp_path / "zero.exr")
    assert np.isfinite(read_exr(tmp_path / "zero.exr")).all()
    assert (scene.frame_current, scene.frame_subframe) == (1, 0.5)
    scene.render.motion_blur_shutter = 0.5
    scene.restir_gi.mode = "RESTIR_BIASED"
    reports.log.clear()
    render_exr(scene, tmp_path / "restir.exr")
    assert np.isfinite(read_exr(tmp_path / "restir.exr")).all()
    assert any("the camera's motion only" in w for w in reports.of("WARNING")), reports.log
    assert reports.of("ERROR") == []
    assert (scene.frame_current, scene.frame_subframe) == (1, 0.5)


@pytest.mark.parametrize("mode", ["RESTIR_BIASED", "RESTIR_UNBIASED"])
def test_camera_motion_blur_in_restir_modes(addon, mode):
    """The ReSTIR modes blur the camera's motion too (each G-buffer ray at
    its own time; reuse follows the frame's camera): against Cycles' blurred
    frame, the blurred image is far closer than the sharp one, and its mean
    within the mode's own tolerance (3 %)."""
    from support.blender_util import block_means, render_image, setup_cycles, setup_restir
    scene = _scene()
    setup_cycles(scene, SAMPLES, 1, BOUNCES)
    cycles = block_means(render_image(scene), 8)
    setup_restir(scene, 1, 1, BOUNCES, mode=mode)
    scene.restir_gi.warmup_frames = 32
    blurred = block_means(render_image(scene), 8)
    scene.render.use_motion_blur = False
    sharp = block_means(render_image(scene), 8)
    right, wrong = np.abs(blurred - cycles).mean(), np.abs(sharp - cycles).mean()
    ratio = float(blurred.mean() / cycles.mean())
    print(f"{mode}: block error blurred {right:.4f}, sharp {wrong:.4f}, mean ratio {ratio:.4f}")
    assert np.isfinite(blurred).all()
    assert wrong > 2.0 * right
    assert abs(ratio - 1.0) < 0.03


def test_rigid_interpolation():
    """Matrices at the steps come back at the steps' times; halfway between
    two rotations is the rotation by half the angle; rows stay orthonormal."""
    from restir_gi.core.camera.motion import rigid_at

    def rz(a, t):
        m = np.eye(4)
        m[:2, :2] = [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]
        m[:3, 3] = t
        return m

    mats = np.stack([rz(0.0, (0, 0, 0)), rz(0.4, (1, 0, 0)), rz(0.8, (2, 2, 0))])
    r, t = rigid_at(mats, np.array([0.0, 0.25, 0.5, 1.0]))
    np.testing.assert_allclose(r[0], mats[0, :3, :3], atol=1e-9)
    np.testing.assert_allclose(r[1], rz(0.2, 0)[:3, :3], atol=1e-9)
    np.testing.assert_allclose(r[3], mats[2, :3, :3], atol=1e-9)
    np.testing.assert_allclose(t[1], (0.5, 0, 0), atol=1e-9)
    np.testing.assert_allclose(np.einsum("nij,nkj->nik", r, r), np.broadcast_to(np.eye(3), (4, 3, 3)), atol=1e-9)
    bad = rigid_at(np.zeros((3, 4, 4)), np.array([0.5]))
    assert np.isfinite(bad[0]).all() and np.isfinite(bad[1]).all()
