"""Final and animation renders: export, render, write the result's passes.

The scene is kept between the frames of an animation (frame_scene.py): a
frame reads and rebuilds only what changed since the previous one.

Path tracing accumulates ``samples`` passes per frame. The ReSTIR GI modes run
``samples`` frames of resampling per animation frame, carrying reservoirs and
each pixel's running mean from the previous frame (state.py); a still render,
or a frame that does not follow the last one rendered, runs ``warmup_frames``
frames on the still scene and writes their mean (core/render.py). An
animation render that starts after the scene's first frame (a chunk of a farm
render) first runs the ``chunk_warmup_frames`` frames before it along the
animation, writing nothing, as if the animation had started there
(``_chunk_warmup``). With stereoscopy every view is rendered into a result
of its own, from Blender's stereo rig, with reservoirs of its own (state.py);
a render region renders as an image of its own through a cropped camera.

Every failure becomes a report and a valid (black or partial) result; the
render never dies with a traceback.
"""

import time
import traceback

import numpy as np

from ..core import RenderSettings, render_frame
from ..core.camera.projection import camera_space_normals
from ..core.util.errors import describe
from ..core.lights.environment import scene_environment
from ..core.camera.film import to_rgba
from ..core.integrators.bounces import Bounces
from ..core.integrators.media import media_of
from ..core.object_motion import ShutterMotion
from ..core.render import render_restir
from ..core.restir import ReSTIRSettings
from . import defaults, memory, state
from .export.camera import render_region
from .memory import SceneTooLarge
from .render_camera import moving_camera, view_camera, view_names
from .passes import NOISY, PASSES

UPDATE_INTERVAL = 1.0   # seconds between progressive result updates
# Frames of resampling on the still scene where a chunk warm-up starts after
# frame_start (None: warmup_frames, as a first frame; bench/bench_chunks.py).
CHUNK_FRESH_FRAMES = None

# Material, world and light previews (Properties editor): path-traced samples.
PREVIEW_SAMPLES = 16


def bounces(scene):
    """Render > Light Paths: the total and per-kind limits (as Cycles counts)."""
    s = scene.restir_gi
    cycles = getattr(scene, "cycles", None)     # Light Paths > Volume is Cycles' own setting (default 0)
    return Bounces(s.max_bounces, getattr(s, "diffuse_bounces", None), getattr(s, "glossy_bounces", None),
                   getattr(s, "transmission_bounces", None), volume=int(getattr(cycles, "volume_bounces", 0)))


def path_settings(scene, samples=None):
    s = scene.restir_gi
    return RenderSettings(mode="PATH" if samples else s.mode, samples=samples or s.samples,
                          max_bounces=bounces(scene), seed=s.seed)


def restir_settings(scene):
    s = scene.restir_gi
    return ReSTIRSettings(
        mode=s.mode, samples=1, max_bounces=bounces(scene), seed=s.seed,
        accumulate=s.accumulate_frames,
        initial_sampling=s.initial_sampling, temporal_M_cap=float(s.temporal_m_cap),
        spatial_M_cap=float(s.spatial_m_cap), max_age=s.max_age,
        spatial_neighbors=s.spatial_neighbors, spatial_radius=float(s.spatial_radius),
        validation_interval=s.validation_interval, validate_on_change=True, light_samples=s.light_samples,
        sky_samples=s.sky_samples, boiling_filter=float(s.boiling_filter),
        denoise=bool(getattr(s, "use_denoising", defaults.DENOISE)))


def denoising_normal(normal, camera):
    """Denoising Normal (H, W, 3) of the Normal pass (H, W, 3, world space):
    in camera space, as Cycles writes it (None without a camera)."""
    if camera is None:
        return None
    return camera_space_normals(camera, normal.reshape(-1, 3)).reshape(normal.shape)


def film_images(film, camera=None):
    """Pass name -> (H, W, C) float32 from a path-traced Film; Combined's
    alpha: coverage by geometry with Film > Transparent, less holdouts.
    camera: the scene's core Camera, for Denoising Normal."""
    alpha = film.aov("alpha", 1) if film.count else 1.0
    images = {"Combined": to_rgba(film.mean(), alpha), "Depth": film.aov("depth", 1),
              "Normal": film.aov("normal", 3), "Denoising Albedo": film.aov("albedo", 3)}
    images["Denoising Normal"] = denoising_normal(images["Normal"], camera)
    if film.count == 0:
        images["Depth"] = np.full_like(images["Depth"], 1e10)
    return images


def frame_images(frame, width, height, camera=None):
    """Pass name -> (H, W, C) float32 from a ReSTIR GI FrameResult (Noisy
    Image when it was denoised). camera: the scene's core Camera, for
    Denoising Normal."""
    shape = (height, width)
    reservoir = np.stack([frame.M, frame.W, np.zeros_like(frame.M)], axis=1)
    alpha = frame.alpha.reshape(*shape, 1) if frame.alpha is not None else 1.0
    normal = frame.normal.reshape(*shape, 3)
    images = {"Combined": to_rgba(frame.color.reshape(*shape, 3), alpha),
              "Depth": frame.depth.reshape(*shape, 1), "Normal": normal,
              "Denoising Normal": denoising_normal(normal, camera),
              "Denoising Albedo": frame.albedo.reshape(*shape, 3),
              "ReSTIR Direct": frame.direct.reshape(*shape, 3),
              "ReSTIR Indirect": frame.indirect.reshape(*shape, 3),
              "ReSTIR Reservoir": reservoir.reshape(*shape, 3)}
    if frame.noisy is not None:
        images[NOISY[0]] = to_rgba(frame.noisy.reshape(*shape, 3), alpha)
    return images


def _write(result, images, width, height):
    """Copy images into the render result's passes (black where missing);
    the result is one view's (render_view)."""
    layer = result.layers[0]
    if images is None:
        images = {"Combined": to_rgba(np.zeros((height, width, 3), np.float32))}
    ours = {name for name, _, _, _ in PASSES} | {"Combined", NOISY[0]}
    for p in layer.passes.values():
        data = images.get(p.name) if p.name in ours else None
        if data is None:
            continue
        if p.name not in ("Combined", NOISY[0]):
            data = np.asarray(data, np.float32)
            if not np.isfinite(data).all():     # (a test, not a copy, in the common case)
                data = np.nan_to_num(data, nan=0.0, posinf=1e10, neginf=0.0)
        p.rect.foreach_set(data.ravel())


def _render_path(engine, ctx, scene, result, width, height, export_s, samples=None):
    settings = path_settings(scene, samples)
    last_update = [time.perf_counter()]

    def on_sample(f, seconds):
        engine.update_progress(f.count / settings.samples)
        engine.update_stats("", f"Frame {scene.frame_current} | Sample {f.count}/{settings.samples} "
                                f"| {seconds:.1f} s (export {export_s:.2f} s)")
        now = time.perf_counter()
        if now - last_update[0] > UPDATE_INTERVAL:
            _write(result, film_images(f, ctx.scene.camera), width, height)
            engine.update_result(result)
            last_update[0] = now

    film = render_frame(ctx, settings, frame=scene.frame_current, on_sample=on_sample,
                        should_stop=engine.test_break)
    if film.count < settings.samples:
        engine.report({"INFO"}, f"Render cancelled after {film.count} of {settings.samples} samples")
    return film_images(film, ctx.scene.camera)


def _camera_name(scene):
    return scene.camera.name if scene.camera is not None else None


def _follows(engine, stream, scene, ctx):
    """Reuse continues only into the next frame of an animation of the same
    shot: a jump in time or a cut (_same_shot) starts over, with the warm-up
    of a first frame."""
    return _next_frame(engine, stream, scene) and _same_shot(stream, scene, ctx)


def _next_frame(engine, stream, scene):
    """This frame of an animation comes right after the stream's last one,
    one Frame Step on (else an animation render began here, after the
    scene's first frame: _chunk_warmup; a cut at this frame needs none, the
    shot starts here). With a Frame Step of 2 or more the frames between are
    not rendered: reuse reprojects over the larger motion, as it does for a
    fast camera, so each written frame costs one frame of resampling."""
    step = max(1, int(getattr(scene, "frame_step", 1)))
    return (engine.is_animation and stream.last_frame is not None
            and scene.frame_current == stream.last_frame + step and stream.restir.history is not None)


def _same_shot(stream, scene, ctx):
    """This frame continues the shot of the stream's last frame: the same
    camera object (timeline markers switch cameras) that did not jump."""
    return _camera_name(scene) == stream.last_camera and not jumped(stream.last_view, ctx.scene.camera,
                                                                     ctx.scene.extent())


CUT_ANGLE = 30.0        # degrees the view direction may turn between two frames of a shot
CUT_MOVE = 0.2          # share of the scene's extent the camera may move between them
CUT_ZOOM = 2.0          # ratio of focal lengths (or orthographic scales) between them


def jumped(prev, cur, extent):
    """Whether the camera jumped between two frames as at a cut (a shot cut
    made with constant keyframes on one camera, a whip pan): its view
    turned by more than CUT_ANGLE, it moved by more than CUT_MOVE of the
    scene's extent, its zoom changed by more than CUT_ZOOM times, or its
    projection changed. Reuse then starts over, with the warm-up of a first
    frame: the history of the other view only ghosts into this one."""
    if prev is None or cur is None:
        return False
    if prev.projection != cur.projection:
        return True
    a, b = np.asarray(prev.to_world, np.float64), np.asarray(cur.to_world, np.float64)
    da, db = -a[:3, 2] / np.linalg.norm(a[:3, 2]), -b[:3, 2] / np.linalg.norm(b[:3, 2])
    if float(np.dot(da, db)) < np.cos(np.radians(CUT_ANGLE)):
        return True
    if float(np.linalg.norm(a[:3, 3] - b[:3, 3])) > CUT_MOVE * extent:
        return True
    za, zb = (prev.lens, cur.lens) if cur.projection == "PERSP" else (prev.ortho_scale, cur.ortho_scale)
    return not (za > 0 and zb > 0 and 1.0 / CUT_ZOOM <= zb / za <= CUT_ZOOM)


def _chunk_warmup(engine, depsgraph, stream, width, height, view=None):
    """The first frame N of an animation render that starts after the
    animation's first frame (state.animation_start: frame_start, or where it
    was before the command line's -s moved it): render frames
    max(that, N - chunk_warmup_frames) .. N - 1 along the animation (the
    scene evaluated at each, so reprojection
    follows the real motion) and write nothing, so frame N continues from the
    history a render started at that frame would have. Reaching back to the
    animation's first frame, the frames are those of the continuous render,
    random numbers included. Returns False if cancelled."""
    scene = depsgraph.scene
    frame = scene.frame_current
    start = state.animation_start(scene)
    first = max(start, frame - scene.restir_gi.chunk_warmup_frames)
    if first >= frame:
        return True
    memory.check_image(width, height, held=stream.restir.nbytes)
    settings = restir_settings(scene)
    frame_scene = stream.frame_scene

    def restart():
        stream.restir.reset()
        stream.last_frame = None

    restart()
    start = time.perf_counter()
    try:
        for f in range(first, frame):
            if engine.test_break():
                return False
            engine.frame_set(f, 0.0)
            camera = view_camera(engine, depsgraph, view, frame_scene.warnings)
            if not frame_scene.update(depsgraph, width, height, camera) or frame_scene.context is None:
                restart()
                continue
            if stream.last_frame is not None and not _same_shot(stream, scene, frame_scene.context):
                restart()           # a cut within the warm-up: the frames before it are another shot
            fresh = stream.last_frame is None
            frames = scene.restir_gi.samples
            if fresh:
                frames = scene.restir_gi.warmup_frames if f == start or \
                    CHUNK_FRESH_FRAMES is None else CHUNK_FRESH_FRAMES
            engine.update_stats("", f"Frame {frame} | chunk warm-up: frame {f} "
                                    f"({f - first + 1}/{frame - first}) "
                                    f"| {time.perf_counter() - start:.1f} s")
            out = render_restir(frame_scene.context, stream.restir, settings, f, frames,
                                fresh=fresh, should_stop=engine.test_break)
            if out is None:
                restart()
                return False
            stream.last_frame, stream.last_camera = f, _camera_name(scene)
            stream.last_view = frame_scene.context.scene.camera
    finally:
        engine.frame_set(frame, 0.0)
        frame_scene.update(depsgraph, width, height, view_camera(engine, depsgraph, view, frame_scene.warnings))
    return True


def _render_restir(engine, ctx, scene, stream, width, height, export_s):
    memory.check_image(width, height, held=stream.restir.nbytes)
    settings = restir_settings(scene)
    frame = scene.frame_current
    camera = _camera_name(scene)
    follows = _follows(engine, stream, scene, ctx)
    if not follows:
        stream.restir.reset()
    frames = scene.restir_gi.samples if follows else scene.restir_gi.warmup_frames
    start = time.perf_counter()
    done = [0]

    def on_frame(i, _result):
        done[0] = i + 1
        engine.update_progress((i + 1) / frames)
        engine.update_stats("", f"Frame {frame} | ReSTIR frame {i + 1}/{frames} "
                                f"| {time.perf_counter() - start:.1f} s (export {export_s:.2f} s)")

    out = render_restir(ctx, stream.restir, settings, frame, frames, fresh=not follows,
                        on_frame=on_frame, should_stop=engine.test_break)
    stream.last_frame, stream.last_camera, stream.last_view = frame, camera, ctx.scene.camera
    if out is None:
        engine.report({"INFO"}, "Render cancelled before the first frame finished")
        stream.restir.reset()
        return None
    if done[0] < frames:
        engine.report({"INFO"}, f"Render cancelled after {done[0]} of {frames} frames of resampling")
    return frame_images(out, width, height, ctx.scene.camera)


def render(engine, depsgraph):
    """A frame: every view of it (one without stereoscopy), each into a
    result of its own; the export's warnings are reported with the first."""
    if engine.is_preview:
        _render_preview(engine, depsgraph)
        return
    for i, view in enumerate(view_names(depsgraph.scene)):
        _render_view(engine, depsgraph, view, report=i == 0)
        if engine.test_break():
            break


def _render_preview(engine, depsgraph):
    """A material, world or light preview of the Properties editor: a few
    path-traced samples, whatever the mode (no warm-up; a preview is small
    and seen for a moment). Its scene export is its own and freed right
    after, and it runs on threads only: previews render in a job beside
    Blender's UI, often several at once, and a twin process is for render
    loops that own the machine. Unsupported nodes fall back as in renders;
    their warnings are not reported (the preview has no report to show)."""
    stream = state.Stream()
    stream.frame_scene.twin_process = False
    try:
        _render_view(engine, depsgraph, None, stream=stream, preview=True)
    finally:
        stream.free()


def _render_view(engine, depsgraph, view, report=True, stream=None, preview=False):
    scene = depsgraph.scene
    # With a render region Blender's result is the region's size (cropped
    # or not): the region is rendered as an image of its own.
    width, height = render_region(scene)[2:]
    result = engine.begin_result(0, 0, width, height, layer=depsgraph.view_layer.name, view=view or "")
    images = None
    try:
        engine.update_stats("", "Exporting scene")
        if stream is None:
            stream = state.stream_for(scene.name, depsgraph.view_layer.name, view)
        # A still is never continued (a render continues only an animation's
        # previous frame): its ReSTIR state is let go after its last frame,
        # before the images are copied to Blender, where a still peaks.
        stream.restir.keep_history = bool(engine.is_animation)
        # An animation reports what the frames' exports warn about once, with
        # the first frame that finds it (in every mode).
        continuing = engine.is_animation and stream.reported_frame == scene.frame_current - 1
        frame_scene = stream.frame_scene
        # A later view of the frame changes only the camera of the exported scene.
        camera = view_camera(engine, depsgraph, view, frame_scene.warnings)
        blur_notes, moving, deformed = [], {}, {}
        if view is None and not preview:
            camera, moving, deformed = moving_camera(engine, depsgraph, blur_notes.append,
                                                     objects=scene.restir_gi.mode == "PATH")
        has_camera = frame_scene.update(depsgraph, width, height, camera, camera_only=not report)
        for text in blur_notes:        # after the update, which may start its warnings over
            frame_scene.warnings(text)
        if frame_scene.scene is not None:       # objects' motion blur (core/object_motion.py)
            frame_scene.scene.shutter_motion = ShutterMotion.of(frame_scene.scene, moving, deformed) \
                if moving or deformed else None
        for text in frame_scene.new_warnings(repeat=not continuing) if report and not preview else ():
            engine.report({"WARNING"}, text)
        if report and not preview:
            stream.reported_frame = scene.frame_current if engine.is_animation else None
        core_scene, ctx = frame_scene.scene, frame_scene.context
        if not has_camera:
            engine.report({"ERROR"}, "The scene has no camera: nothing to render")
            return
        if core_scene is None or ctx is None:
            engine.report({"ERROR"}, "The scene could not be prepared for rendering")
            return
        if core_scene.triangle_count == 0 and not core_scene.volume_grids:
            engine.report({"WARNING"}, "The scene has no geometry to render")
        emissive = len(ctx.lights.tri_index) > 0
        lit = len(core_scene.lights) and bool((np.asarray(core_scene.lights.power) > 0).any())
        if not (lit or scene_environment(core_scene) is not None or emissive):
            engine.report({"WARNING"}, "The scene has no light source (no lights, emissive "
                                       "materials or world light): the image is black")
        # Volumes are path-traced (core/integrators/media_path.py): a ReSTIR
        # mode renders a frame with media as Path Tracing with its warm-up
        # frames as samples, rather than leave them out.
        media_samples = None
        if not preview and scene.restir_gi.mode != "PATH" and media_of(core_scene, ctx.eps) is not None:
            media_samples = max(1, int(scene.restir_gi.warmup_frames))
            engine.report({"WARNING"}, f"Volumes: the ReSTIR modes render a frame with volumes by Path Tracing "
                                       f"({media_samples} samples, the warm-up frames)")
        read_s, apply_s = frame_scene.timings
        export_s = read_s + apply_s
        trace_before, rays_before = ctx.accel.trace_seconds, ctx.accel.rays_traced
        t1 = time.perf_counter()
        if preview:
            images = _render_path(engine, ctx, scene, result, width, height, export_s, PREVIEW_SAMPLES)
        elif scene.restir_gi.mode == "PATH" or media_samples:
            images = _render_path(engine, ctx, scene, result, width, height, export_s, media_samples)
        else:
            if engine.is_animation and not _next_frame(engine, stream, scene):
                if not _chunk_warmup(engine, depsgraph, stream, width, height, view):
                    engine.report({"INFO"}, "Render cancelled during the chunk warm-up")
                    return
                ctx = frame_scene.context
            images = _render_restir(engine, ctx, scene, stream, width, height, export_s)
        render_s = time.perf_counter() - t1
        trace_s = ctx.accel.trace_seconds - trace_before
        stream.timings = dict(export=read_s, accel=apply_s, render=render_s, trace=trace_s,
                              shade=render_s - trace_s, rays=ctx.accel.rays_traced - rays_before)
    except SceneTooLarge as exc:
        engine.report({"ERROR"}, str(exc))
    except Exception as exc:  # noqa: BLE001 -- report, never kill the render
        traceback.print_exc()
        engine.report({"ERROR"}, f"ReSTIR GI render failed: {describe(exc)}")
    finally:
        t2 = time.perf_counter()
        try:
            _write(result, images, width, height)
        finally:
            engine.end_result(result)
        if stream is not None:
            stream.timings["write"] = time.perf_counter() - t2
