"""Memory of ReSTIR GI's state: the bytes per pixel a frame keeps for the
next (docs/memory.md) match the arrays actually held, and the add-on refuses
a resolution whose render would not fit, with a report and a valid image."""

import numpy as np
import pytest

from restir_gi.core import RenderContext
from restir_gi.core.restir import BIASED, UNBIASED, ReSTIRGI, ReSTIRSettings
from restir_gi.core.restir.temporal import state_bytes_per_pixel
from support.moving_card import OCCLUDER, SIZE, scene_with
from support.scenes import cornell_box


@pytest.mark.parametrize("narrow,denoise", [(True, False), (False, False), (False, True)])
@pytest.mark.parametrize("accumulate", [16, 1])
@pytest.mark.parametrize("mode", [BIASED, UNBIASED])
def test_state_size_matches_the_arrays_held(mode, accumulate, narrow, denoise, monkeypatch):
    """Narrow reservoirs (images of NARROW_MIN_PIXELS and more) and float32
    ones; with the denoiser, its moments in the running means."""
    import restir_gi.core.restir.reservoirs as store
    if narrow:
        monkeypatch.setattr(store, "NARROW_MIN_PIXELS", 1)
    scene = cornell_box("area", 40, 24)
    ctx = RenderContext.build(scene)
    try:
        restir = ReSTIRGI()
        settings = ReSTIRSettings(mode=mode, max_bounces=2, seed=1, accumulate=accumulate, denoise=denoise)
        for f in range(2):
            restir.render_frame(ctx, settings, f)
        assert restir.nbytes == 40 * 24 * state_bytes_per_pixel(accumulate > 1, pixels=40 * 24, denoise=denoise,
                                                                moving=False)
    finally:
        ctx.close()


@pytest.mark.parametrize("accumulate", [16, 1])
def test_state_size_counts_the_light_probes_where_objects_move(accumulate):
    """Frames where objects moved keep a light probe per pixel
    (core/restir/light_probes.py) when they accumulate."""
    restir = ReSTIRGI()
    settings = ReSTIRSettings(max_bounces=2, seed=1, accumulate=accumulate)
    for f, x in enumerate((0.0, 0.1)):
        ctx = RenderContext.build(scene_with(OCCLUDER, x))
        try:
            restir.render_frame(ctx, settings, f)
        finally:
            ctx.close()
    assert (restir.history.light_probe is not None) == (accumulate > 1)
    assert restir.nbytes == SIZE * SIZE * state_bytes_per_pixel(accumulate > 1, pixels=SIZE * SIZE)


@pytest.mark.parametrize("mode", [BIASED, UNBIASED])
def test_narrow_state_changes_images_by_float16_rounding_only(mode, monkeypatch):
    """Large images store their whole-image reservoirs narrowed
    (core/restir/reservoirs.py). Against the same frames with float32
    reservoirs (as small images keep them), what does not depend on them is
    bit for bit the same and the indirect light differs by about float16's
    rounding of the reused radiance, but for a choice it flips here and there."""
    import restir_gi.core.restir.reservoirs as store
    scene = cornell_box("area", 48, 32)

    def frames():
        ctx = RenderContext.build(scene)
        try:
            restir = ReSTIRGI()
            settings = ReSTIRSettings(mode=mode, max_bounces=2, seed=4)
            return [restir.render_frame(ctx, settings, f) for f in range(4)]
        finally:
            ctx.close()

    wide = frames()
    monkeypatch.setattr(store, "NARROW_MIN_PIXELS", 1)
    narrow = frames()
    assert not np.array_equal(narrow[-1].indirect, wide[-1].indirect)
    for a, b in zip(narrow, wide):
        for name in ("direct", "normal", "albedo", "depth", "alpha"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert (a.M == b.M).mean() > 0.99
        scale = max(float(np.abs(b.indirect).mean()), 1e-6)
        # Rounding can flip a resampling choice (which candidate wins) in
        # a pixel or two; elsewhere the difference is the rounding's.
        diff = np.abs(a.indirect - b.indirect)
        far = diff.max(axis=1) >= 2e-3 * max(float(np.abs(b.indirect).max()), 1e-6)
        assert diff[~far].mean() < 5e-4 * scale
        assert far.mean() < 0.005, int(far.sum())


def test_documented_bytes_per_pixel():
    """docs/memory.md states the figure this computes."""
    from pathlib import Path
    text = (Path(__file__).resolve().parents[2] / "docs" / "memory.md").read_text()
    assert f"{state_bytes_per_pixel()} bytes per pixel" in text


def test_a_render_too_large_is_refused_with_a_report(addon, reports, tmp_path, monkeypatch):
    import bpy
    from support.addon_util import add_mesh, camera, fresh, rect, world
    scene = fresh(64, 48, samples=1, mode="RESTIR_BIASED")
    scene.restir_gi.warmup_frames = 1
    world((0.5, 0.5, 0.5))
    add_mesh("Floor", *rect(-2, 2, -2, 2))
    camera(location=(0, 0, 5), type="ORTHO", ortho_scale=4.0)
    memory = addon.restir_addon.memory
    monkeypatch.setattr(memory, "available_bytes", lambda: 1_000_000)
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(tmp_path / "big.exr")
    with pytest.raises(RuntimeError):                   # bpy raises on an ERROR report
        bpy.ops.render.render(write_still=True)
    errors = reports.of("ERROR")
    assert len(errors) == 1 and "64x48" in errors[0] and "GB" in errors[0], errors
    # Blender stays usable: with the memory there, the same render works.
    monkeypatch.setattr(memory, "available_bytes", lambda: 8 * 1024 ** 3)
    reports.log.clear()
    bpy.ops.render.render(write_still=True)
    assert reports.of("ERROR") == []
    from restir_gi.core.camera.film import read_exr
    img = read_exr(tmp_path / "big.exr")
    assert img.shape[:2] == (48, 64) and np.isfinite(img).all() and img.mean() > 0


def test_viewport_falls_back_to_a_coarser_scale_or_reports(addon, monkeypatch):
    """The viewport's ReSTIR image must fit too: the AUTO scale goes coarser
    until it does; a fixed scale that does not fit stops with the message."""
    from support.addon_util import add_mesh, camera, fresh, rect, world
    import bpy
    fresh(64, 48, samples=1, mode="RESTIR_BIASED")
    world((0.5, 0.5, 0.5))
    add_mesh("Floor", *rect(-2, 2, -2, 2))
    camera(location=(0, 0, 5), type="ORTHO", ortho_scale=4.0)
    memory = addon.restir_addon.memory
    per_pixel = memory.RESTIR_BYTES_PER_PIXEL
    # Room for a quarter of the pixels and a little more, not for half of them.
    monkeypatch.setattr(memory, "available_bytes",
                        lambda: int((memory.RESTIR_FIXED_BYTES + 64 * 48 / 4 * per_pixel * 1.1)
                                    / memory.IMAGE_BUDGET_SHARE))
    vp = addon.restir_addon.viewport.session
    for scale, expected in (("AUTO", (32, 24)), ("FULL", None)):
        session = vp.ViewportSession(mode="RESTIR_BIASED", scale=scale, threads=1, max_bounces=1)
        session._divisor = 1                                # as if AUTO had gone fine
        session.sync(bpy.context.evaluated_depsgraph_get())
        try:
            if expected is None:
                with pytest.raises(memory.SceneTooLarge, match="64x48"):
                    session.render_step()
            else:
                assert session.render_step()
                assert session.render_size == expected
        finally:
            session.close()


def test_state_already_held_counts_as_available(addon):
    """Frame 2 of an animation holds frame 1's state, which the per-pixel
    figure already includes: it must not be refused for it."""
    memory = addon.restir_addon.memory
    need = memory.image_bytes(100, 100)
    short = int(need / memory.IMAGE_BUDGET_SHARE) - 10_000
    with pytest.raises(memory.SceneTooLarge):
        memory.check_image(100, 100, available=short)
    memory.check_image(100, 100, available=short, held=100 * 100 * state_bytes_per_pixel())


def test_a_still_lets_its_state_go_and_an_animation_keeps_it(addon, tmp_path):
    """Nothing continues a still render, so its reservoirs are released before
    the images go to Blender; an animation frame keeps them for the next."""
    import bpy
    from support.addon_util import add_mesh, camera, fresh, rect, world
    scene = fresh(32, 24, samples=1, mode="RESTIR_BIASED")
    scene.restir_gi.warmup_frames = 2
    world((0.5, 0.5, 0.5))
    add_mesh("Floor", *rect(-2, 2, -2, 2))
    camera(location=(0, 0, 5), type="ORTHO", ortho_scale=4.0)
    scene.render.image_settings.file_format = "OPEN_EXR"
    stream = addon.restir_addon.state.stream_for(scene.name, bpy.context.view_layer.name)
    scene.render.filepath = str(tmp_path / "still.exr")
    bpy.ops.render.render(write_still=True)
    assert stream.restir.history is None and stream.restir.nbytes == 0
    from restir_gi.core.camera.film import read_exr
    img = read_exr(tmp_path / "still.exr")
    assert np.isfinite(img).all() and img.mean() > 0
    scene.frame_start, scene.frame_end = 1, 2
    scene.render.filepath = str(tmp_path / "f_####")
    bpy.ops.render.render(animation=True)
    assert stream.restir.history is not None and stream.last_frame == 2
