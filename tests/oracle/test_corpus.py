"""The benchmark corpus (example_blends/corpus_*.blend, made by
example_blends/make_corpus.py, rendered by bench/equal_time.py): each file has
the settings the benchmark relies on, a camera move and nothing else moving
(but the movers' box),
and exports without warnings to a scene with triangles and light. No renders.
"""

import math

import numpy as np
import pytest

from support.blender_util import EXAMPLES

FRAMES = 32
# Scene name -> light types the file must have (exactly these, sorted).
CORPUS = {
    "room": ["SUN"],
    "movers": ["SUN"],
    "slit": ["SUN"],
    "glossy": ["AREA", "SUN"],
    "courtyard": ["SUN"],
    "emitters": [],
}


def open_corpus(name):
    import bpy
    path = EXAMPLES / f"corpus_{name}.blend"
    assert path.is_file(), f"{path.name} is missing: run example_blends/make_corpus.py"
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
    return bpy.context.scene


def camera_pose(scene, frame):
    scene.frame_set(frame)
    m = np.array(scene.camera.matrix_world, float)
    return m[:3, 3].copy(), m[:3, :3].copy()


@pytest.mark.parametrize("name", sorted(CORPUS))
def test_corpus_settings(addon, name):
    scene = open_corpus(name)
    r = scene.render
    assert (r.resolution_x, r.resolution_y, r.resolution_percentage) == (320, 180, 100)
    assert (scene.frame_start, scene.frame_end) == (1, FRAMES)
    # Blender's default pixel filter.
    assert r.filter_size == pytest.approx(1.5)
    assert scene.cycles.pixel_filter_type == "BLACKMAN_HARRIS"
    # Cycles: default bounce limits, but unbiased and without denoising or adaptive stop.
    c = scene.cycles
    assert (c.max_bounces, c.diffuse_bounces, c.glossy_bounces) == (12, 4, 4)
    assert c.sample_clamp_indirect == 0.0 and c.sample_clamp_direct == 0.0
    assert c.blur_glossy == 0.0
    assert not c.use_denoising and not c.use_adaptive_sampling
    # The engine's settings.
    s = scene.restir_gi
    assert s.mode == "RESTIR_BIASED"
    # The engine's bounce limits are Cycles' (the references are Cycles').
    assert (s.max_bounces, s.diffuse_bounces, s.glossy_bounces, s.transmission_bounces) == \
        (c.max_bounces, c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces)
    assert s.warmup_frames == 16


@pytest.mark.parametrize("name", sorted(CORPUS))
def test_corpus_camera_moves_and_nothing_else(addon, name):
    import bpy
    scene = open_corpus(name)
    assert scene.camera is not None
    animated = sorted(ob.name for ob in bpy.data.objects if ob.animation_data is not None)
    assert animated == sorted([scene.camera.name] + (["MovingBox"] if name == "movers" else []))
    action = scene.camera.animation_data.action
    assert action is not None
    assert tuple(action.frame_range) == (1.0, float(FRAMES))
    loc1, rot1 = camera_pose(scene, 1)
    loc_mid, _ = camera_pose(scene, FRAMES // 2)
    loc2, rot2 = camera_pose(scene, FRAMES)
    # A dolly of 20-40 cm and a pan of a few degrees, linear in time.
    assert 0.2 <= np.linalg.norm(loc2 - loc1) <= 0.4
    turn = math.degrees(math.acos(np.clip((np.trace(rot1.T @ rot2) - 1) / 2, -1, 1)))
    assert 1.0 <= turn <= 8.0
    halfway = loc1 + (loc2 - loc1) * (FRAMES // 2 - 1) / (FRAMES - 1)
    assert np.allclose(loc_mid, halfway, atol=1e-4)


@pytest.mark.parametrize("name", sorted(CORPUS))
def test_corpus_exports_with_light(addon, name):
    import bpy
    from restir_gi.restir_addon.export import export_scene
    open_corpus(name)
    core_scene, has_camera = export_scene(bpy.context.evaluated_depsgraph_get(), 320, 180)
    assert has_camera
    # Only what the engine supports: nothing approximated.
    assert core_scene.warnings == []
    assert core_scene.triangle_count > 0
    from restir_gi.core.materials.shading import triangle_emission
    emissive = triangle_emission(core_scene).any(axis=1)
    lights = sorted(bpy.data.objects[n].data.type for n in core_scene.lights.names)
    assert lights == CORPUS[name]
    world = core_scene.environment
    assert len(core_scene.lights.names) or world is not None or emissive.any()
    if name == "emitters":
        # Lit only by its small emissive boxes (12 triangles each), black world.
        assert world is None
        assert 20 <= emissive.sum() // 12 <= 40
    if name == "courtyard":
        assert world.constant.max() > 0.5     # a bright open sky
