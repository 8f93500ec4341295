"""The path tracer against Cycles, the independent oracle shipped in bpy.

The same Cornell box (Diffuse BSDF walls) is lit by an emissive quad, a point
light and an area light and rendered by both engines, each twice with
independent seeds. Mean brightness must agree within 2 %, and the block-wise
differences must be what the noise allows: the sum of squared block differences
over the sum of their estimated variances (from each engine's two independent
renders) stays near 1; a brightness convention off by a few percent, or a
missing light path, pushes it far above.
"""

import numpy as np
import pytest

from blender_util import compare_with_cycles, open_example, set_resolution

SIZE = 64
BLOCK = 8
SAMPLES = 128
BOUNCES = 8


def _cornell(light):
    import bpy
    scene = open_example("cornell_box.blend")
    set_resolution(scene, SIZE, SIZE)
    if light != "emitter":
        bpy.data.objects.remove(bpy.data.objects["CeilingLight"])
        if light == "point":
            data = bpy.data.lights.new("Point", "POINT")
            data.energy = 60.0
            data.shadow_soft_size = 0.05
            obj = bpy.data.objects.new("Point", data)
            obj.location = (0.0, 0.0, 1.7)
        else:
            data = bpy.data.lights.new("Area", "AREA")
            data.energy = 60.0
            data.shape = "RECTANGLE"
            data.size, data.size_y = 0.6, 0.4
            obj = bpy.data.objects.new("Area", data)
            obj.location = (0.0, 0.0, 1.98)
        scene.collection.objects.link(obj)
    return scene


@pytest.mark.parametrize("light", ["emitter", "point", "area"])
def test_cornell_box_matches_cycles(addon, light):
    r = compare_with_cycles(_cornell(light), SAMPLES, BOUNCES, BLOCK)
    assert np.isfinite(r["ours"]).all()
    print(f"{light}: mean ours {r['ours_mean']:.4f} cycles {r['cycles_mean']:.4f} "
          f"ratio {r['ratio']:.4f} block chi {r['chi']:.2f}")
    assert abs(r["ratio"] - 1.0) < 0.02
    assert r["chi"] < 2.5
