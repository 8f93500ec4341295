"""Panoramic cameras (core/camera/panorama.py): Cycles' equirectangular, fisheye,
mirror ball, central cylindrical and cube map face projections against
Cycles' renders of the same scene, the export of their
settings, and the ReSTIR modes with a panoramic camera (reprojection through
the panorama's inverse mapping), which must stay finite and near the path
tracer.

The Cycles comparisons: a camera inside a box of walls of six colours, a
floor and a sun, so a projection turned, mirrored or stretched puts other
colours in the blocks; mean within 2 % and block chi < 2.5 (as
tests/oracle/test_nodes_vs_cycles.py).
"""

import math

import numpy as np
import pytest

SAMPLES = 64
BOUNCES = 2
CASES = {
    "equirectangular": (64, 32, dict(panorama_type="EQUIRECTANGULAR")),
    "equirectangular_range": (48, 32, dict(panorama_type="EQUIRECTANGULAR", latitude_min=-0.6,
                                           latitude_max=1.1, longitude_min=-2.0, longitude_max=1.2)),
    "fisheye_equidistant": (48, 40, dict(panorama_type="FISHEYE_EQUIDISTANT", fisheye_fov=math.radians(200))),
    "fisheye_equisolid": (48, 32, dict(panorama_type="FISHEYE_EQUISOLID", fisheye_fov=math.radians(170),
                                       fisheye_lens=9.0, sensor_width=30.0)),
    "fisheye_lens_polynomial": (48, 32, dict(panorama_type="FISHEYE_LENS_POLYNOMIAL", fisheye_fov=math.radians(190),
                                             fisheye_polynomial_k1=-0.06, fisheye_polynomial_k2=-0.0004)),
    "mirror_ball": (40, 40, dict(panorama_type="MIRRORBALL")),
    "central_cylindrical": (48, 32, dict(panorama_type="CENTRAL_CYLINDRICAL", central_cylindrical_range_u_min=-2.0,
                                         central_cylindrical_range_u_max=2.5, central_cylindrical_range_v_min=-0.8,
                                         central_cylindrical_range_v_max=1.2, central_cylindrical_radius=1.5)),
    "cubemap_face": (40, 40, dict(panorama_type="EQUIANGULAR_CUBEMAP_FACE")),
    "equirectangular_depth_of_field": (64, 32, dict(panorama_type="EQUIRECTANGULAR")),
}


def _room():
    """Walls of six colours around the origin, lit by a sun and a grey world."""
    import bpy
    from support.addon_util import add_mesh, world
    from support.blender_util import diffuse_material
    world((0.3, 0.35, 0.4))
    faces = {   # name: (colour, corners)
        "floor": ((0.7, 0.7, 0.7), [(-3, -3, -1), (3, -3, -1), (3, 3, -1), (-3, 3, -1)]),
        "north": ((0.8, 0.1, 0.1), [(-3, 3, -1), (3, 3, -1), (3, 3, 1.5), (-3, 3, 1.5)]),
        "east": ((0.1, 0.7, 0.1), [(3, -3, -1), (3, -3, 1.5), (3, 3, 1.5), (3, 3, -1)]),
        "south": ((0.1, 0.2, 0.8), [(-3, -3, -1), (-3, -3, 1.5), (3, -3, 1.5), (3, -3, -1)]),
        "west_low": ((0.8, 0.7, 0.1), [(-3, -3, -1), (-3, 3, -1), (-3, 3, 0.2), (-3, -3, 0.2)]),
        "block": ((0.6, 0.2, 0.6), [(0.5, 1.0, -1), (1.5, 1.0, -1), (1.5, 1.0, 0.3), (0.5, 1.0, 0.3)]),
    }
    for name, (color, corners) in faces.items():
        add_mesh(name, corners, [[0, 1, 2, 3]], mat=diffuse_material(name, color))
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 3.0
    ob = bpy.data.objects.new("Sun", sun)
    ob.rotation_euler = (math.radians(40), math.radians(10), math.radians(30))
    bpy.context.scene.collection.objects.link(ob)


def _pano_camera(**props):
    from support.addon_util import camera
    # Looking along +y, tilted up a little and rolled: every axis of the
    # mapping shows.
    return camera(location=(0.2, -0.3, 0.1), rotation=(math.radians(95), math.radians(4), math.radians(20)),
                  type="PANO", clip_start=0.05, **props)


@pytest.mark.slow
@pytest.mark.parametrize("case", list(CASES))
def test_panorama_matches_cycles(addon, case):
    from support.addon_util import fresh
    from support.blender_util import compare_with_cycles
    width, height, props = CASES[case]
    scene = fresh(width, height)
    _room()
    cam = _pano_camera(**props)
    if case.endswith("depth_of_field"):     # in focus 1.5 away, the walls (2-3.5 away) blurred
        cam.data.dof.use_dof, cam.data.dof.focus_distance, cam.data.dof.aperture_fstop = True, 1.5, 0.05
    r = compare_with_cycles(scene, SAMPLES, BOUNCES, block=4)
    assert np.isfinite(r["ours"]).all()
    print(f"{case}: mean ours {r['ours_mean']:.4f} cycles {r['cycles_mean']:.4f} "
          f"ratio {r['ratio']:.4f} block chi {r['chi']:.2f}")
    assert abs(r["ratio"] - 1.0) < 0.02
    assert r["chi"] < 2.5
    if case in ("fisheye_equidistant", "fisheye_equisolid", "mirror_ball"):      # outside the lens: black in both
        assert (r["ours"][0, 0] == 0).all() and (r["cycles"][0, 0] == 0).all()


def test_panorama_mirrored_would_fail(addon):
    """The comparison can fail: the equirectangular image flipped left to
    right (a mapping turned the wrong way) is far from Cycles'."""
    from support.addon_util import fresh
    from support.blender_util import block_means, render_image, setup_cycles, setup_restir
    width, height, props = CASES["equirectangular"]
    scene = fresh(width, height)
    _room()
    _pano_camera(**props)
    setup_restir(scene, SAMPLES, 1, BOUNCES)
    ours = render_image(scene)
    setup_cycles(scene, SAMPLES, 1, BOUNCES)
    cycles = render_image(scene)
    right = np.abs(block_means(ours, 4) - block_means(cycles, 4)).mean()
    flipped = np.abs(block_means(ours[:, ::-1], 4) - block_means(cycles, 4)).mean()
    print(f"block error {right:.4f}, mirrored {flipped:.4f}")
    assert flipped > 4 * right


def test_panorama_export_and_warnings(addon):
    import bpy
    from support.addon_util import fresh
    from support.export_util import export
    fresh(40, 20)
    _room()
    cam = _pano_camera(panorama_type="FISHEYE_EQUISOLID", fisheye_fov=2.5, fisheye_lens=8.0)
    bpy.context.view_layer.update()
    c = export(addon, 40, 20).camera
    assert (c.projection, c.panorama_type) == ("PANO", "FISHEYE_EQUISOLID")
    assert math.isclose(c.fisheye_fov, 2.5, rel_tol=1e-6) and math.isclose(c.fisheye_lens, 8.0, rel_tol=1e-6)
    warnings = []
    cam.data.panorama_type = "CENTRAL_CYLINDRICAL"
    cam.data.central_cylindrical_radius = 2.0
    cam.data.dof.use_dof = True
    bpy.context.view_layer.update()
    c = addon.restir_addon.export.camera.export_camera(bpy.context.evaluated_depsgraph_get(), warnings.append)
    assert c.panorama_type == "CENTRAL_CYLINDRICAL" and c.central_cylindrical_radius == 2.0
    assert c.aperture_size > 0 and not warnings


def test_panorama_round_trip_and_region():
    """project inverts generate_rays inside the lens; a render region's
    camera traces the rays of the full image's pixels it covers; bad
    settings (zero ranges, zero lens) give finite rays."""
    from restir_gi.core.camera.projection import crop, generate_rays, project
    from restir_gi.core.scene import Camera
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, 1, (2000, 2)) * [60, 36]
    for kind in ("EQUIRECTANGULAR", "FISHEYE_EQUIDISTANT", "FISHEYE_EQUISOLID", "FISHEYE_LENS_POLYNOMIAL",
                 "MIRRORBALL", "CENTRAL_CYLINDRICAL", "EQUIANGULAR_CUBEMAP_FACE"):
        cam = Camera(projection="PANO", panorama_type=kind, latitude_min=-1.2, latitude_max=1.0,
                     longitude_min=-2.5, longitude_max=2.9, fisheye_fov=3.5, fisheye_lens=8.0,
                     to_world=np.array([[0, 0, 1, 1], [1, 0, 0, 2], [0, 1, 0, 3], [0, 0, 0, 1]], np.float32))
        o, d, tmax = generate_rays(cam, 60, 36, xy)
        inside = tmax > 0
        assert inside.mean() > 0.3
        film, depth = project(cam, 60, 36, o + 2.0 * d)
        np.testing.assert_allclose(film[inside], xy[inside], atol=2e-3)
        np.testing.assert_allclose(depth, 2.0 + cam.clip_start, rtol=1e-4)
        part = crop(cam, 60, 36, 10, 6, 20, 12)
        _, d2, _ = generate_rays(part, 20, 12, xy[:50] / 3)
        _, d3, _ = generate_rays(cam, 60, 36, xy[:50] / 3 + [10, 6])
        np.testing.assert_allclose(d2, d3, atol=1e-6)
        bad = Camera(projection="PANO", panorama_type=kind, latitude_min=0.3, latitude_max=0.3,
                     longitude_min=1.0, longitude_max=1.0, fisheye_fov=0.0, fisheye_lens=0.0,
                     fisheye_polynomial_k1=0.0, central_cylindrical_radius=0.0,
                     central_cylindrical_range_u_min=1.0, central_cylindrical_range_u_max=1.0)
        o, d, tmax = generate_rays(bad, 60, 36, xy)
        film, depth = project(bad, 60, 36, o + d)
        assert np.isfinite(o).all() and np.isfinite(d).all() and np.isfinite(tmax).all()
        assert np.isfinite(film).all() and np.isfinite(depth).all()


@pytest.mark.parametrize("mode", ["RESTIR_BIASED", "RESTIR_UNBIASED"])
def test_restir_with_panorama(mode):
    """The ReSTIR modes with an equirectangular camera inside the Cornell box,
    on frames of a moving camera (temporal reuse through the panorama's
    reprojection): finite, and the mean within 5 % of the path tracer's."""
    import dataclasses
    from restir_gi.core import Camera, RenderContext, RenderSettings, render_frame
    from restir_gi.core.render import render_restir
    from restir_gi.core.restir import BIASED, UNBIASED, ReSTIRGI, ReSTIRSettings
    from support.scenes import cornell_box, look_at
    scene = cornell_box("area", 48, 24)

    def view(f):
        return Camera(to_world=look_at((0.03 * f, -0.5, 1.0), (0.1 * f, 1.0, 1.0)), projection="PANO",
                      panorama_type="EQUIRECTANGULAR")

    scene.camera = view(0)
    base = RenderContext.build(scene)
    try:
        ref = render_frame(base, RenderSettings(samples=256, max_bounces=3, seed=1)).mean()
        settings = ReSTIRSettings(mode=BIASED if mode == "RESTIR_BIASED" else UNBIASED, max_bounces=3)
        restir = ReSTIRGI()
        result = render_restir(base, restir, settings, 0, 16, fresh=True)
        assert np.isfinite(result.color).all()
        first = float(result.color.mean() / ref.mean())
        for f in range(1, 4):           # the camera moves: reprojection
            ctx = dataclasses.replace(base, scene=dataclasses.replace(scene, camera=view(f)))
            result = render_restir(ctx, restir, settings, f, 1)
            assert np.isfinite(result.color).all()
        assert result.history_found > 0.5       # temporal reuse found its history
        print(f"{mode}: still {first:.4f} of path tracing, history found {result.history_found:.2f}")
        assert abs(first - 1.0) < 0.05
    finally:
        base.close()
