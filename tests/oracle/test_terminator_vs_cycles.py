"""The shadow terminator of smooth-shaded low-poly meshes against Cycles
(core/integrators/terminator.py): a 10-segment UV sphere, Shade Smooth,
lit by a sun from the side. Cycles lifts its shadow rays to the smooth
surface near the terminator (Geometry Offset 0.1 by default); a flat
triangle's shadow rays leave a staircase of dark facets there."""

import math

import numpy as np

SPP = 64


def _scene():
    import bpy
    from support.addon_util import camera, fresh, world
    from support.blender_util import diffuse_material
    scene = fresh(96, 96, samples=SPP)
    world((0, 0, 0))
    camera(location=(0, -6, 0), rotation=(math.radians(90), 0, 0), lens=50.0)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.4, segments=10, ring_count=6)
    ob = bpy.context.object
    bpy.ops.object.shade_smooth()
    ob.data.materials.append(diffuse_material("White", (0.8, 0.8, 0.8)))
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy, sun.angle = 3.0, 0.0
    light = bpy.data.objects.new("Sun", sun)
    light.rotation_euler = (math.radians(20), math.radians(-75), 0.0)   # from the side: the terminator in view
    bpy.context.scene.collection.objects.link(light)
    return scene


def test_smooth_low_poly_sphere_terminator_matches_cycles(addon, monkeypatch):
    """Measured: ratio 1.000, block chi 1.4; with the shadow rays from the
    flat triangles (the same rays, no lift) 0.971 and chi ~10^4."""
    from support.blender_util import compare_with_cycles
    scene = _scene()
    got = compare_with_cycles(scene, SPP, 1)
    print(f"ratio {got['ratio']:.4f} chi {got['chi']:.2f}")
    assert abs(got["ratio"] - 1.0) < 0.02 and got["chi"] < 2.5, got
    terminator = addon.core.integrators.terminator
    monkeypatch.setattr(terminator, "smooth_lift", lambda scene, prim, bary, ng: np.zeros((len(prim), 3), np.float32))
    flat = compare_with_cycles(scene, SPP, 1)
    print(f"without the lift: ratio {flat['ratio']:.4f} chi {flat['chi']:.2f}")
    assert flat["chi"] > 100, flat
