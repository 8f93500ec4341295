"""Export of Blender lights to core.Scene's lights: the light types as Cycles
defines them, Normalize off and exposure, temperature and spread, lights of
zero size or without shadows, light node trees and Light Falloff, negative
power; each checked against values computed here from the numbers the scene
was built with (never against the exporter's own functions).

Every test starts from an empty factory file (export_util.fresh).
"""

import math

import numpy as np
import pytest

from support.export_util import add_light, export, fresh, light, trs


def _local_axes(rotation):
    return trs((0, 0, 0), rotation, (1, 1, 1))[:3, :3]


def test_light_types_follow_cycles_conventions(addon):
    cs = addon.core.scene
    fresh()
    rot = (0.4, -0.3, 0.2)
    axes = _local_axes(rot)
    add_light("point", "POINT", location=(1, 2, 3), scale=(3, 3, 3), energy=100.0,
              color=(1, 0.5, 0.25), shadow_soft_size=0.2, use_soft_falloff=False)
    add_light("spot", "SPOT", location=(0, 0, 4), rotation=rot, energy=50.0,
              spot_size=math.radians(60), spot_blend=0.3, shadow_soft_size=0.1)
    add_light("sun", "SUN", rotation=rot, energy=3.0, angle=math.radians(5))
    sizes = {"SQUARE": (0.5 * 2, 0.5 * 3), "RECTANGLE": (0.5 * 2, 2.0 * 3),
             "DISK": (0.5 * 2, 0.5 * 3), "ELLIPSE": (0.5 * 2, 2.0 * 3)}
    for shape in sizes:
        add_light(f"area_{shape}", "AREA", location=(0, 0, 2), rotation=rot, scale=(2, 3, 1),
                  energy=80.0, shape=shape, size=0.5, size_y=2.0)
    lit = add_light("seen", "POINT", shadow_soft_size=0.3)
    lit.visible_camera = True
    s = export(addon)
    assert s.warnings == []
    assert len(s.lights) == 8

    p = light(s, "point")
    assert p["kind"] == cs.LIGHT_POINT
    np.testing.assert_allclose(p["position"], (1, 2, 3))
    np.testing.assert_allclose(p["power"], (100, 50, 25))
    np.testing.assert_allclose(p["radius"], 0.2, rtol=1e-6)       # object scale does not count
    assert not p["soft_falloff"] and not p["camera_visible"]

    sp = light(s, "spot")
    assert sp["kind"] == cs.LIGHT_SPOT
    np.testing.assert_allclose(sp["direction"], -axes[:, 2], atol=1e-6)
    np.testing.assert_allclose([sp["spot_size"], sp["spot_blend"], sp["radius"]],
                               [math.radians(60), 0.3, 0.1], rtol=1e-6)
    np.testing.assert_allclose(sp["power"], (50, 50, 50))
    assert sp["soft_falloff"]

    su = light(s, "sun")
    assert su["kind"] == cs.LIGHT_SUN
    np.testing.assert_allclose(su["direction"], -axes[:, 2], atol=1e-6)
    np.testing.assert_allclose(su["angle"], math.radians(5), rtol=1e-6)
    np.testing.assert_allclose(su["power"], (3, 3, 3))

    shapes = {"SQUARE": cs.SHAPE_SQUARE, "RECTANGLE": cs.SHAPE_RECTANGLE,
              "DISK": cs.SHAPE_DISK, "ELLIPSE": cs.SHAPE_ELLIPSE}
    for shape, (u, v) in sizes.items():
        a = light(s, f"area_{shape}")
        assert a["kind"] == cs.LIGHT_AREA and a["shape"] == shapes[shape]
        np.testing.assert_allclose([a["size_u"], a["size_v"]], [u, v], rtol=1e-6)
        np.testing.assert_allclose(a["direction"], -axes[:, 2], atol=1e-6)
        np.testing.assert_allclose(a["axis_u"], axes[:, 0], atol=1e-6)
        np.testing.assert_allclose(a["axis_v"], axes[:, 1], atol=1e-6)
        np.testing.assert_allclose(a["power"], (80, 80, 80))
        assert not a["camera_visible"]

    assert light(s, "seen")["camera_visible"]


def test_light_normalize_off_and_exposure(addon):
    fresh()
    add_light("point0", "POINT", energy=10.0, normalize=False)
    add_light("point_r", "POINT", energy=10.0, normalize=False, shadow_soft_size=0.2)
    add_light("spot_r", "SPOT", energy=10.0, normalize=False, shadow_soft_size=0.2)
    add_light("sun", "SUN", energy=2.0, normalize=False, angle=math.radians(10))
    add_light("sun0", "SUN", energy=2.0, normalize=False, angle=0.0)
    add_light("rect", "AREA", energy=10.0, normalize=False, shape="RECTANGLE", size=2.0,
              size_y=0.5, scale=(1, 2, 1))
    add_light("disk", "AREA", energy=10.0, normalize=False, shape="DISK", size=2.0)
    add_light("exposed", "POINT", energy=10.0, exposure=1.5)
    s = export(addon)

    # With normalize off Cycles keeps the radiance (or intensity) of a unit-area
    # light: the exported power carries the area (docs/cycles-conventions.md).
    expected = {
        "point0": 10 * 4.0,                                   # I = P / pi
        "point_r": 10 * 4 * math.pi * 0.2 ** 2,               # L = P / pi
        "spot_r": 10 * 4 * math.pi * 0.2 ** 2,
        "sun": 2 * math.pi * math.sin(math.radians(5)) ** 2,  # L = S
        "sun0": 2.0,
        "rect": 10 * 2.0 * 1.0,                               # L = P / pi, A = 2 x 1
        "disk": 10 * math.pi / 4 * 4.0,
        "exposed": 10 * 2 ** 1.5,                             # P * 2^exposure
    }
    for name, power in expected.items():
        np.testing.assert_allclose(light(s, name)["power"], (power,) * 3, rtol=1e-5,
                                   err_msg=name)


def test_light_temperature_and_spread(addon):
    """Colour temperature tints the light (a black body of luminance 1, as the
    Blackbody node); a spread below 180 degrees warns, once per light."""
    import bpy
    scene = fresh()
    add_light("narrow", "AREA", spread=math.radians(60))
    # A light placed three times through a collection: three lights, one warning.
    src = bpy.data.collections.new("Lamps")
    warm = add_light("warm", "POINT", location=(0, 0, 1), use_temperature=True, temperature=3000.0)
    scene.collection.objects.unlink(warm)
    src.objects.link(warm)
    for i in range(3):
        empty = bpy.data.objects.new(f"lamp{i}", None)
        empty.instance_type, empty.instance_collection = "COLLECTION", src
        empty.location = (2 * i, 0, 0)
        scene.collection.objects.link(empty)
    s = export(addon)

    assert len(s.lights) == 4
    warm_rows = [i for i, n in enumerate(s.lights.names) if n == "warm"]
    np.testing.assert_allclose(sorted(s.lights.position[warm_rows].tolist()),
                               [[0, 0, 1], [2, 0, 1], [4, 0, 1]], atol=1e-6)
    from restir_gi.core.materials.shader.nodes_spectrum import blackbody_rec709
    tint = blackbody_rec709(np.float32(3000.0)).ravel()
    warm_power = s.lights.power[warm_rows[0]]
    np.testing.assert_allclose(warm_power / warm_power.sum(), tint / tint.sum(), rtol=1e-5)
    assert warm_power[0] > 1.5 * warm_power[2]          # warm: red over blue
    assert len([w for w in s.warnings if "narrow" in w and "spread" in w]) == 1, s.warnings
    assert len(s.warnings) == 1, s.warnings


def test_area_light_of_zero_size_emits_nothing(addon):
    """An area light of size 0 (or scaled flat) has no area: Cycles renders
    nothing of it; here it emits nothing too, with a warning, instead of a
    point of unbounded radiance."""
    fresh()
    add_light("flat", "AREA", size=1.0, scale=(1, 0, 1), energy=100.0)
    add_light("dot", "AREA", size=0.0, energy=100.0)
    add_light("lamp", "AREA", size=0.5, energy=100.0)
    s = export(addon)
    power = {name: s.lights.power[s.lights.names.index(name)] for name in ("flat", "dot", "lamp")}
    assert (power["flat"] == 0).all() and (power["dot"] == 0).all() and (power["lamp"] > 0).all()
    assert sorted(w for w in s.warnings if "zero size" in w) == [
        "Light 'dot': area light of zero size emits no light",
        "Light 'flat': area light of zero size emits no light"], s.warnings


def test_light_without_shadows_is_exported(addon):
    """Cast Shadow off reaches the light rows (core/lights/light_set.py then traces no
    shadow rays for them: tests/oracle/test_lights_vs_cycles.py), without a warning."""
    fresh()
    add_light("ghost", "POINT", location=(0, 0, 1), use_shadow=False)
    add_light("plain", "POINT", location=(1, 0, 1))
    s = export(addon)
    assert dict(zip(s.lights.names, s.lights.shadowless.tolist())) == {"ghost": True, "plain": False}
    assert not [w for w in s.warnings if "Cast Shadow" in w], s.warnings


def _light_tree(light):
    """A light's node tree: there by default from Blender 5.2 (where use_nodes
    is deprecated and always on), made by turning use_nodes on before."""
    if light.node_tree is None:
        light.use_nodes = True
    return light.node_tree


def test_light_node_trees_scale_the_power(addon):
    """A light's Emission colour x strength multiplies its power, whether the
    tree is the plain Emission node (read off its sockets) or a graph (compiled);
    the default tree leaves the power alone. The export reads no deprecated
    property (Light.use_nodes warns from Blender 5.2 on)."""
    import warnings
    fresh()
    add_light("plain", "POINT", energy=10.0)
    tinted = _light_tree(add_light("tinted", "POINT", energy=10.0).data)
    emit = next(n for n in tinted.nodes if n.type == "EMISSION")
    emit.inputs["Color"].default_value = (0.5, 1.0, 0.25, 1.0)
    emit.inputs["Strength"].default_value = 2.0
    graph = _light_tree(add_light("graph", "POINT", energy=10.0).data)
    emit = next(n for n in graph.nodes if n.type == "EMISSION")
    emit.inputs["Color"].default_value = (0.5, 1.0, 0.25, 1.0)
    value = graph.nodes.new("ShaderNodeValue")
    value.outputs[0].default_value = 3.0
    graph.links.new(value.outputs[0], emit.inputs["Strength"])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        s = export(addon)
    assert not [w for w in caught if "removed in Blender" in str(w.message)], \
        [str(w.message) for w in caught]
    np.testing.assert_allclose(light(s, "plain")["power"], (10, 10, 10), rtol=1e-6)
    np.testing.assert_allclose(light(s, "tinted")["power"], (10, 20, 5), rtol=1e-6)
    np.testing.assert_allclose(light(s, "graph")["power"], (15, 30, 7.5), rtol=1e-6)
    assert not s.warnings, s.warnings


def test_light_falloff_becomes_the_lights_falloff(addon):
    """Light Falloff in a light's tree: the output read (Quadratic, Linear,
    Constant), its Smooth and what scales it on the way (a Value node, Math)
    become the light's falloff law and power; a sun ignores it as Cycles'
    distant lights do; two outputs added follow no single law (a warning,
    and the value at distance 1)."""
    fresh()

    def with_falloff(name, kind, output, strength=2.0, smooth=0.0, scale=1.0, extra=None):
        tree = _light_tree(add_light(name, kind, energy=10.0).data)
        emit = next(n for n in tree.nodes if n.type == "EMISSION")
        falloff = tree.nodes.new("ShaderNodeLightFalloff")
        falloff.inputs["Strength"].default_value = strength
        falloff.inputs["Smooth"].default_value = smooth
        math = tree.nodes.new("ShaderNodeMath")
        math.operation = "MULTIPLY" if extra is None else "ADD"
        math.inputs[1].default_value = scale
        tree.links.new(falloff.outputs[output], math.inputs[0])
        if extra is not None:
            tree.links.new(falloff.outputs[extra], math.inputs[1])
        tree.links.new(math.outputs[0], emit.inputs["Strength"])

    with_falloff("linear", "POINT", "Linear")
    with_falloff("constant", "AREA", "Constant", smooth=0.5, scale=0.25)
    with_falloff("quadratic", "SPOT", "Quadratic", strength=3.0)
    with_falloff("sun", "SUN", "Constant", smooth=4.0)
    with_falloff("mixed", "POINT", "Linear", extra="Constant")
    s = export(addon)
    expected = {"linear": (20.0, 1.0, 0.0), "constant": (5.0, 2.0, 0.5), "quadratic": (30.0, 0.0, 0.0),
                "sun": (20.0, 0.0, 0.0), "mixed": (40.0, 0.0, 0.0)}
    for name, (power, falloff, smooth) in expected.items():
        i = s.lights.names.index(name)
        np.testing.assert_allclose(s.lights.power[i], (power,) * 3, rtol=1e-5, err_msg=name)
        assert (s.lights.falloff[i], s.lights.falloff_smooth[i]) == pytest.approx((falloff, smooth)), name
    assert s.warnings == ["Light 'mixed': its Light Falloff is combined in a way not supported (only one "
                          "of its outputs, scaled); the light emits as at distance 1 from everywhere"], s.warnings


def test_negative_light_power_emits_nothing_and_says_so(addon):
    """Cycles subtracts the light of a negative power; the engine leaves the
    light out and warns."""
    fresh()
    add_light("sink", "POINT", location=(0, 0, 1), energy=-500.0)
    s = export(addon)
    assert np.all(s.lights.power == 0)
    assert [w for w in s.warnings if "negative power" in w] == [
        "Light 'sink': negative power is not supported; the light emits nothing"], s.warnings
