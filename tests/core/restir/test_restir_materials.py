"""ReSTIR GI on shader-graph materials: a glass box and a textured floor;
and on a metal box under a binding per-kind bounce limit.

A visible point on glass has no diffuse lobe for the reservoirs to shade;
its light comes from its own BSDF-sampled path (through the glass), and a
textured floor's parameters vary per hit. The unbiased mode must keep the
path tracer's mean, compared by z-tests on the whole image and on blocks as
in tests/core/restir/test_restir_world.py."""

import numpy as np
import pytest

from restir_gi.core import RenderContext, RenderSettings, render_frame
from restir_gi.core.integrators.bounces import Bounces
from restir_gi.core.restir import UNBIASED, ReSTIRGI, ReSTIRSettings
from restir_gi.core.util.vectors import luminance
from restir_gi.core.materials.shader import Link, Node, ShaderGraph
from support.scenes import cornell_box
from support.restir_reference import assert_same_mean

SIZE = 12
MAX_BOUNCES = 4
REFERENCE_SPP = 512


def make_scene():
    """The Cornell box of tests/support/scenes.py (area light) with a rough glass tall
    box and a checker-textured floor (Generated-free: Object coordinates)."""
    scene = cornell_box("area", SIZE, SIZE)
    scene.filter_width = 0.0
    glass = ShaderGraph(nodes=[Node("BSDF_GLASS", {"Color": (1.0, 1.0, 1.0), "Roughness": 0.2,
                                                   "IOR": 1.45})], output=Link(0, "BSDF"))
    checker = ShaderGraph(nodes=[
        Node("TEX_COORD"),
        Node("TEX_CHECKER", {"Vector": Link(0, "Object"), "Color1": (0.8, 0.8, 0.8),
                             "Color2": (0.2, 0.3, 0.6), "Scale": 2.0}),
        Node("BSDF_PRINCIPLED", {"Base Color": Link(1, "Color"), "Roughness": 0.5})],
        output=Link(2, "BSDF"))
    # Material ids of the box (tests/support/scenes.py): 0 white, 1 red, 2 green, 3 light;
    # new ids 4 (glass) and 5 (floor).
    from restir_gi.core import Materials
    rows = [{"name": n} for n in scene.materials.names] + [{"name": "glass"}, {"name": "floor"}]
    base = scene.materials
    scene.materials = Materials.from_list([
        {"name": base.names[i], "base_color": tuple(base.base_color[i]), "metallic": float(base.metallic[i]),
         "roughness": float(base.roughness[i]), "specular": float(base.specular[i]), "ior": float(base.ior[i]),
         "emission": tuple(base.emission[i])} for i in range(len(base))] + rows[len(base):])
    centre = scene.vertices[scene.triangles].mean(axis=1)
    floor = np.abs(centre[:, 2]) < 1e-4
    tall = (centre[:, 0] > -0.61) & (centre[:, 0] < -0.04) & (centre[:, 1] > -0.11) & (centre[:, 1] < 0.51) \
        & (centre[:, 2] > 1e-4)
    scene.material_ids = np.where(tall, 4, np.where(floor, 5, scene.material_ids)).astype(np.int32)
    scene.shaders = [None] * len(base) + [glass, checker]
    scene.object_matrices = np.eye(4, dtype=np.float32)[None]
    return scene


@pytest.fixture(scope="module")
def setup():
    ctx = RenderContext.build(make_scene())
    film = render_frame(ctx, RenderSettings(samples=REFERENCE_SPP, max_bounces=MAX_BOUNCES, seed=0))
    ref = (luminance(film.mean().reshape(-1, 3)).astype(np.float64),
           film.variance_of_mean().reshape(-1).astype(np.float64))
    yield ctx, ref
    ctx.close()


def test01_the_scene_has_glass_and_texture(setup):
    ctx, (mean, _) = setup
    from restir_gi.core.materials.shading import shading
    assert shading(ctx.scene).varying == [4, 5]
    assert (mean > 0.01).mean() > 0.9


@pytest.mark.slow
def test02_unbiased_matches_path_tracing(setup):
    ctx, ref = setup
    out = []
    for r in range(64):
        restir = ReSTIRGI()
        settings = ReSTIRSettings(mode=UNBIASED, seed=700 + r, max_bounces=MAX_BOUNCES)
        for f in range(4):
            result = restir.render_frame(ctx, settings, f)
        out.append(luminance(result.color))
    assert_same_mean(np.stack(out).astype(np.float64), ref, "glass and texture, unbiased")


LIMITS = Bounces(4, 1, 4, 4)    # one diffuse bounce: binding, so a miscounted bounce shows


def metal_box_scene():
    """The Cornell box with its tall box rough metal."""
    scene = cornell_box("area", SIZE, SIZE)
    scene.filter_width = 0.0
    from restir_gi.core import Materials
    base = scene.materials
    scene.materials = Materials.from_list([
        {"name": base.names[i], "base_color": tuple(base.base_color[i]), "metallic": float(base.metallic[i]),
         "roughness": float(base.roughness[i]), "specular": float(base.specular[i]), "ior": float(base.ior[i]),
         "emission": tuple(base.emission[i])} for i in range(len(base))]
        + [{"name": "metal", "base_color": (0.9, 0.9, 0.9), "metallic": 1.0, "roughness": 0.3}])
    centre = scene.vertices[scene.triangles].mean(axis=1)
    tall = (centre[:, 0] > -0.61) & (centre[:, 0] < -0.04) & (centre[:, 1] > -0.11) & (centre[:, 1] < 0.51) \
        & (centre[:, 2] > 1e-4)
    scene.material_ids = np.where(tall, len(base), scene.material_ids).astype(np.int32)
    return scene


@pytest.mark.slow
def test03_glossy_sample_paths_count_a_glossy_bounce():
    """The path from a sample point counts the sample ray as a bounce of the
    kind of lobe that drew it, as the path tracer does: from a metal, a
    glossy one. Counted as diffuse, the one diffuse bounce allowed here was
    spent at the metal and the walls it reflects lost their indirect light."""
    ctx = RenderContext.build(metal_box_scene())
    try:
        film = render_frame(ctx, RenderSettings(samples=REFERENCE_SPP, max_bounces=LIMITS, seed=0))
        ref = (luminance(film.mean().reshape(-1, 3)).astype(np.float64),
               film.variance_of_mean().reshape(-1).astype(np.float64))
        out = []
        for r in range(64):
            restir = ReSTIRGI()
            settings = ReSTIRSettings(mode=UNBIASED, seed=900 + r, max_bounces=LIMITS)
            for f in range(4):
                result = restir.render_frame(ctx, settings, f)
            out.append(luminance(result.color))
        assert_same_mean(np.stack(out).astype(np.float64), ref, "metal box, one diffuse bounce, unbiased")
    finally:
        ctx.close()
