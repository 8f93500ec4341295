"""Final and animation renders: export, render passes, write the result.

Every failure becomes a report and a valid (black or partial) result; the
render never dies with a traceback.
"""

import time
import traceback

import numpy as np

from ..core import RenderContext, RenderSettings, render_frame
from ..core.film import to_rgba
from .export import export_scene
from .export.camera import render_size
from .passes import PASSES

UPDATE_INTERVAL = 1.0   # seconds between progressive result updates

# Seconds spent in each stage of the latest frame (for the benchmarks and the log).
last_timings = {}


def _settings(scene):
    s = scene.restir_gi
    return RenderSettings(mode=s.mode, samples=s.samples, max_bounces=s.max_bounces, seed=s.seed)


def _write(result, film, width, height):
    """Copy the film's mean and AOVs into the render result's passes."""
    layer = result.layers[0]
    combined = to_rgba(film.mean()) if film is not None else to_rgba(np.zeros((height, width, 3)))
    layer.passes["Combined"].rect.foreach_set(combined.ravel())
    if film is None:
        return
    for name, channels, _, _ in PASSES:
        p = layer.passes.get(name) if hasattr(layer.passes, "get") else None
        if p is None:
            continue
        key = {"Depth": "depth", "Normal": "normal", "Denoising Albedo": "albedo"}[name]
        data = film.aov(key, channels)
        if name == "Depth" and film.count == 0:
            data = np.full_like(data, 1e10)
        p.rect.foreach_set(np.nan_to_num(data, nan=0.0, posinf=1e10, neginf=0.0).astype(np.float32).ravel())


def render(engine, depsgraph):
    scene = depsgraph.scene
    width, height = render_size(scene)
    result = engine.begin_result(0, 0, width, height, layer=depsgraph.view_layer.name)
    film = None
    try:
        engine.update_stats("", "Exporting scene")
        t0 = time.perf_counter()
        core_scene, has_camera = export_scene(depsgraph, width, height)
        for text in core_scene.warnings:
            engine.report({"WARNING"}, text)
        if not has_camera:
            engine.report({"ERROR"}, "The scene has no camera: nothing to render")
            return
        if core_scene.triangle_count == 0:
            engine.report({"WARNING"}, "The scene has no geometry to render")
        ctx = RenderContext.build(core_scene)
        export_s = time.perf_counter() - t0
        settings = _settings(scene)
        last_update = [time.perf_counter()]

        def on_sample(f, seconds):
            engine.update_progress(f.count / settings.samples)
            engine.update_stats("", f"Frame {scene.frame_current} | Sample {f.count}/{settings.samples} "
                                    f"| {seconds:.1f} s (export {export_s:.2f} s)")
            now = time.perf_counter()
            if now - last_update[0] > UPDATE_INTERVAL:
                _write(result, f, width, height)
                engine.update_result(result)
                last_update[0] = now

        t1 = time.perf_counter()
        try:
            film = render_frame(ctx, settings, frame=scene.frame_current, on_sample=on_sample,
                                should_stop=engine.test_break)
        finally:
            ctx.close()
        render_s = time.perf_counter() - t1
        last_timings.clear()
        last_timings.update(export=export_s, trace=ctx.accel.trace_seconds,
                            shade=render_s - ctx.accel.trace_seconds, rays=ctx.accel.rays_traced)
        if film.count < settings.samples:
            engine.report({"INFO"}, f"Render cancelled after {film.count} of {settings.samples} samples")
    except Exception as exc:  # report, never kill the render
        traceback.print_exc()
        engine.report({"ERROR"}, f"ReSTIR GI render failed: {exc}")
    finally:
        t2 = time.perf_counter()
        try:
            _write(result, film, width, height)
        finally:
            engine.end_result(result)
        last_timings["write"] = time.perf_counter() - t2
