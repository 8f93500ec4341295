"""Material, world and light previews (the Properties editor's): the engine
renders the preview scene Blender hands it with a few path-traced samples in
every mode, on threads, with a scene export of its own freed right after.
(The previews themselves are seen in a real window: tests/e2e/.)"""

import numpy as np
import pytest

from support.addon_util import MODES, FakeEngine, lit_plane_scene

NAMES = ["Combined", "Depth", "Normal", "Denoising Albedo"]


@pytest.mark.parametrize("mode", MODES)
def test_preview_renders_path_traced_samples_on_threads(addon, monkeypatch, mode):
    import bpy
    final, state = addon.restir_addon.final, addon.restir_addon.state
    lit_plane_scene(24, 16, samples=200, mode=mode)
    seen = []
    real = final.render_frame

    def recording(ctx, settings, **kwargs):
        seen.append((settings.mode, settings.samples, ctx.workers.processes))
        return real(ctx, settings, **kwargs)
    monkeypatch.setattr(final, "render_frame", recording)
    released = []
    real_free = state.Stream.free

    def free(stream):
        released.append(stream)
        real_free(stream)
    monkeypatch.setattr(state.Stream, "free", free)
    streams = state.stream_count()

    engine = FakeEngine(NAMES)
    engine.is_preview = True
    final.render(engine, bpy.context.evaluated_depsgraph_get())

    assert seen == [("PATH", final.PREVIEW_SAMPLES, False)]
    assert engine.ended and not [m for k, m in engine.log if k == "ERROR"]
    img = engine.pixels["Combined"].reshape(16, 24, 4)
    assert np.isfinite(img).all() and img[..., :3].mean() > 0.05
    assert state.stream_count() == streams          # nothing kept for later renders
    assert len(released) == 1 and released[0].frame_scene.scene is None
