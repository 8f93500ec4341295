"""Spot (also with colour temperature and a light node tree), sun (also with
Cast Shadow off), emissive Principled mesh, an emitter with a textured
colour, world lighting, many lamps and glowing cubes at once, and lamps
whose node trees use Light Falloff (linear, constant and quadratic, with
Smooth) against Cycles.

A floor with two boxes (Diffuse BSDF) is built in code and lit by one source at
a time; both engines render it twice with independent seeds. As in
test_vs_cycles.py, mean brightness must agree within 2 % and the block chi
statistic (squared block differences over their variance estimated from the
two seeds) must stay below 2.5.
"""

import math

import numpy as np
import pytest

from support.blender_util import compare_with_cycles, diffuse_material, set_resolution

SIZE = 64
BLOCK = 8
SAMPLES = 128
BOUNCES = 4


def _mesh(name, verts, faces, mat):
    import bpy
    me = bpy.data.meshes.new(name)
    me.from_pydata(np.asarray(verts, np.float64).tolist(), [], [[int(i) for i in f] for f in faces])
    me.update()
    me.materials.append(mat)
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def _box(lo, hi):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = [[x, y, z] for z in (z0, z1) for y in (y0, y1) for x in (x0, x1)]
    faces = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    return v, faces


def _light(name, kind, location, rotation=(0, 0, 0), **props):
    import bpy
    data = bpy.data.lights.new(name, kind)
    for key, value in props.items():
        setattr(data, key, value)
    ob = bpy.data.objects.new(name, data)
    ob.location, ob.rotation_euler = location, rotation
    bpy.context.scene.collection.objects.link(ob)
    return ob


def _light_tree(light_object):
    """The light's node tree: there by default from Blender 5.2 (whose
    use_nodes is deprecated), made with use_nodes before."""
    light = light_object.data
    if light.node_tree is None:
        light.use_nodes = True
    return light.node_tree


def _scene(source):
    import bpy
    from mathutils import Vector
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    set_resolution(scene, SIZE, SIZE)

    world = bpy.data.worlds.new("World")
    scene.world = world
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.3, 0.5, 0.9, 1) if source == "world" else (0, 0, 0, 1)

    white = diffuse_material("White", (0.8, 0.8, 0.8))
    _mesh("Floor", [[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0]], [[0, 1, 2, 3]], white)
    _mesh("BoxA", *_box((-1.3, -0.2, 0), (-0.3, 0.8, 1)), diffuse_material("Red", (0.8, 0.25, 0.2)))
    _mesh("BoxB", *_box((0.5, -0.6, 0), (1.1, 0.0, 1.6)), white)

    if source == "spot":
        _light("Spot", "SPOT", (0.2, 0.1, 4.5), energy=2000.0, spot_size=math.radians(60),
               spot_blend=0.3, shadow_soft_size=0.1)
    elif source in ("sun", "shadowless_sun"):
        # Cast Shadow off: the boxes cast no shadow from the sun's light
        # samples, while rays that find the sun's disc are still blocked.
        _light("Sun", "SUN", (0, 0, 5), rotation=(math.radians(30), 0, math.radians(20)),
               energy=3.0, angle=math.radians(5), use_shadow=source == "sun")
    elif source == "warm_spot":
        # Colour temperature and a light node tree (Emission colour x strength).
        spot = _light("Spot", "SPOT", (0.2, 0.1, 4.5), energy=1000.0, spot_size=math.radians(60),
                      spot_blend=0.3, shadow_soft_size=0.1, use_temperature=True, temperature=3200.0)
        if spot.data.node_tree is None:         # a light's tree is there by default from 5.2
            spot.data.use_nodes = True
        emission = next(n for n in spot.data.node_tree.nodes if n.type == "EMISSION")
        emission.inputs["Strength"].default_value = 2.0
        emission.inputs["Color"].default_value = (0.9, 1.0, 0.8, 1)
    elif source == "emitter":
        mat = bpy.data.materials.new("Glow")
        p = mat.node_tree.nodes["Principled BSDF"]
        p.inputs["Base Color"].default_value = (0, 0, 0, 1)
        p.inputs["Emission Color"].default_value = (1.0, 0.8, 0.6, 1)
        p.inputs["Emission Strength"].default_value = 20.0
        # Above and in front of the scene, out of the camera's view: a directly seen
        # emitter's few high-contrast edge blocks would dominate the chi statistic.
        _mesh("Emitter", [[-1, -3.5, 4.5], [1, -3.5, 4.5], [1, -2.5, 4.5], [-1, -2.5, 4.5]],
              [[0, 1, 2, 3]], mat)

    elif source == "textured_emitter":
        # An emitting panel whose colour is a checker of red and blue: light
        # samples read the emission where they land (a triangle's centre
        # would give one colour per triangle).
        mat = bpy.data.materials.new("Checkered")
        tree = mat.node_tree
        tree.nodes.clear()
        out, emit = tree.nodes.new("ShaderNodeOutputMaterial"), tree.nodes.new("ShaderNodeEmission")
        checker = tree.nodes.new("ShaderNodeTexChecker")
        checker.inputs["Scale"].default_value = 2.0
        checker.inputs["Color1"].default_value = (1.0, 0.1, 0.05, 1)
        checker.inputs["Color2"].default_value = (0.05, 0.2, 1.0, 1)
        tree.links.new(checker.outputs["Color"], emit.inputs["Color"])
        emit.inputs["Strength"].default_value = 25.0
        tree.links.new(emit.outputs[0], out.inputs["Surface"])
        _mesh("Panel", [[-2, -3.5, 4.5], [2, -3.5, 4.5], [2, 0.5, 4.5], [-2, 0.5, 4.5]], [[0, 1, 2, 3]], mat)
    elif source == "many_lamps":
        # Lamps and small glowing cubes spread over the floor: emitters are
        # chosen by where the shading point is (core/lights/light_grid.py).
        rng = np.random.default_rng(5)
        for i, (x, y) in enumerate(rng.uniform(-2.7, 2.7, (10, 2))):
            _light(f"Lamp{i}", "POINT", (x, y, rng.uniform(0.3, 2.0)), energy=float(rng.uniform(20, 120)),
                   shadow_soft_size=float(rng.uniform(0.0, 0.2)), color=tuple(rng.uniform(0.4, 1.0, 3)))
        glow = bpy.data.materials.new("Glow")
        emission = glow.node_tree.nodes["Principled BSDF"]
        emission.inputs["Emission Color"].default_value = (0.6, 0.8, 1.0, 1)
        emission.inputs["Emission Strength"].default_value = 30.0
        for i, (x, y) in enumerate(rng.uniform(-2.7, 2.7, (6, 2))):
            _mesh(f"Cube{i}", *_box((x, y, 0.0), (x + 0.15, y + 0.15, 0.15)), glow)
        for i, (x, y) in enumerate(rng.uniform(-2.0, 2.0, (3, 2))):      # downlights and panels:
            _light(f"Down{i}", "SPOT", (x, y, 2.2), energy=300.0,       # the grid weighs their cones
                   spot_size=math.radians(50), spot_blend=0.2, shadow_soft_size=0.05)
            _light(f"Panel{i}", "AREA", (-x, -y, 2.6), energy=80.0, size=0.4)

    elif source == "falloff_point":
        # A point lamp whose node tree sets its colour from an RGB node and
        # its strength from Light Falloff's Linear output: light falling off
        # as 1 / d, not 1 / d^2.
        lamp = _light("Lamp", "POINT", (-0.4, -0.6, 2.2), energy=40.0, shadow_soft_size=0.15)
        tree = _light_tree(lamp)
        emission = next(n for n in tree.nodes if n.type == "EMISSION")
        rgb = tree.nodes.new("ShaderNodeRGB")
        rgb.outputs[0].default_value = (1.0, 0.15, 0.1, 1.0)
        tree.links.new(rgb.outputs[0], emission.inputs["Color"])
        falloff = tree.nodes.new("ShaderNodeLightFalloff")
        falloff.inputs["Strength"].default_value = 2.0
        tree.links.new(falloff.outputs["Linear"], emission.inputs["Strength"])
    elif source == "falloff_area_spot":
        # Light Falloff's Constant output with a Smooth on an area light, its
        # Strength from a Value node; its Quadratic output with a Smooth on a
        # spot, scaled by a Math node.
        panel = _light("Panel", "AREA", (0.8, -1.2, 2.4), rotation=(math.radians(20), 0, 0), energy=15.0, size=0.6)
        tree = _light_tree(panel)
        emission = next(n for n in tree.nodes if n.type == "EMISSION")
        emission.inputs["Color"].default_value = (0.4, 0.6, 1.0, 1.0)
        falloff = tree.nodes.new("ShaderNodeLightFalloff")
        value = tree.nodes.new("ShaderNodeValue")
        value.outputs[0].default_value = 0.5
        tree.links.new(value.outputs[0], falloff.inputs["Strength"])
        falloff.inputs["Smooth"].default_value = 2.0
        tree.links.new(falloff.outputs["Constant"], emission.inputs["Strength"])
        spot = _light("Spot", "SPOT", (-0.6, 0.3, 3.5), energy=800.0, spot_size=math.radians(50),
                      spot_blend=0.3, shadow_soft_size=0.1)
        tree = _light_tree(spot)
        emission = next(n for n in tree.nodes if n.type == "EMISSION")
        falloff = tree.nodes.new("ShaderNodeLightFalloff")
        falloff.inputs["Strength"].default_value = 1.0
        falloff.inputs["Smooth"].default_value = 30.0
        half = tree.nodes.new("ShaderNodeMath")
        half.operation = "MULTIPLY"
        half.inputs[1].default_value = 0.5
        tree.links.new(falloff.outputs["Quadratic"], half.inputs[0])
        tree.links.new(half.outputs[0], emission.inputs["Strength"])

    cam_data = bpy.data.cameras.new("Camera")
    cam_data.lens = 30.0
    cam = bpy.data.objects.new("Camera", cam_data)
    cam.location = (0.5, -5.5, 3.5)
    direction = Vector((0.0, 0.2, 0.6)) - cam.location
    cam.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(cam)
    scene.camera = cam
    return scene


@pytest.mark.parametrize("source", ["spot", "warm_spot", "sun", "shadowless_sun", "emitter", "world",
                                    "many_lamps", "textured_emitter", "falloff_point", "falloff_area_spot"])
def test_lights_match_cycles(addon, source):
    r = compare_with_cycles(_scene(source), SAMPLES, BOUNCES, BLOCK)
    assert np.isfinite(r["ours"]).all()
    print(f"{source}: mean ours {r['ours_mean']:.4f} cycles {r['cycles_mean']:.4f} "
          f"ratio {r['ratio']:.4f} block chi {r['chi']:.2f}")
    assert r["cycles_mean"] > 0.02          # the scene is lit at all
    assert abs(r["ratio"] - 1.0) < 0.02
    assert r["chi"] < 2.5
