"""Volume objects (OpenVDB grids) against Cycles, in Path Tracing
(restir_addon/export/volume_objects.py, core/integrators/grid_media.py), and
bad input.

Each scene: a volume object whose .vdb file the test writes (a lumpy ball of
density, 40 voxels a side) over a lit floor, a sun and a grey world; both
engines at 64 spp. Mean within 2 % and block chi < 2.5, as the node tests.
"""

import numpy as np
import pytest

from support.volume_scenes import colour_waves, lumpy_ball, smoke_material, stage, volume_object, write_vdb

SAMPLES = 64
BOUNCES = 3


@pytest.mark.parametrize("case", ["principled", "attribute_scatter", "emission", "no_material", "fire",
                                  "fire_without_grid", "color"])
def test_vdb_matches_cycles(addon, tmp_path, case):
    """A lumpy ball of smoke from a .vdb file: its shading, its shadow on
    the floor and (with emission) the glow that fills its box as in Cycles;
    without a material both engines use their default volume shader. Fire:
    a blackbody whose temperature grid (a smaller ball, up to 1.2 x the
    Temperature of 1500 K) makes it glow, or without that grid the Temperature
    everywhere in the box. Colour: a colour grid on the density's voxels
    tints scattering and absorption."""
    from support.blender_util import compare_with_cycles
    scene = stage()
    grids = {"density": lumpy_ball()}
    if case == "fire":
        grids["temperature"] = np.clip(lumpy_ball() / 2.5, 0, 1.2)
    if case == "color":
        grids["color"] = colour_waves()
    path = write_vdb(tmp_path / "ball.vdb", grids)
    volume_object(path, material=None if case == "no_material" else smoke_material(case)[0])
    r = compare_with_cycles(scene, SAMPLES, BOUNCES, block=8)
    assert np.isfinite(r["ours"]).all()
    print(f"{case}: mean ours {r['ours_mean']:.4f} cycles {r['cycles_mean']:.4f} "
          f"ratio {r['ratio']:.4f} block chi {r['chi']:.2f}")
    assert abs(r["ratio"] - 1.0) < 0.02
    assert r["chi"] < 2.5


def test_vdb_can_fail(addon, tmp_path):
    """The comparison fails when the grid is misread: three times the
    density against Cycles' is far outside the tolerance."""
    from support.blender_util import block_error_after_change
    scene = stage()
    path = write_vdb(tmp_path / "ball.vdb", {"density": lumpy_ball()})
    mat, node = smoke_material("principled")
    volume_object(path, material=mat)
    error = block_error_after_change(scene, lambda: setattr(node.inputs["Density"], "default_value", 6.0),
                                     SAMPLES, BOUNCES)
    print(f"density x3: block error {error:.4f}")
    assert error > 0.01


def test_vdb_bad_input(addon, reports, tmp_path):
    """A grid of zeros, NaN voxels, a file with only a vector grid, a
    missing file and an object without a file: valid images in Path
    Tracing and a ReSTIR mode (which path-traces a frame with volumes),
    warnings that name each volume that is not rendered."""
    from support.addon_util import render_exr
    from restir_gi.core.camera.film import read_exr
    scene = stage(32, 24)
    nan = lumpy_ball()
    nan[10:20, 10:20, 10:20] = np.nan
    volume_object(write_vdb(tmp_path / "zeros.vdb", {"density": np.zeros((4, 4, 4), np.float32)}), "Zeros")
    volume_object(write_vdb(tmp_path / "nan.vdb", {"density": nan}), "NaN")
    volume_object(write_vdb(tmp_path / "vec.vdb", {"velocity": np.ones((4, 4, 4, 3), np.float32)}), "Vector")
    volume_object(str(tmp_path / "missing.vdb"), "Missing")
    volume_object("", "Empty")
    for mode in ("PATH", "RESTIR_BIASED"):
        scene.restir_gi.mode = mode
        reports.log.clear()
        render_exr(scene, tmp_path / f"{mode}.exr")
        img = read_exr(tmp_path / f"{mode}.exr")
        assert np.isfinite(img).all() and img.mean() > 0
        warnings = reports.of("WARNING")
        assert reports.of("ERROR") == []
        for name in ("Vector", "Missing", "Empty"):
            assert any(f"'{name}'" in w and "not rendered" in w for w in warnings), (name, reports.log)
        if mode != "PATH":
            assert any("by Path Tracing" in w for w in warnings), reports.log


def test_vdb_without_the_openvdb_module(addon, reports, tmp_path, monkeypatch):
    """A Blender without the openvdb module (a Linux distribution's build):
    one warning that says what to install, the volume left out, the image
    valid."""
    from support.addon_util import render_exr
    from restir_gi.core.camera.film import read_exr
    from restir_gi.restir_addon.export import volume_objects
    scene = stage(32, 24)
    path = write_vdb(tmp_path / "ball.vdb", {"density": lumpy_ball()})
    monkeypatch.setattr(volume_objects, "openvdb_module", lambda: None)
    volume_object(path, material=smoke_material("principled")[0])
    render_exr(scene, tmp_path / "out.exr")
    img = read_exr(tmp_path / "out.exr")
    assert np.isfinite(img).all() and img.mean() > 0
    warnings = [w for w in reports.of("WARNING") if "openvdb" in w]
    assert len(warnings) == 1 and "python3-openvdb" in warnings[0], reports.log
