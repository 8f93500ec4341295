"""The engine's viewport callbacks and the GPU drawing of the latest frame.

``view_update``, ``view_draw`` and ``free`` only hand work over to the engine's
ViewportSession: they create, configure and close it and draw its latest frame
(a few lines, skipped in background mode where bpy has no GPU).
"""

import traceback
from dataclasses import replace

import bpy
import numpy as np

from ..sync.objects import camera_from_region
from ..final import bounces, restir_settings
from .. import defaults
from .redraw import REDRAWS
from .session import ViewportSession


def session_settings(scene):
    """ViewportSession arguments from the scene's settings (viewport_* ones
    are optional: defaults when the scene has none). The viewport denoises
    with its own toggle (Viewport Denoise), not the final renders' one."""
    s = scene.restir_gi
    restir = replace(restir_settings(scene),
                     denoise=bool(getattr(s, "use_preview_denoising", defaults.VIEWPORT_DENOISE)))
    return dict(mode=s.mode, scale=getattr(s, "viewport_scale", defaults.VIEWPORT_SCALE),
                samples=getattr(s, "viewport_samples", defaults.VIEWPORT_SAMPLES),
                frame_budget=getattr(s, "viewport_frame_budget", defaults.VIEWPORT_FRAME_BUDGET),
                max_bounces=bounces(scene), seed=s.seed, restir=restir,
                denoise_start=getattr(s, "preview_denoising_start_sample", defaults.VIEWPORT_DENOISE_START))


def view_update(engine, context, depsgraph):
    try:
        session = getattr(engine, "viewport_session", None)
        if session is None:
            session = ViewportSession(**session_settings(depsgraph.scene))
            engine.viewport_session = session
            session.resize(context.region.width, context.region.height)
            session.set_view(camera_from_region(context.region_data, depsgraph.scene))
            session.sync(depsgraph)
            session.start()
            REDRAWS.watch(session)
            return
        session.configure(**session_settings(depsgraph.scene))
        session.sync(depsgraph, depsgraph.updates)
    except Exception as exc:  # noqa: BLE001 -- never let the viewport die with a traceback
        traceback.print_exc()
        engine.update_stats("", f"ReSTIR GI viewport failed: {exc}")


def view_draw(engine, context, depsgraph):
    session = getattr(engine, "viewport_session", None)
    if session is None:
        return
    try:
        region = context.region
        # Settings edited in a panel need not reach view_update (no depsgraph
        # update for add-on properties): compare them on every redraw (cheap).
        session.configure(**session_settings(depsgraph.scene))
        session.resize(region.width, region.height)
        session.set_view(camera_from_region(context.region_data, depsgraph.scene))
        serial, frame = session.frame_serial, session.frame    # the thread may replace it
        if frame is not None and not bpy.app.background:
            _draw(engine, depsgraph.scene, frame, serial, region.width, region.height)
        status = session.status()
        engine.update_stats("", f"ReSTIR GI | {status}")
        REDRAWS.drawn(session, serial, status)      # the next draw comes when there is news (redraw.py)
    except Exception as exc:  # noqa: BLE001 -- as above
        traceback.print_exc()
        engine.update_stats("", f"ReSTIR GI viewport failed: {exc}")


def _draw(engine, scene, frame, serial, width, height):
    """Draw a frame over the region through Blender's display transform (the
    texture is uploaded once per new frame)."""
    import gpu  # noqa: PLC0415 (Blender's GPU module: not in the bpy module the tests use)
    from gpu_extras.presets import draw_texture_2d  # noqa: PLC0415
    cached = getattr(engine, "viewport_texture", None)
    if cached is None or cached[0] != serial:
        frame = np.ascontiguousarray(frame, np.float32)
        h, w = frame.shape[:2]
        pixels = gpu.types.Buffer("FLOAT", w * h * 4, frame.ravel())
        texture = gpu.types.GPUTexture((w, h), format="RGBA16F", data=pixels)
        texture.filter_mode(True)   # a coarse frame (moving, refining) upscaled bilinearly, not in blocks
        cached = (serial, texture)
        engine.viewport_texture = cached
    gpu.state.blend_set("ALPHA_PREMULT")
    engine.bind_display_space_shader(scene)
    draw_texture_2d(cached[1], (0, 0), width, height)
    engine.unbind_display_space_shader()
    gpu.state.blend_set("NONE")


def free(engine):
    """The viewport closed: stop the render thread without waiting for it."""
    try:
        session = getattr(engine, "viewport_session", None)
    except Exception:   # noqa: BLE001 -- the engine's Blender data may already be gone
        return
    if session is not None:
        engine.viewport_session = None
        REDRAWS.forget(session)
        session.close(wait=False)
