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

from blender_util import (block_means, open_example, render_image, set_resolution,
                          setup_cycles, setup_restir)

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


def _two_renders(scene, setup):
    out = []
    for seed in (1, 2):
        setup(scene, SAMPLES, seed, BOUNCES)
        out.append(render_image(scene))
    return out


@pytest.mark.parametrize("light", ["emitter", "point", "area"])
def test_cornell_box_matches_cycles(addon, light):
    scene = _cornell(light)
    ours = _two_renders(scene, setup_restir)
    cycles = _two_renders(scene, setup_cycles)
    for img in ours:
        assert np.isfinite(img).all()

    o = [block_means(i, BLOCK) for i in ours]
    c = [block_means(i, BLOCK) for i in cycles]
    o_mean, c_mean = (o[0] + o[1]) / 2, (c[0] + c[1]) / 2
    # Unbiased variance of each two-render mean, per block: ((a - b) / 2)^2.
    var = ((o[0] - o[1]) / 2) ** 2 + ((c[0] - c[1]) / 2) ** 2
    ratio = float(o_mean.mean() / c_mean.mean())
    chi = float(((o_mean - c_mean) ** 2).sum() / var.sum())
    print(f"{light}: mean ours {o_mean.mean():.4f} cycles {c_mean.mean():.4f} ratio {ratio:.4f} "
          f"block chi {chi:.2f}")
    assert abs(ratio - 1.0) < 0.02
    assert chi < 2.5
