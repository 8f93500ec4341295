"""The engine through Blender's own render operator: passes written to EXR,
bad input that must still give a valid image and a clear report, cancel,
render regions (helpers and the ``reports`` fixture: addon_util.py;
animations: test_addon_animation.py).

Blender itself refuses to start a render without a camera, so the engine's own
no-camera guard is driven directly with a stand-in engine.
"""

import time

import numpy as np
import pytest

from support.addon_util import (MODES, FakeEngine, add_mesh, assert_valid, camera, emission, fresh,
                        lit_plane_scene, read_passes, rect, render_exr, world)
from support.blender_util import diffuse_material
from restir_gi.core.camera.film import read_exr


# ---------------------------------------------------------------- passes

@pytest.mark.parametrize("mode", MODES)
def test_passes_hold_depth_normal_albedo(addon, tmp_path, mode):
    scene = fresh(32, 32, samples=8, mode=mode)
    scene.restir_gi.warmup_frames = 4
    camera(location=(0, 0, 5))
    world((0.5, 0.5, 0.5))
    # The plane covers the left half of the view; the right half sees the world.
    add_mesh("Plane", *rect(-5, 0, -5, 5, z=1.0), mat=diffuse_material("Orange", (0.6, 0.3, 0.1)))
    path = tmp_path / "passes.exr"
    render_exr(scene, path, multilayer=True)
    p = read_passes(path)

    assert {"Combined", "Depth", "Normal", "Denoising Albedo"} <= set(p)
    for name, img in p.items():
        assert img.shape[:2] == (32, 32), name
        assert np.isfinite(img).all(), name
    left, right = np.s_[:, 2:13], np.s_[:, 19:30]     # away from the edge the filter blurs
    # Depth: distance along the view axis, 5 - 1 = 4 m to the plane.
    np.testing.assert_allclose(p["Depth"][left][..., 0], 4.0, rtol=1e-4)
    assert (p["Depth"][right] > 1e9).all()
    np.testing.assert_allclose(p["Normal"][left], np.broadcast_to([0, 0, 1], p["Normal"][left].shape),
                               atol=1e-5)
    np.testing.assert_allclose(p["Normal"][right], 0)
    np.testing.assert_allclose(p["Denoising Albedo"][left],
                               np.broadcast_to([0.6, 0.3, 0.1], p["Denoising Albedo"][left].shape),
                               atol=1e-5)
    np.testing.assert_allclose(p["Denoising Albedo"][right], 0)
    # Combined: the world seen directly, and albedo x world on the unoccluded plane.
    rgb = p["Combined"][..., :3]
    np.testing.assert_allclose(rgb[right], 0.5, rtol=1e-5)
    np.testing.assert_allclose(rgb[left].reshape(-1, 3).mean(axis=0), [0.3, 0.15, 0.05], rtol=0.03)
    np.testing.assert_allclose(p["Combined"][..., 3], 1.0)
    np.testing.assert_allclose(read_exr(path), rgb)


# ---------------------------------------------------------------- bad input

def test_resampling_panel_settings_reach_the_renderer(addon):
    """What the Resampling panel sets is what ReSTIR GI renders with."""
    scene = fresh(mode="RESTIR_UNBIASED")
    s = scene.restir_gi
    s.light_samples, s.sky_samples, s.spatial_neighbors, s.boiling_filter = 7, 0, 3, 0.5
    settings = addon.restir_addon.final.restir_settings(scene)
    assert (settings.light_samples, settings.sky_samples, settings.spatial_neighbors) == (7, 0, 3)
    assert settings.boiling_filter == pytest.approx(0.5) and settings.mode == "RESTIR_UNBIASED"
    s.sky_samples = 8
    assert addon.restir_addon.final.restir_settings(scene).sky_samples == 8


@pytest.mark.parametrize("mode", MODES)
def test_empty_scene_renders_black(addon, reports, tmp_path, mode):
    scene = fresh(mode=mode)
    camera()                     # Blender refuses to render without one (next test)
    render_exr(scene, tmp_path / "empty.exr")
    img = read_exr(tmp_path / "empty.exr")
    assert_valid(img, (32, 32))
    assert (img == 0).all()
    assert any("no geometry" in m for m in reports.of("WARNING")), reports.log
    assert reports.of("ERROR") == []


def test_no_camera_is_refused_with_a_clear_error(addon, tmp_path):
    import bpy
    scene = fresh()
    add_mesh("Plane", *rect(-1, 1, -1, 1))
    scene.render.filepath = str(tmp_path / "nocam.exr")
    with pytest.raises(RuntimeError, match="no camera"):
        bpy.ops.render.render(write_still=True)


def test_engine_without_camera_reports_error_and_black(addon):
    """The engine's own guard (the render operator stops earlier, see above)."""
    import bpy
    fresh(16, 8)
    world((1, 1, 1))
    add_mesh("Plane", *rect(-1, 1, -1, 1))
    engine = FakeEngine(["Combined", "Depth", "Normal", "Denoising Albedo"])
    addon.restir_addon.final.render(engine, bpy.context.evaluated_depsgraph_get())
    assert engine.ended
    errors = [m for k, m in engine.log if k == "ERROR"]
    assert len(errors) == 1 and "camera" in errors[0]
    combined = engine.pixels["Combined"].reshape(8, 16, 4)
    assert np.isfinite(combined).all() and (combined[..., :3] == 0).all()


@pytest.mark.parametrize("mode", MODES)
def test_no_lights_black_world_renders_black(addon, reports, tmp_path, mode):
    """No light source, or only a lamp of no power: black, and it says why."""
    import bpy
    scene = fresh(mode=mode)
    camera()
    world((0, 0, 0))
    add_mesh("Plane", *rect(-5, 5, -5, 5), mat=diffuse_material("White", (0.8, 0.8, 0.8)))
    if mode != "PATH":
        lamp = bpy.data.objects.new("Off", bpy.data.lights.new("Off", "POINT"))
        lamp.data.energy = 0.0
        lamp.location = (0, 0, 2)
        scene.collection.objects.link(lamp)
    render_exr(scene, tmp_path / "dark.exr")
    img = read_exr(tmp_path / "dark.exr")
    assert_valid(img, (32, 32))
    assert (img == 0).all()
    assert any("no light source" in m for m in reports.of("WARNING")), reports.log
    assert reports.of("ERROR") == []


@pytest.mark.parametrize("source", ["light", "emitter", "world"])
def test_any_light_source_silences_the_no_light_warning(addon, reports, tmp_path, source):
    import bpy
    scene = fresh(8, 8, samples=1)
    camera()
    world((0.2, 0.2, 0.2) if source == "world" else (0, 0, 0))
    add_mesh("Plane", *rect(-5, 5, -5, 5), mat=diffuse_material("White", (0.8, 0.8, 0.8)))
    if source == "light":
        lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
        lamp.location = (0, 0, 2)
        scene.collection.objects.link(lamp)
    elif source == "emitter":
        add_mesh("Glow", *rect(-1, 1, -1, 1, z=2.0), mat=emission("Glow", 1.0))
    render_exr(scene, tmp_path / "lit.exr")
    assert read_exr(tmp_path / "lit.exr").mean() > 0
    assert reports.of("WARNING") == [] and reports.of("ERROR") == []


@pytest.mark.parametrize("mode", MODES)
def test_nan_and_degenerate_triangles(addon, reports, tmp_path, mode):
    scene = lit_plane_scene(mode=mode)
    nan = float("nan")
    verts = [[0, 0, 1], [1, 0, 1], [nan, 0.5, 1],         # a NaN corner
             [0, 0, 2], [1, 1, 2], [2, 2, 2],             # collinear: zero area
             [0, 1, 1.5], [0, 1, 1.5], [1, 1, 1.5]]       # repeated point: zero area
    add_mesh("Broken", verts, [[0, 1, 2], [3, 4, 5], [6, 7, 8]])
    render_exr(scene, tmp_path / "broken.exr")
    img = read_exr(tmp_path / "broken.exr")
    assert_valid(img, (32, 32))
    # The rest of the scene still renders as it does without the broken mesh.
    np.testing.assert_allclose(img.reshape(-1, 3).mean(axis=0), [0.3, 0.15, 0.05], rtol=0.05)
    warnings = reports.of("WARNING")
    assert any("Skipped 1 " in m and "non-finite" in m for m in warnings), warnings
    assert any("Skipped 2 " in m and "degenerate" in m for m in warnings), warnings
    assert reports.of("ERROR") == []


def test_unsupported_node_reported(addon, reports, tmp_path):
    import bpy
    scene = lit_plane_scene()
    mat = bpy.data.materials.new("Cartoon")
    tree = mat.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    toon = tree.nodes.new("ShaderNodeBsdfToon")
    tree.links.new(toon.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    add_mesh("Toon", *rect(-1, 1, -1, 1, z=1.0), mat=mat)
    render_exr(scene, tmp_path / "toon.exr")
    img = read_exr(tmp_path / "toon.exr")
    assert_valid(img, (32, 32))
    assert img.mean() > 0.05
    naming = [m for m in reports.of("WARNING") if "Toon BSDF" in m]
    assert len(naming) == 1 and "Cartoon" in naming[0], reports.log


def test_what_is_not_rendered_is_reported(addon, reports, tmp_path):
    """A volume object without a file, displacement and shadow catchers each
    say they are not rendered; the render goes on (an empty point cloud, hair curves with all
    points at one place, particle hair, a plane with a volume material and
    motion blur, which Path Tracing renders whole, are there too: they
    render without a warning). (Holdout objects and collections are
    rendered: tests/addon/test_addon_film.py; Indirect Only collections:
    tests/oracle/test_light_paths_vs_cycles.py.)"""
    import bpy
    scene = lit_plane_scene()
    hair = bpy.data.hair_curves.new("Fur")
    hair.add_curves([4, 4])
    for name, data in (("Smoke", bpy.data.volumes.new("Smoke")), ("Dots", bpy.data.pointclouds.new("Dots")),
                       ("Fur", hair)):
        scene.collection.objects.link(bpy.data.objects.new(name, data))
    furry = add_mesh("Furry", *rect(-1, 1, -1, 1, z=0.5))
    furry.modifiers.new("hair", "PARTICLE_SYSTEM").particle_system.settings.type = "HAIR"
    mat = bpy.data.materials.new("Fog")
    tree = mat.node_tree
    out = tree.nodes["Material Output"]
    tree.links.new(tree.nodes.new("ShaderNodeVolumePrincipled").outputs[0], out.inputs["Volume"])
    tree.links.new(tree.nodes.new("ShaderNodeDisplacement").outputs[0], out.inputs["Displacement"])
    add_mesh("Foggy", *rect(-1, 1, -1, 1, z=1.0), mat=mat)
    add_mesh("Catcher", *rect(-1, 1, -1, 1, z=0.2)).is_shadow_catcher = True
    scene.render.use_motion_blur = True
    render_exr(scene, tmp_path / "what.exr")
    warnings = reports.of("WARNING")
    for text in ("'Smoke': no volume file",
                 "'Fog': displacement", "'Catcher': shadow catcher"):
        assert any(text in w for w in warnings), (text, reports.log)
    assert not any("Motion blur" in w for w in warnings), reports.log
    img = read_exr(tmp_path / "what.exr")
    assert_valid(img, (32, 32))
    assert img.mean() > 0.05
    assert reports.of("ERROR") == []


def test_volume_only_material_is_fog(addon, reports, tmp_path):
    """A fog box around the scene (a material with only a Volume) has no
    surface in Cycles: its boundary lets light through and the medium inside
    dims and scatters it (tests/oracle/test_volumes.py compares media with Cycles).
    Rendered, not a black box: darker than the clear scene but lit."""
    import bpy
    scene = lit_plane_scene()
    render_exr(scene, tmp_path / "clear.exr")
    mat = bpy.data.materials.new("Fog")
    tree = mat.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    fog = tree.nodes.new("ShaderNodeVolumePrincipled")
    fog.inputs["Density"].default_value = 0.05
    tree.links.new(fog.outputs[0], tree.nodes["Material Output"].inputs["Volume"])
    corners = [(x, y, z) for x in (-8, 8) for y in (-8, 8) for z in (-8, 8)]
    faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    add_mesh("FogBox", corners, faces, mat=mat)
    render_exr(scene, tmp_path / "fog.exr")
    clear, fog = read_exr(tmp_path / "clear.exr"), read_exr(tmp_path / "fog.exr")
    assert_valid(fog, (32, 32))
    assert 0.05 * clear.mean() < fog.mean() < clear.mean()
    assert not any("volume" in w for w in reports.of("WARNING")), reports.log


def test_fixed_problems_are_not_reported_again(addon, reports, tmp_path):
    """A warning belongs to the render that found it: once the user fixed what
    it was about (a shadow catcher made an ordinary object), the next render
    is silent."""
    scene = lit_plane_scene()
    catcher = add_mesh("Catcher", *rect(-1, 1, -1, 1, z=0.5))
    catcher.is_shadow_catcher = True
    render_exr(scene, tmp_path / "before.exr")
    assert any("'Catcher': shadow catcher" in w for w in reports.of("WARNING")), reports.log
    catcher.is_shadow_catcher = False
    reports.log.clear()
    render_exr(scene, tmp_path / "after.exr")
    assert not any("shadow catcher" in w for w in reports.of("WARNING")), reports.log


@pytest.mark.parametrize("mode", ["PATH", "RESTIR_BIASED"])
def test_stereo_views(addon, reports, tmp_path, mode):
    """Stereo 3D renders each eye from Blender's stereo rig (the left eye is
    the camera itself with the default pivot); ReSTIR keeps reservoirs per
    eye, and an animation continues both. The right eye against Cycles' is
    in test_vs_cycles.py."""
    import bpy
    scene = fresh(32, 16, samples=4, mode=mode)
    scene.restir_gi.warmup_frames = 2
    camera(location=(0, 0, 5), type="PERSP")
    world((0, 0, 0))
    glow = add_mesh("Glow", *rect(-0.5, 0.5, -0.5, 0.5), mat=emission("Glow", 2.0))
    glow.location = (0, 0, 0)
    scene.render.use_multiview = True
    scene.render.views_format = "STEREO_3D"
    scene.camera.data.stereo.interocular_distance = 0.5
    scene.camera.data.stereo.convergence_distance = 100.0   # nearly parallel: the eye moves the image
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth = "OPEN_EXR", "32"
    scene.frame_start, scene.frame_end = 1, 2
    scene.render.filepath = str(tmp_path / "eye_####")
    bpy.ops.render.render(animation=True)      # one file per view and frame: eye_0001_L.exr, ...
    assert reports.of("ERROR") == []
    for frame in (1, 2):
        left, right = (read_exr(tmp_path / f"eye_{frame:04d}_{v}.exr") for v in "LR")
        assert_valid(left, (16, 32))
        assert_valid(right, (16, 32))

        def centre(img):
            lum = img.sum(axis=2)
            return float((lum.sum(axis=0) * np.arange(32)).sum() / lum.sum())
        assert left.mean() > 0.01 and right.mean() > 0.01
        assert centre(right) < centre(left) - 0.5     # the right eye sees the quad further left
    if mode != "PATH":
        streams = addon.restir_addon.state
        assert streams.stream_for(scene.name, bpy.context.view_layer.name, "right").last_frame == 2


# ---------------------------------------------------------------- cancel

@pytest.mark.parametrize("mode", ["PATH", "RESTIR_BIASED"])
def test_cancel_stops_early_with_partial_image(addon, reports, tmp_path, mode):
    # 400 samples (path tracing: a 64x64 image traces 16 samples to a batch,
    # and a cancel is seen between batches) or 400 warm-up frames of 2
    # samples (ReSTIR GI: between frames)
    from restir_gi.core.render import samples_per_pass
    done = samples_per_pass(64 * 64, 400) if mode == "PATH" else 1
    scene = lit_plane_scene(64, 64, samples=400 if mode == "PATH" else 2, mode=mode)
    scene.restir_gi.warmup_frames = 400
    progress, asked, ended = [], [], []

    def test_break():
        if progress:                  # a sample (or ReSTIR warm-up frame) is done: cancel
            asked.append(time.perf_counter())
            return True
        return False

    reports.options.update(test_break=test_break, on_progress=progress.append,
                           on_end=lambda: ended.append(time.perf_counter()))
    render_exr(scene, tmp_path / "cancel.exr")
    img = read_exr(tmp_path / "cancel.exr")

    assert asked and ended
    assert ended[0] - asked[0] < 1.0, f"took {ended[0] - asked[0]:.2f} s to stop"
    assert len(progress) == done, progress
    assert_valid(img, (64, 64))
    assert img.mean() > 0.05            # the samples of a lit plane, not black
    info = [m for m in reports.of("INFO") if "cancel" in m.lower()]
    assert len(info) == 1, reports.log
    assert f"{done} of 400" in info[0]


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["PATH", "RESTIR_BIASED"])
def test_render_region(addon, reports, mode):
    """Output > Render Region: Blender's result is the region's size; the
    region renders as an image of its own (the same pixels as that part of
    the whole image, up to noise), cropped or placed in the full frame."""
    from support.blender_util import open_example, render_image, set_resolution, setup_restir
    scene = open_example("cornell_box.blend")
    set_resolution(scene, 48, 40)
    setup_restir(scene, 64, 1, 4, mode)
    scene.restir_gi.warmup_frames = 32
    full = render_image(scene)
    r = scene.render
    r.use_border = True
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.25, 0.75, 0.5, 1.0
    r.use_crop_to_border = True
    cropped = render_image(scene)
    r.use_crop_to_border = False
    placed = render_image(scene)
    assert_valid(cropped, (20, 24))
    assert_valid(placed, (40, 48))
    assert reports.of("ERROR") == []
    part = full[20:40, 12:36]
    np.testing.assert_array_equal(placed[20:40, 12:36], cropped)
    outside = np.ones((40, 48), bool)
    outside[20:40, 12:36] = False
    assert not placed[outside].any()
    # The same picture: 4x4-pixel block means agree up to the noise.
    def blocks(img):
        return img.reshape(5, 4, 6, 4, 3).mean(axis=(1, 3))
    assert abs(cropped.mean() / part.mean() - 1) < 0.03
    assert np.abs(blocks(cropped) - blocks(part)).mean() < 0.1 * part.mean()
    shifted = np.roll(part, 2, axis=1)     # two pixels off: clearly another picture (0.36)
    assert np.abs(blocks(shifted) - blocks(part)).mean() > 0.2 * part.mean()
