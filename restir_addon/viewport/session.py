"""Viewport rendered mode: incremental scene sync and progressive frames.

``ViewportSession`` holds everything one 3D viewport renders with and is driven
the same way by the engine and by tests:

- ``sync(depsgraph, updates)`` reads what changed from Blender (UI thread):
  a transform-only change reads the new matrices (no mesh data), a geometry
  change re-reads that object's mesh only, material, light and world edits
  replace their table and never touch triangles or the Embree scenes.
- ``set_view(camera)`` and ``resize(width, height)`` take the viewport's
  camera and size (a resize never re-exports).
- ``render_step(time_budget)`` applies the queued changes to the core scene
  (moved objects go to the small dynamic Embree scene of
  ``core.geometry.dynamic_accel``) and renders one frame: a ReSTIR GI frame that keeps
  its reservoirs through camera and object motion, or one more path-traced
  sample. A still view is refined progressively (progress.py):
  coarse frames step to full resolution, carrying what they learnt, then
  frames are averaged until ``samples`` frames (0: no limit) or convergence.
- ``start()`` runs ``render_step`` on a background thread (one per session),
  which never calls bpy; ``close()`` stops it (the frame in progress is
  abandoned at its next ray batch) and frees the buffers.

Only ``sync`` touches bpy; everything it read is queued under a lock and
applied by ``render_step`` between two frames, so the render thread never
sees a scene half-updated.

Here: the session, its settings, the hand-over between the threads and the
frame loop. The stages of a still view's refinement and the resolution of
each frame are in progress.py (Progress, Refinement). What sync reads is
in ../sync/reader.py (SceneReader), how the render side applies it in
../sync/applier.py (SceneApplier), the bookkeeping (Work, Update, Pending)
in ../sync/state.py. The reading of meshes and cameras is in
../sync/objects.py, the combined world-space arrays of all objects in
../sync/arrays.py; the engine's callbacks (``view_update``, ``view_draw``, ``free``) and the GPU drawing are
in draw.py.
"""

import threading
import time
import traceback
from dataclasses import replace

import numpy as np

from ...core.integrators.bounces import Bounces
from ...core.geometry.dynamic_accel import TraceInterrupted
from ...core.util.errors import describe
from ...core.camera.film import to_rgba
from ...core.integrators.media import media_of
from ...core.render import RenderSettings, render_frame, render_restir
from ...core.restir import ReSTIRGI, ReSTIRSettings
from ...core.restir.accumulation import STILL
from .. import defaults
from ..sync.scene_sync import SceneSync
from .progress import SCALES, Progress, Refinement, relative_change
from ..sync.objects import same_camera
from ..sync.state import Update, as_update  # noqa: F401 (re-exported for tests)
from ..sync.objects import camera_from_region, camera_from_view  # noqa: F401

PATH = "PATH"

# An edit abandons the frame in progress and starts over with it: the frame
# would show the scene before the edit, and finishing it only delays the one
# the user waits for (bench/bench_viewport.py, "threaded"). Never two frames in
# a row, so a continuous drag still gets frames out.


class ViewportSession(Refinement, SceneSync):
    """The state of one viewport: scene, acceleration structure, reservoirs or
    accumulated samples, the latest frame, and counters of the work done.

    mode: "PATH", "RESTIR_BIASED" or "RESTIR_UNBIASED". scale: "AUTO", "FULL",
    "HALF" or "QUARTER" (AUTO: while the view moves the finest scale whose
    frame time fits frame_budget, on a still view stepping to full
    resolution). samples: frames (path tracing: samples) of a still view
    before the viewport stops, 0 for no limit; settle_frames: frames without
    edits before moved objects rejoin the static Embree scene; restir: the
    ReSTIRSettings to start from (None: the defaults, with the denoiser as
    defaults.VIEWPORT_DENOISE says); denoise_start: with the denoiser on, the first
    sample of a still view shown denoised (the ones before are shown as
    accumulated; the frames right after a change count as sample 1).
    """

    # Small ReSTIR frames run in two processes where the platform forks, as
    # final renders do (core/workers/forked.py): on two threads a 320x180
    # frame's short numpy calls hand the GIL over at every call
    # (bench/bench_viewport.py --no-twin: 2.4-2.6 frames/s against 3.9-4.0).
    # Between frames the twin is parked and sent the new view, or the scene's
    # edits (core/render.render_restir's Continuation); a frame abandoned for
    # an edit is unwound by both processes and the twin kept (a fork anew
    # would cost ~10 ms, and about 0.1 s of copy-on-write page faults in the
    # restarted frame: docs/performance.md, "The viewport"). Above
    # twin_max_pixels frames stay on threads, whose calls are long enough to
    # overlap: at 524x347 the twin took 0.72 s a frame against 0.76 s
    # headless, and 1.7 s against 1.26 s in the real window (one run each),
    # where the software-drawn view takes a share of the cores.
    # A twin that does not answer within a second, or four times the
    # leader's half of a pass, is left and the session goes on without one
    # (parallel.Workers): the view must not freeze for the final renders' 30 s.
    twin_process = True
    twin_wait = (1.0, 4.0)
    twin_max_pixels = 1 << 17

    def __init__(self, mode="RESTIR_BIASED", scale=defaults.VIEWPORT_SCALE, samples=defaults.VIEWPORT_SAMPLES,
                 frame_budget=defaults.VIEWPORT_FRAME_BUDGET, settle_frames=defaults.VIEWPORT_SETTLE_FRAMES,
                 max_bounces=4, seed=0, restir=None, denoise_start=defaults.VIEWPORT_DENOISE_START, threads=None):
        super().__init__(threads)
        self.progress = Progress(samples)
        self._set_settings(mode, scale, samples, frame_budget, settle_frames, max_bounces, seed,
                           restir, denoise_start)
        self._stop = False
        self._frame_started = None      # perf_counter() when the frame in progress started
        self._frame_is_restart = False  # the frame in progress replaces an abandoned one
        self._next_is_restart = False
        self._thread = None
        self._restir = ReSTIRGI()
        self._frame_index = 0
        self._divisor = None
        self._fits = None               # (width, height, divisor) whose image was found to fit
        self._memory_floor = (None, 1)  # (display size, finest divisor that fits in memory)
        self._pixel_seconds = None      # measured seconds per pixel per frame
        self._accum = None              # running sum of frames since the last change
        self._accum_n = 0               # frames in _accum (weights: a resolution step carries a few)
        self._shown = None              # the latest published frame, for the convergence test
        self._carried = None            # (image, weight): the coarse image before a resolution step
        # --- published ---
        self.frame = None               # (h, w, 4) float32 RGBA, row 0 at the bottom
        self.frame_serial = 0
        self.frame_generation = 0       # generation of the changes the frame includes
        self.last_frame_seconds = None
        self.last_history_found = None
        self.error = None

    # ------------------------------------------------------------------ settings

    def _set_settings(self, mode, scale, samples, frame_budget, settle_frames, max_bounces, seed,
                      restir, denoise_start):
        if scale != "AUTO" and scale not in SCALES:
            raise ValueError(f"unknown viewport scale {scale!r}")
        self.mode = mode
        self.scale = scale
        self.samples = max(0, int(samples))
        self.progress.limit = self.samples
        self.denoise_start = max(1, int(denoise_start))
        self.frame_budget = float(frame_budget)
        self.settle_frames = max(1, int(settle_frames))
        self.max_bounces = max_bounces if isinstance(max_bounces, Bounces) else int(max_bounces)
        self.seed = int(seed)
        base = restir if restir is not None else ReSTIRSettings(denoise=defaults.VIEWPORT_DENOISE)
        # One initial sample per pixel per frame, and stored samples validated
        # every validation_interval frames: the viewport favours frame rate.
        self.restir_settings = replace(base, mode=mode if mode != PATH else base.mode,
                                       max_bounces=self.max_bounces, seed=self.seed, samples=1,
                                       validate_on_change=False)
        # A still view's frames (after the one that follows a change): one
        # running mean over all of them, as an F12 still's
        # (core/render.py), from reservoirs that hold samples for fewer frames.
        self._still_settings = replace(
            self.restir_settings, accumulate=STILL if self.restir_settings.accumulate > 1 else 1,
            temporal_M_cap=min(self.restir_settings.temporal_M_cap, self.restir_settings.still_temporal_M_cap))

    def configure(self, mode="RESTIR_BIASED", scale=defaults.VIEWPORT_SCALE, samples=defaults.VIEWPORT_SAMPLES,
                  frame_budget=defaults.VIEWPORT_FRAME_BUDGET, settle_frames=defaults.VIEWPORT_SETTLE_FRAMES,
                  max_bounces=4, seed=0, restir=None, denoise_start=defaults.VIEWPORT_DENOISE_START):
        """New settings (same arguments as the constructor); restarts the image
        only if something changed. The sample limit and the denoiser's start
        sample do not restart it (a higher limit goes on refining)."""
        before = (self.mode, self.scale, self.frame_budget, self.settle_frames, self.restir_settings)
        limits = (self.samples, self.denoise_start)
        self._set_settings(mode, scale, samples, frame_budget, settle_frames, max_bounces, seed,
                           restir, denoise_start)
        after = (self.mode, self.scale, self.frame_budget, self.settle_frames, self.restir_settings)
        if before != after:
            self.work.settings_updates += 1
            self._queue(settings=True, abandon=True)
        elif limits != (self.samples, self.denoise_start):
            with self._cond:
                self._cond.notify_all()     # a converged render thread may have more to do

    # ------------------------------------------------------------------ Blender side

    def _edit_abandons(self):
        """An edit abandons the frame in progress unless that frame is itself a restart."""
        return self._frame_started is not None and not self._frame_is_restart

    def set_view(self, camera):
        """The viewport camera (a core.Camera; see camera_from_region). Keeps
        the reservoirs: the next frame reprojects them."""
        if same_camera(camera, self._view):
            return
        self._view = camera
        self._view_from_scene = False
        self.work.camera_updates += 1
        self._queue(camera=camera)

    def resize(self, width, height):
        """The viewport's size in pixels: new buffers, no export."""
        size = (max(1, int(width)), max(1, int(height)))
        if size == self._display:
            return
        self._display = size
        self.work.resizes += 1
        self._queue(size=size, abandon=True)

    # ------------------------------------------------------------------ render side

    @property
    def converged(self):
        """Nothing left to do until something changes."""
        with self._cond:
            if not self._pending.empty() or self._applying:
                return False
        if self._scene is None or self._camera is None:
            return True
        return self.progress.done

    @property
    def view(self):
        """The camera the latest sync or set_view asked for."""
        return self._view

    @property
    def render_size(self):
        return None if self._scene is None else (self._scene.width, self._scene.height)

    @property
    def restir(self):
        return self._restir

    @property
    def nbytes(self):
        """Bytes held by the frame buffers and reservoirs."""
        total = self._restir.nbytes
        for a in (self.frame, self._accum):
            if a is not None:
                total += a.nbytes
        return total

    def _should_abandon(self):
        return self._stop or self._abandon

    def _settings_changed(self):
        self._restir.reset()
        self._divisor = None
        self.progress.divisor = None

    def _scene_changed(self):
        self._accum, self._accum_n = None, 0
        self._carried = None
        self._shown = None
        self.progress.changed()

    def render_step(self, time_budget=None):
        """Apply pending changes and render one frame. Returns True if a frame
        was rendered, False when there is nothing to do (converged, no scene)."""
        budget = self.frame_budget if time_budget is None else time_budget
        self.apply_pending()
        if self._ctx is None:
            return False
        if self._frames_since_edit >= self.settle_frames and self._accel.dynamic_keys:
            counts = self._accel.static_builds, self._accel.dynamic_builds
            self._accel.settle()
            self._count_builds(*counts)
        if self.converged:
            return False
        divisor = self._next_divisor(budget)
        if divisor != self._divisor or divisor != self.progress.divisor:
            self._step_to(divisor)
        scene = self._scene
        w, h = scene.width, scene.height
        t0 = time.perf_counter()
        self._frame_is_restart, self._next_is_restart = self._next_is_restart, False
        self._frame_started = t0
        path = self.path_traced
        try:
            if path:
                color = self._path_sample(self.progress.samples)
            else:
                settings = self.restir_settings if self.progress.moving else self._still_settings
                result = render_restir(self._ctx, self._restir, settings, self._frame_index)
                self._frame_index += 1
                self.last_history_found = result.history_found
                denoised = self.progress.samples + 1 >= self.denoise_start
                color = result.color if denoised or result.noisy is None else result.noisy
        except TraceInterrupted:
            self.work.abandoned_frames += 1
            self._next_is_restart = True
            raise
        finally:
            self._frame_started = None
        seconds = time.perf_counter() - t0
        color = np.nan_to_num(np.asarray(color, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
        if path:                    # (ReSTIR frames are running means already)
            self._accum = color if self._accum is None else self._accum + color
            self._accum_n += 1
            color = self._accum / self._accum_n
        frame = to_rgba(color.reshape(h, w, 3))
        if not path:
            frame = self._blend_carried(frame)
        change = relative_change(frame, self._shown)
        # The frame is counted and published before the progress counts it: a
        # reader that sees the session converged then also sees every frame
        # it took.
        self.work.frames += 1
        self._frames_since_edit += 1
        self.frame = self._shown = frame
        self.frame_generation = self._applied_generation
        self.frame_serial += 1
        self.progress.frame_done(change)
        self.last_frame_seconds = seconds
        per_pixel = seconds / max(1, w * h)
        self._pixel_seconds = per_pixel if self._pixel_seconds is None else (
            0.5 * self._pixel_seconds + 0.5 * per_pixel)
        return True

    @property
    def path_traced(self):
        """Whether frames are path-traced: in Path Tracing, and in the ReSTIR
        modes while the scene has volumes, which they render by path
        tracing as final renders do (core/integrators/media_path.py)."""
        if self.mode == PATH:
            return True
        return self._ctx is not None and media_of(self._scene, self._ctx.eps) is not None

    def _path_sample(self, sample):
        """One path-traced sample per pixel (an abandon is noticed between
        ray batches through the accel), in the twin process as ReSTIR
        frames are (core/render.render_frame's Continuation)."""
        settings = RenderSettings(mode=PATH, samples=1, max_bounces=self.max_bounces, seed=self.seed)
        return render_frame(self._ctx, settings, 0, first_sample=sample).mean().reshape(-1, 3)

    # ------------------------------------------------------------------ thread

    def start(self):
        """Render on a background thread until closed (idle while converged)."""
        if self._thread is not None:
            return
        self._thread = threading.Thread(target=self._run, name="restir-viewport", daemon=True)
        self._thread.start()

    @property
    def running(self):
        return self._thread is not None and self._thread.is_alive()

    def _run(self):
        try:
            while True:
                with self._cond:
                    while not self._stop and self._pending.empty() and (self.converged or self.error):
                        self._cond.wait()
                    if self._stop:
                        break
                try:
                    self.render_step()
                    self.error = None
                except TraceInterrupted:
                    continue
                except Exception as exc:  # noqa: BLE001 -- keep the viewport alive; show the error, wait for edits
                    traceback.print_exc()
                    self.error = describe(exc)
        finally:
            self._free()

    def wait_for_frame(self, generation=None, timeout=30.0):
        """Block until a frame including change ``generation`` (default: all
        queued so far) is published, or the session has nothing to do. For
        tests and benchmarks, never for the UI."""
        target = self._generation if generation is None else generation
        deadline = time.perf_counter() + timeout
        while time.perf_counter() < deadline:
            if self.frame is not None and self.frame_generation >= target:
                return True
            if not self.running:
                return False
            time.sleep(0.002)
        return False

    def close(self, wait=True, timeout=10.0):
        """Stop the render thread (its frame in progress is abandoned at the next
        ray batch) and free the buffers; with wait False, return at once and let
        the thread free them when it exits."""
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        thread = self._thread
        if thread is None:
            self._free()
            return True
        if wait:
            thread.join(timeout)
        return not thread.is_alive()

    def _free(self):
        self._free_scene()
        self._restir.reset()
        self._accum, self._accum_n = None, 0
        self._carried = None
        self.frame = self._shown = None

    def status(self):
        if self.error:
            return f"Error: {self.error}"
        if self._scene is None:
            return "Waiting for the scene"
        w, h = self._scene.width, self._scene.height
        timing = f" | {self.last_frame_seconds:.2f} s/frame" if self.last_frame_seconds else ""
        volumes = " | volumes: path traced" if self.mode != PATH and self.path_traced else ""
        return f"{self.progress.text()} | {w}x{h}{timing}{volumes}"
