"""The Sky Texture against Cycles: a white ground with a box on it under each
sky model, the horizon and the sky toward the sun in view, rendered by both
engines. Mean colour per channel must agree within 3 % and each quadrant's
brightness within 4 % (the box's shadow falls to one side: a sun turned the
wrong way, or missing, moves it). The bright, small sun disc lights most of
the ground: the path tracer finds it by NEE (core/lights/environment.py), and both
ReSTIR modes must render the default sky without fireflies or NaN."""

import math

import numpy as np
import pytest

from support.blender_util import diffuse_material, render_image, setup_cycles, setup_restir

SIZE = 32
SAMPLES = 16
BOUNCES = 4
CLAMP = 50.0            # the sun itself, if a pixel catches it, is not what is compared
ROTATION = math.radians(30.0)


def sky_scene(sky_type, elevation):
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    white = diffuse_material("white", (0.8, 0.8, 0.8))
    for name, verts, faces in (
            ("ground", [(-50, -50, 0), (50, -50, 0), (50, 50, 0), (-50, 50, 0)], [(0, 1, 2, 3)]),
            ("box", [(x, y, z) for x in (-1, 1) for y in (3, 5) for z in (0, 2)],
             [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])):
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata(verts, [], faces)
        mesh.materials.append(white)
        scene.collection.objects.link(bpy.data.objects.new(name, mesh))
    camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    camera.location = (0, -4, 2)
    camera.rotation_euler = (math.radians(82), 0, 0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    world = bpy.data.worlds.new("sky")
    scene.world = world
    sky = world.node_tree.nodes.new("ShaderNodeTexSky")
    sky.sky_type = sky_type
    e = math.radians(elevation)
    sky.sun_elevation, sky.sun_rotation = e, ROTATION
    sky.sun_direction = (math.cos(e) * math.sin(ROTATION), math.cos(e) * math.cos(ROTATION), math.sin(e))
    world.node_tree.links.new(sky.outputs[0], world.node_tree.nodes["Background"].inputs["Color"])
    return scene


def quadrants(img):
    lum = img @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    h, w = lum.shape
    return lum.reshape(2, h // 2, 2, w // 2).mean(axis=(1, 3)).ravel()


def render_both(scene, mode="PATH", samples=SAMPLES):
    setup_restir(scene, samples, 1, BOUNCES, mode)
    ours = render_image(scene)[..., :3]
    setup_cycles(scene, SAMPLES, 1, BOUNCES)
    cycles = render_image(scene)[..., :3]
    return ours, cycles


@pytest.mark.parametrize("sky_type, elevation", [("MULTIPLE_SCATTERING", 30.0), ("SINGLE_SCATTERING", 10.0),
                                                 ("PREETHAM", 60.0), ("HOSEK_WILKIE", 30.0)])
def test_sky_matches_cycles(addon, sky_type, elevation):
    ours, cycles = render_both(sky_scene(sky_type, elevation))
    assert np.isfinite(ours).all()
    o, c = np.minimum(ours, CLAMP), np.minimum(cycles, CLAMP)
    ratio = o.reshape(-1, 3).mean(axis=0) / c.reshape(-1, 3).mean(axis=0)
    quad = quadrants(o) / quadrants(c)
    print(f"{sky_type} {elevation}: mean ours {o.reshape(-1, 3).mean(axis=0)} cycles "
          f"{c.reshape(-1, 3).mean(axis=0)} ratio {ratio} quadrants {quad}")
    assert (np.abs(ratio - 1) < 0.03).all(), ratio
    assert (np.abs(quad - 1) < 0.04).all(), quad


@pytest.mark.parametrize("mode", ["RESTIR_BIASED", "RESTIR_UNBIASED"])
def test_default_sky_in_restir_modes(addon, mode):
    """The default sky (Multiple Scattering, its sun) in both ReSTIR modes:
    finite, the mean within 3 % of Cycles', no pixel far above Cycles'
    brightest (a firefly would be tens of times brighter)."""
    scene = sky_scene("MULTIPLE_SCATTERING", 30.0)
    scene.restir_gi.warmup_frames = 4
    ours, cycles = render_both(scene, mode, samples=1)
    assert np.isfinite(ours).all()
    o, c = np.minimum(ours, CLAMP), np.minimum(cycles, CLAMP)
    ratio = o.mean() / c.mean()
    print(f"{mode}: mean ours {o.mean():.4f} cycles {c.mean():.4f} ratio {ratio:.4f} "
          f"max ours {ours.max():.2f} cycles {cycles.max():.2f}")
    assert abs(ratio - 1) < 0.03
    assert ours.max() < 2 * cycles.max()
