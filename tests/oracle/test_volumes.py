"""Homogeneous volumes (core/integrators/media.py, core/integrators/media_path.py,
restir_addon/export/volumes.py) against Cycles, in Path Tracing, and bad
input; the world's volume too.

Each scene: a box of medium (its material has only a Volume) on a lit floor
in front of a wall, a sun and a grey world; both engines at 64 spp with the
same bounce limits (Cycles' Light Paths > Volume, which the engine reads
too). Mean within 2 % and block chi < 2.5, as the node tests.
"""

import math

import numpy as np
import pytest

SAMPLES = 64
BOUNCES = 3


def _volume_material(name, kind, **inputs):
    import bpy
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    node = tree.nodes.new(kind)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    tree.links.new(node.outputs[0], tree.nodes["Material Output"].inputs["Volume"])
    return mat, node


def _box(name, lo, hi, mat):
    from support.addon_util import add_mesh
    corners = [(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    return add_mesh(name, corners, faces, mat=mat)


def _stage(width=64, height=48, volume_bounces=BOUNCES, camera_at=(0.0, -4.0, 1.2)):
    import bpy
    from support.addon_util import add_mesh, camera, fresh, rect, world
    from support.blender_util import diffuse_material
    scene = fresh(width, height)
    world((0.3, 0.32, 0.35))
    add_mesh("Floor", *rect(-4, 4, -4, 4), mat=diffuse_material("Floor", (0.6, 0.6, 0.6)))
    add_mesh("Wall", [(-4, 2, 0), (4, 2, 0), (4, 2, 4), (-4, 2, 4)], [[0, 1, 2, 3]],
             mat=diffuse_material("Wall", (0.2, 0.4, 0.7)))
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 3.0
    ob = bpy.data.objects.new("Sun", sun)
    ob.rotation_euler = (math.radians(40), 0.0, math.radians(30))
    scene.collection.objects.link(ob)
    camera(location=camera_at, rotation=(math.radians(80), 0, 0), lens=30)
    scene.cycles.volume_bounces = volume_bounces
    return scene


def _compare(scene, label, mean_tol=0.02, max_chi=2.5):
    from support.blender_util import compare_with_cycles
    r = compare_with_cycles(scene, SAMPLES, BOUNCES, block=8)
    assert np.isfinite(r["ours"]).all()
    print(f"{label}: mean ours {r['ours_mean']:.4f} cycles {r['cycles_mean']:.4f} "
          f"ratio {r['ratio']:.4f} block chi {r['chi']:.2f}")
    assert abs(r["ratio"] - 1.0) < mean_tol
    assert r["chi"] < max_chi
    return r


CASES = {
    "principled": ("ShaderNodeVolumePrincipled", dict(Density=1.2, Color=(0.9, 0.7, 0.5, 1), Anisotropy=0.3)),
    "scatter_back": ("ShaderNodeVolumeScatter", dict(Density=0.8, Color=(0.7, 0.8, 0.9, 1), Anisotropy=-0.4)),
    "absorption": ("ShaderNodeVolumeAbsorption", dict(Density=1.5, Color=(0.9, 0.3, 0.2, 1))),
    "principled_emission": ("ShaderNodeVolumePrincipled", {"Density": 0.5, "Emission Strength": 0.6,
                                                           "Emission Color": (1.0, 0.5, 0.2, 1)}),
    "principled_blackbody": ("ShaderNodeVolumePrincipled", {"Density": 0.5, "Blackbody Intensity": 1.0,
                                                            "Temperature": 1500.0,
                                                            "Blackbody Tint": (1.0, 0.8, 0.9, 1)}),
    "principled_absorption_color": ("ShaderNodeVolumePrincipled", {"Density": 1.5, "Color": (0.5, 0.5, 0.5, 1),
                                                                   "Absorption Color": (0.6, 0.1, 0.3, 1)}),
}


@pytest.mark.parametrize("case", list(CASES))
def test_volume_matches_cycles(addon, case):
    kind, inputs = CASES[case]
    scene = _stage()
    mat, _ = _volume_material(case, kind, **inputs)
    _box("Fog", (-1.0, -1.0, 0.02), (1.0, 1.0, 2.0), mat)
    _compare(scene, case)


def test_single_scattering_by_default(addon):
    """Cycles' default Volume bounces (0): light scatters once in the fog;
    the engine reads the same setting."""
    scene = _stage(volume_bounces=0)
    mat, _ = _volume_material("fog", "ShaderNodeVolumeScatter", Density=2.0)
    _box("Fog", (-1.0, -1.0, 0.02), (1.0, 1.0, 2.0), mat)
    _compare(scene, "single scattering")


def test_camera_inside_fog_and_overlap(addon):
    """The camera inside a fog box, a second box of absorption overlapping
    it: the media add up where they overlap."""
    scene = _stage(camera_at=(0.0, -2.5, 1.2))
    fog, _ = _volume_material("fog", "ShaderNodeVolumeScatter", Density=0.25, Anisotropy=0.2)
    _box("Fog", (-3.5, -3.5, 0.01), (3.5, 1.9, 3.0), fog)
    ink, _ = _volume_material("ink", "ShaderNodeVolumeAbsorption", Density=1.0, Color=(0.2, 0.6, 0.9, 1))
    _box("Ink", (-0.8, -0.8, 0.0), (0.8, 0.8, 1.6), ink)
    _compare(scene, "camera in fog, overlapping absorption")


def test_volume_in_restir_mode(addon, reports):
    """A ReSTIR mode renders a frame with volumes by path tracing (its
    warm-up frames as samples): the media are there, as in Cycles."""
    kind, inputs = CASES["principled"]
    scene = _stage()
    mat, _ = _volume_material("fog", kind, **inputs)
    _box("Fog", (-1.0, -1.0, 0.02), (1.0, 1.0, 2.0), mat)
    scene.restir_gi.warmup_frames = SAMPLES
    from support.blender_util import block_means, render_image, setup_cycles, setup_restir
    setup_cycles(scene, SAMPLES, 1, BOUNCES)
    cycles = render_image(scene)
    setup_restir(scene, SAMPLES, 1, BOUNCES, mode="RESTIR_BIASED")
    scene.restir_gi.samples = 1
    ours = render_image(scene)
    ratio = float(block_means(ours, 8).mean() / block_means(cycles, 8).mean())
    print(f"ReSTIR biased with a fog box: ratio {ratio:.4f}")
    assert abs(ratio - 1.0) < 0.02
    assert any("by Path Tracing" in w for w in reports.of("WARNING")), reports.log


def test_moved_volume_follows(addon):
    """A render after the fog box moved (the engine keeps its scene between
    renders and moves objects in place) has the medium where the box is now."""
    kind, inputs = CASES["principled"]
    scene = _stage()
    mat, _ = _volume_material("fog", kind, **inputs)
    box = _box("Fog", (-1.0, -1.0, 0.02), (1.0, 1.0, 2.0), mat)
    from support.blender_util import render_image, setup_restir
    setup_restir(scene, 4, 1, BOUNCES)
    render_image(scene)
    box.location.x = 1.5
    _compare(scene, "moved fog box")


def test_volume_can_fail(addon):
    """The comparison fails when the medium is off: twice the density here
    against Cycles' is far outside the tolerance."""
    from support.blender_util import block_error_after_change
    scene = _stage()
    mat, node = _volume_material("fog", "ShaderNodeVolumeScatter", Density=1.0)
    _box("Fog", (-1.0, -1.0, 0.02), (1.0, 1.0, 2.0), mat)
    error = block_error_after_change(scene, lambda: setattr(node.inputs["Density"], "default_value", 2.0),
                                     SAMPLES, BOUNCES)
    print(f"density x2: block error {error:.4f}")
    assert error > 0.01


def _noise_density(mat, node, scale=3.0):
    """Density = 4 x (Noise Texture's Fac - 0.45), on Generated coordinates."""
    tree = mat.node_tree
    noise = tree.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = scale
    noise.inputs["Detail"].default_value = 1.0
    sub = tree.nodes.new("ShaderNodeMath")
    sub.operation, sub.inputs[1].default_value = "SUBTRACT", 0.45
    mul = tree.nodes.new("ShaderNodeMath")
    mul.operation, mul.inputs[1].default_value = "MULTIPLY", 4.0
    tree.links.new(noise.outputs["Fac"], sub.inputs[0])
    tree.links.new(sub.outputs[0], mul.inputs[0])
    tree.links.new(mul.outputs[0], node.inputs["Density"])
    return noise


@pytest.mark.parametrize("shape", ["box", "sphere"])
def test_textured_density_matches_cycles(addon, shape):
    """A Noise Texture drives a Principled Volume's Density inside a box and
    inside a sphere (core/integrators/field_media.py: the texture on a
    lattice, inside the mesh): the clouds' shapes and shadows as Cycles'."""
    import bpy
    scene = _stage()
    mat, node = _volume_material("cloud", "ShaderNodeVolumePrincipled", Color=(0.8, 0.7, 0.6, 1))
    _noise_density(mat, node, scale=3.0 if shape == "box" else 5.0)
    if shape == "box":
        _box("Cloud", (-1.0, -1.0, 0.02), (1.0, 1.0, 2.0), mat)
    else:
        bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, location=(0, 0, 1.0), segments=32, ring_count=16)
        bpy.context.object.data.materials.append(mat)
    _compare(scene, f"textured density, {shape}")


def test_textured_density_can_fail(addon):
    """The comparison fails when the texture is off: a Noise Texture of
    scale 4 against Cycles' 3 moves the clouds: the block error is several
    times that of the same texture (the noise of the two renders)."""
    from support.blender_util import block_error_after_change
    scene = _stage()
    mat, node = _volume_material("cloud", "ShaderNodeVolumePrincipled")
    noise = _noise_density(mat, node)
    _box("Cloud", (-1.0, -1.0, 0.02), (1.0, 1.0, 2.0), mat)
    same, moved = block_error_after_change(
        scene, lambda: lambda: setattr(noise.inputs["Scale"], "default_value", 4.0), SAMPLES, BOUNCES)
    print(f"block error: same texture {same:.4f}, scale 4 for 3 {moved:.4f}")
    assert moved > 3 * same


def test_volume_bad_input(addon, reports, tmp_path):
    """An empty volume object, a volume of density zero, an open surface
    with a volume material, a textured colour and a density of 1 / 0 from
    a Math node: valid images, no NaN, warnings that name what is not
    rendered."""
    import bpy
    from support.addon_util import add_mesh, render_exr
    from restir_gi.core.camera.film import read_exr
    scene = _stage(32, 24)
    vol = bpy.data.objects.new("Smoke", bpy.data.volumes.new("Smoke"))
    scene.collection.objects.link(vol)
    empty, _ = _volume_material("empty", "ShaderNodeVolumePrincipled", Density=0.0)
    _box("Empty", (-1, -1, 0), (1, 1, 2), empty)
    sheet, _ = _volume_material("sheet", "ShaderNodeVolumeScatter", Density=3.0)
    add_mesh("Sheet", [(-1, -1.5, 0.5), (1, -1.5, 0.5), (1, -1.5, 1.5), (-1, -1.5, 1.5)], [[0, 1, 2, 3]],
             mat=sheet)
    tex, node = _volume_material("textured", "ShaderNodeVolumePrincipled")
    noise = tex.node_tree.nodes.new("ShaderNodeTexNoise")
    tex.node_tree.links.new(noise.outputs["Fac"], node.inputs["Color"])
    _box("Cloud", (1.5, -1, 0), (2.5, 0, 1), tex)
    inf, node = _volume_material("infinite", "ShaderNodeVolumeScatter")
    div = inf.node_tree.nodes.new("ShaderNodeMath")
    div.operation, div.inputs[0].default_value, div.inputs[1].default_value = "DIVIDE", 1.0, 0.0
    inf.node_tree.links.new(div.outputs[0], node.inputs["Density"])
    _box("Infinite", (-2.5, -1, 0), (-1.5, 0, 1), inf)
    for mode in ("PATH", "RESTIR_BIASED"):
        scene.restir_gi.mode = mode
        reports.log.clear()
        render_exr(scene, tmp_path / f"{mode}.exr")
        img = read_exr(tmp_path / f"{mode}.exr")
        assert np.isfinite(img).all() and img.mean() > 0
        warnings = reports.of("WARNING")
        assert reports.of("ERROR") == []
        assert any("'Smoke': no volume file" in w for w in warnings), reports.log
        assert any("heterogeneous" in w and "Color" in w for w in warnings), reports.log
        if mode != "PATH":
            assert any("by Path Tracing" in w for w in warnings), reports.log


def _world_volume(kind, **inputs):
    """Link a volume node to the scene's world output (Cycles' world volume)."""
    import bpy
    tree = bpy.context.scene.world.node_tree
    node = tree.nodes.new(kind)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    out = next(n for n in tree.nodes if n.type == "OUTPUT_WORLD")
    tree.links.new(node.outputs[0], out.inputs["Volume"])
    return node


def _lamp(location=(0.5, -1.0, 2.2), power=400.0):
    import bpy
    lamp = bpy.data.lights.new("Lamp", "POINT")
    lamp.energy = power
    lamp.shadow_soft_size = 0.1
    ob = bpy.data.objects.new("Lamp", lamp)
    ob.location = location
    bpy.context.scene.collection.objects.link(ob)
    return ob


WORLD_CASES = {
    "scatter": ("ShaderNodeVolumeScatter", dict(Density=0.12, Color=(0.8, 0.85, 0.9, 1), Anisotropy=0.3)),
    "principled_emission": ("ShaderNodeVolumePrincipled", {"Density": 0.1, "Emission Strength": 0.05,
                                                           "Emission Color": (1.0, 0.6, 0.3, 1)}),
}


@pytest.mark.parametrize("case", list(WORLD_CASES))
def test_world_volume_matches_cycles(addon, case):
    """Fog filling the world, lit by a point lamp: the sun and the sky are not
    seen through an infinite length of it (as in Cycles), the lamp's light
    is attenuated and scattered on its way."""
    kind, inputs = WORLD_CASES[case]
    scene = _stage()
    _lamp()
    _world_volume(kind, **inputs)
    _compare(scene, f"world {case}")


def test_world_volume_with_a_fog_box(addon):
    """The world's medium and a box's add up inside the box."""
    scene = _stage()
    _lamp()
    _world_volume("ShaderNodeVolumeScatter", Density=0.08)
    ink, _ = _volume_material("ink", "ShaderNodeVolumeAbsorption", Density=1.0, Color=(0.2, 0.6, 0.9, 1))
    _box("Ink", (-0.8, -0.8, 0.0), (0.8, 0.8, 1.6), ink)
    _compare(scene, "world fog and an absorbing box")


def test_world_volume_can_fail(addon):
    """Without the world's medium the image is far from Cycles' with it."""
    from support.blender_util import block_error_after_change
    scene = _stage()
    _lamp()
    node = _world_volume("ShaderNodeVolumeScatter", Density=0.12)
    error = block_error_after_change(scene, lambda: setattr(node.inputs["Density"], "default_value", 0.0),
                                     SAMPLES, BOUNCES)
    print(f"world fog left out: block error {error:.4f}")
    assert error > 0.02


def test_world_volume_bad_input(addon, reports, tmp_path):
    """A world volume of density zero renders as none; a textured density
    is read at its constant value with a warning; no lamp at all leaves a
    black image. Valid images, no NaN, in every mode."""
    from support.addon_util import render_exr
    from restir_gi.core.camera.film import read_exr
    scene = _stage(32, 24)
    node = _world_volume("ShaderNodeVolumePrincipled", Density=0.0)
    for mode in ("PATH", "RESTIR_BIASED"):
        scene.restir_gi.mode = mode
        render_exr(scene, tmp_path / f"zero_{mode}.exr")
        img = read_exr(tmp_path / f"zero_{mode}.exr")
        assert np.isfinite(img).all() and img[..., :3].mean() > 0.05     # the sun and the sky
    tree = scene.world.node_tree
    noise = tree.nodes.new("ShaderNodeTexNoise")
    tree.links.new(noise.outputs["Fac"], node.inputs["Density"])
    node.inputs["Density"].default_value = 1.0
    for mode in ("PATH", "RESTIR_BIASED"):
        scene.restir_gi.mode = mode
        reports.log.clear()
        render_exr(scene, tmp_path / f"textured_{mode}.exr")
        img = read_exr(tmp_path / f"textured_{mode}.exr")
        assert np.isfinite(img).all()
        assert img[..., :3].mean() < 1e-3       # no lamp: the fog hides the sun and the sky
        assert reports.of("ERROR") == []
        assert any("World" in w and "heterogeneous" in w for w in reports.of("WARNING")), reports.log


def test_media_unit():
    """Transmittance and emission of one interval in closed form; sampling
    gives the right share of scattering and HG samples are normalised."""
    from restir_gi.core.integrators.media import Intervals, hg_pdf, hg_sample
    n = 200000
    vals = np.zeros((n, 1, 10))
    vals[:, 0, :3] = (0.5, 1.0, 2.0)
    vals[:, 0, 3:6] = (0.25, 0.5, 1.0)
    vals[:, 0, 6:9] = (1.0, 1.0, 1.0)
    iv = Intervals(np.tile([[0.0, 1.0]], (n, 1)), vals)
    np.testing.assert_allclose(iv.transmittance()[0], np.exp(-np.array([0.5, 1.0, 2.0])), rtol=1e-5)
    np.testing.assert_allclose(iv.emission()[0], (1 - np.exp(-np.array([0.5, 1.0, 2.0]))) / [0.5, 1, 2], rtol=1e-5)
    rng = np.random.default_rng(1)
    scat, t, w, ss, g = iv.sample(rng.random(n), rng.random(n))
    # E[weight of scattering] = integral of T sigma_s = sigma_s / sigma_t (1 - T)
    expect = np.array([0.5, 0.5, 0.5]) * (1 - np.exp(-np.array([0.5, 1.0, 2.0])))
    np.testing.assert_allclose((w * scat[:, None]).mean(axis=0), expect, rtol=0.02)
    np.testing.assert_allclose((w * ~scat[:, None]).mean(axis=0), np.exp(-np.array([0.5, 1.0, 2.0])), rtol=0.02)
    d = np.tile([[0.0, 0.0, 1.0]], (n, 1)).astype(np.float32)
    for gv in (-0.6, 0.0, 0.8):
        wi, pdf = hg_sample(d, np.full(n, gv), rng.random((n, 2)))
        np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1, atol=1e-5)
        np.testing.assert_allclose(wi[:, 2].mean(), gv, atol=0.01)      # mean cosine is g
        np.testing.assert_allclose(pdf, hg_pdf(wi[:, 2], gv), rtol=1e-4)
