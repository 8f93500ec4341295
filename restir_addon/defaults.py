"""Every default of the engine's settings, in one place.

The renderer's own (``RESTIR``, core's ReSTIRSettings: caps, neighbours,
radius, light and sky samples, ...) and the add-on's: what a new scene
renders with and how the rendered viewport refines. ``properties.py`` builds
``scene.restir_gi`` from these; the viewport session and final renders fall
back to them where a scene has no such setting. No bpy here."""

from ..core.restir import ReSTIRSettings

RESTIR = ReSTIRSettings()       # the resampling's defaults (core/restir/settings.py)

# A scene's render settings
MODE = "PATH"
SAMPLES = 16                    # path tracing: samples per pixel; ReSTIR: frames per animation frame
WARMUP_FRAMES = 32              # ReSTIR: frames of a still render, averaged
CHUNK_WARMUP_FRAMES = 16        # ReSTIR: frames before a farm chunk's first frame
DENOISE = True                  # ReSTIR: the engine's denoiser on final renders
MAX_BOUNCES = 12                # Light Paths, as Cycles' defaults
DIFFUSE_BOUNCES = 4
GLOSSY_BOUNCES = 4
TRANSMISSION_BOUNCES = 12

# The rendered viewport
VIEWPORT_SCALE = "AUTO"
VIEWPORT_FRAME_BUDGET = 0.25    # seconds per frame the AUTO scale aims for
VIEWPORT_SAMPLES = 1024         # frames (path tracing: samples) of a still view before it
                                # stops, 0: no limit (Cycles' viewport samples)
VIEWPORT_SETTLE_FRAMES = 8      # frames without edits before moved objects rejoin the static scene
VIEWPORT_DENOISE = True         # ReSTIR: the engine's denoiser on the viewport's frames
VIEWPORT_DENOISE_START = 1      # the first sample (frame) of a still view shown denoised
