"""Light Paths as Cycles counts them (core/integrators/bounces.py), both
engines rendering the same scene: per-kind bounce limits (diffuse, glossy,
transmission under a larger total) and per-object ray visibility by the kind
of bounce (Diffuse, Glossy, Transmission toggles). Mean within 2 % and block
chi as tests/oracle/test_vs_cycles.py; and the setting changes our image by more
than the noise (so the comparisons could fail)."""

import numpy as np
import pytest

from support.blender_util import block_means, open_example, render_image, set_resolution, setup_cycles
from support.cornell_box import assign, new_material, principled, spheres

SIZE = 64
BLOCK = 8
SAMPLES = 128
CLAMP = 1.0


def _mirror_and_glass():
    """The Cornell box with a mirror-like sphere and a glass sphere for boxes."""
    spheres([(0.4, (-0.4, 0.3), principled("Mirror", **{
                 "Base Color": (0.9, 0.9, 0.9, 1), "Metallic": 1.0, "Roughness": 0.15})),
             (0.35, (0.45, -0.3), principled("Glass", **{
                 "Roughness": 0.05, "Transmission Weight": 1.0, "IOR": 1.45}))])


def _limits(total, diffuse, glossy, transmission):
    def cycles(scene, samples, seed):
        setup_cycles(scene, samples, seed, total)
        c = scene.cycles
        c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces = diffuse, glossy, transmission

    def ours(scene, samples, seed):
        scene.render.engine = "RESTIR_GI"
        s = scene.restir_gi
        s.mode, s.samples, s.seed = "PATH", samples, seed
        s.max_bounces, s.diffuse_bounces = total, diffuse
        s.glossy_bounces, s.transmission_bounces = glossy, transmission
    return ours, cycles


def _compare(scene, ours, cycles):
    renders = {}
    for name, setup in (("ours", ours), ("cycles", cycles)):
        renders[name] = []
        for seed in (1, 2):
            setup(scene, SAMPLES, seed)
            renders[name].append(np.minimum(render_image(scene), CLAMP))
    o = [block_means(i, BLOCK) for i in renders["ours"]]
    c = [block_means(i, BLOCK) for i in renders["cycles"]]
    o_mean, c_mean = (o[0] + o[1]) / 2, (c[0] + c[1]) / 2
    var = ((o[0] - o[1]) / 2) ** 2 + ((c[0] - c[1]) / 2) ** 2
    ratio = float(o_mean.mean() / c_mean.mean())
    chi = float(((o_mean - c_mean) ** 2).sum() / var.sum())
    return ratio, chi, (renders["ours"][0] + renders["ours"][1]) / 2, float(var.sum())


def _chi(a, b, var):
    """Block chi of two images against the comparison's noise."""
    return float(((block_means(a, BLOCK) - block_means(b, BLOCK)) ** 2).sum() / var)


@pytest.mark.parametrize("limits", [(8, 1, 8, 8), (8, 8, 0, 1)], ids=["diffuse1", "glossy0-transmission1"])
def test_bounce_limits_per_kind_match_cycles(addon, limits):
    scene = open_example("cornell_box.blend")
    set_resolution(scene, SIZE, SIZE)
    _mirror_and_glass()
    ratio, chi, img, var = _compare(scene, *_limits(*limits))
    print(f"{limits}: ratio {ratio:.4f} block chi {chi:.2f}")
    assert abs(ratio - 1) < 0.02 and chi < 2.5
    # The limits matter here: with every kind at the total the image differs
    # by far more than the noise.
    ours, _ = _limits(8, 8, 8, 8)
    ours(scene, SAMPLES, 3)
    free = np.minimum(render_image(scene), CLAMP)
    assert _chi(free, img, var) > 10, _chi(free, img, var)


def test_ray_visibility_per_kind_matches_cycles(addon):
    """Two glowing red cubes, one in front of the spheres and one behind the
    glass sphere, on a polished metal floor: hidden from glossy rays, the
    floor and the mirror sphere do not show them; hidden from transmission
    rays, the glass sphere does not; hidden from diffuse rays, their red
    light does not reach the walls (light sampling leaves them out of the
    diffuse lobes too, as Cycles does)."""
    import bpy
    scene = open_example("cornell_box.blend")
    set_resolution(scene, SIZE, SIZE)
    spheres([(0.35, (-0.4, -0.2), principled("Mirror", **{
                 "Base Color": (0.9, 0.9, 0.9, 1), "Metallic": 1.0, "Roughness": 0.1})),
             (0.35, (0.4, -0.2), principled("Glass", **{
                 "Roughness": 0.05, "Transmission Weight": 1.0, "IOR": 1.45}))])
    assign(["Floor"], principled("Polished", **{
        "Base Color": (0.8, 0.8, 0.8, 1), "Metallic": 1.0, "Roughness": 0.15}))
    glow = principled("Glow", **{"Base Color": (0.8, 0.1, 0.1, 1), "Emission Color": (1.0, 0.2, 0.1, 1),
                                 "Emission Strength": 3.0})
    cubes = []
    for size, location in ((0.3, (0.0, -1.1, 0.152)), (0.4, (0.4, 0.6, 0.202))):
        bpy.ops.mesh.primitive_cube_add(size=size, location=location)
        cubes.append(bpy.context.object)
        cubes[-1].data.materials.append(glow)

    def show(hidden_from=None):
        for cube in cubes:
            for k in ("glossy", "transmission", "diffuse"):
                setattr(cube, "visible_" + k, k != hidden_from)

    ours, cycles = _limits(8, 8, 8, 8)
    show()
    ours(scene, SAMPLES, 3)
    baseline = np.minimum(render_image(scene), CLAMP)
    for kind in ("glossy", "transmission", "diffuse"):
        show(kind)
        ratio, chi, img, var = _compare(scene, ours, cycles)
        change = _chi(baseline, img, var)
        print(f"hidden from {kind}: ratio {ratio:.4f} block chi {chi:.2f} change {change:.1f}")
        assert abs(ratio - 1) < 0.02 and chi < 2.5, kind
        assert change > 5, (kind, change)       # hiding them changed the picture (noise: ~1)


def test_lamp_hidden_by_kind_matches_cycles(addon):
    """An area lamp over the polished floor and the mirror sphere, hidden
    from glossy rays (no highlight of it, no reflection), then from diffuse
    rays (it lights only the glossy lobes)."""
    import bpy
    scene = open_example("cornell_box.blend")
    set_resolution(scene, SIZE, SIZE)
    spheres([(0.35, (-0.4, -0.2), principled("Mirror", **{
                 "Base Color": (0.9, 0.9, 0.9, 1), "Metallic": 1.0, "Roughness": 0.2}))])
    assign(["Floor"], principled("Satin", **{"Base Color": (0.6, 0.6, 0.6, 1), "Roughness": 0.25}))
    lamp = bpy.data.lights.new("Lamp", "AREA")
    lamp.energy, lamp.size = 40.0, 0.4
    obj = bpy.data.objects.new("Lamp", lamp)
    obj.location = (0.45, -0.3, 1.4)
    scene.collection.objects.link(obj)
    ours, cycles = _limits(8, 8, 8, 8)
    ours(scene, SAMPLES, 3)
    baseline = np.minimum(render_image(scene), CLAMP)
    for kind in ("glossy", "diffuse"):
        obj.visible_glossy, obj.visible_diffuse = kind != "glossy", kind != "diffuse"
        ratio, chi, img, var = _compare(scene, ours, cycles)
        change = _chi(baseline, img, var)
        print(f"lamp hidden from {kind}: ratio {ratio:.4f} block chi {chi:.2f} change {change:.1f}")
        assert abs(ratio - 1) < 0.02 and chi < 2.5, kind
        assert change > 5, (kind, change)


def _spheres_and_baseline():
    """The Cornell box with the mirror and glass spheres, the two engines'
    setups (8 bounces of each kind) and our render of it as it is."""
    scene = open_example("cornell_box.blend")
    set_resolution(scene, SIZE, SIZE)
    _mirror_and_glass()
    ours, cycles = _limits(8, 8, 8, 8)
    ours(scene, SAMPLES, 3)
    return scene, ours, cycles, np.minimum(render_image(scene), CLAMP)


def _assert_matches_and_changes(scene, ours, cycles, baseline, label):
    """Both engines agree on the changed scene, and the change moved our
    picture by more than the noise (so the comparison could fail)."""
    ratio, chi, img, var = _compare(scene, ours, cycles)
    change = _chi(baseline, img, var)
    print(f"{label}: ratio {ratio:.4f} block chi {chi:.2f} change {change:.1f}")
    assert abs(ratio - 1) < 0.02 and chi < 2.5
    assert change > 5


def test_indirect_only_collection_matches_cycles(addon):
    """The mirror sphere in an Indirect Only collection (the view layer's):
    the camera does not see it, its shadow, its reflection in the glass
    sphere and the light it bounces stay, as Cycles renders them."""
    import bpy
    scene, ours, cycles, baseline = _spheres_and_baseline()
    side = bpy.data.collections.new("Side")
    scene.collection.children.link(side)
    mirror = next(o for o in scene.objects if o.active_material is not None
                  and o.active_material.name == "Mirror")
    for ob in (mirror,):
        for owner in list(ob.users_collection):
            owner.objects.unlink(ob)
        side.objects.link(ob)
    bpy.context.view_layer.layer_collection.children["Side"].indirect_only = True
    _assert_matches_and_changes(scene, ours, cycles, baseline, "indirect only")


def test_glass_transparent_to_shadow_rays_matches_cycles(addon):
    """The usual glass trick: Mix Shader of Glass and Transparent by Light
    Path > Is Shadow Ray. Shadow rays pass the glass sphere (its shadow is
    light), other rays see glass, as Cycles renders it."""
    scene, ours, cycles, baseline = _spheres_and_baseline()
    mat, tree, out = new_material("ShadowlessGlass")
    glass, clear = tree.nodes.new("ShaderNodeBsdfGlass"), tree.nodes.new("ShaderNodeBsdfTransparent")
    glass.inputs["Roughness"].default_value, glass.inputs["IOR"].default_value = 0.05, 1.45
    mix, path = tree.nodes.new("ShaderNodeMixShader"), tree.nodes.new("ShaderNodeLightPath")
    tree.links.new(path.outputs["Is Shadow Ray"], mix.inputs["Fac"])
    tree.links.new(glass.outputs[0], mix.inputs[1])
    tree.links.new(clear.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], out.inputs["Surface"])
    sphere = next(o for o in scene.objects if o.active_material is not None
                  and o.active_material.name == "Glass")
    sphere.active_material = mat
    _assert_matches_and_changes(scene, ours, cycles, baseline, "glass clear to shadows")
