"""Settings of the engine, attached to every scene as ``scene.restir_gi``."""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty

from . import defaults

R = defaults.RESTIR     # the resampling's defaults, as core keeps them

MODE_ITEMS = (
    ("PATH", "Path Tracing", "Plain path tracing: samples per pixel, no reuse between frames"),
    ("RESTIR_BIASED", "ReSTIR GI (Biased)",
     "Reuse indirect-light samples across pixels and frames; 1/M weights: least noise, slightly dark "
     "near contact shadows"),
    ("RESTIR_UNBIASED", "ReSTIR GI (Unbiased)",
     "Reuse indirect-light samples across pixels and frames; MIS weights with visibility rays "
     "between neighbours: converges to the path-traced result"),
)

INITIAL_SAMPLING_ITEMS = (
    ("COSINE", "Cosine", "Cosine-weighted hemisphere directions for initial samples"),
    ("UNIFORM", "Uniform", "Uniform hemisphere directions for initial samples (better for light "
                           "arriving at grazing angles)"),
)


class RestirGISceneSettings(bpy.types.PropertyGroup):
    mode: EnumProperty(
        name="Mode",
        description="Light transport algorithm",
        items=MODE_ITEMS,
        default=defaults.MODE,
    )
    samples: IntProperty(
        name="Samples",
        description="Path tracing: samples per pixel. ReSTIR GI: frames of resampling per animation "
                    "frame, averaged (more time per frame, a cleaner frame)",
        default=defaults.SAMPLES, min=1, soft_max=1024, max=65536,
    )
    warmup_frames: IntProperty(
        name="Warm-up Frames",
        description="ReSTIR GI: frames of resampling run on the still scene for a still render or "
                    "the first frame of an animation; the image is their mean (the first frames, "
                    "while the reservoirs fill, weigh less in the unbiased mode and are left out "
                    "in the biased one)",
        default=defaults.WARMUP_FRAMES, min=1, soft_max=128, max=4096,
    )
    chunk_warmup_frames: IntProperty(
        name="Chunk Warm-up", default=defaults.CHUNK_WARMUP_FRAMES, min=0, soft_max=64, max=4096,
        description="ReSTIR GI: an animation render that starts after the scene's first frame (a "
                    "chunk on a render farm, or a resumed render) first renders up to this many "
                    "preceding frames along the animation, without writing them, so its first frame "
                    "has the history a continuous render would have (0 = start cold)",
    )
    accumulate_frames: IntProperty(
        name="Accumulation", default=R.accumulate, min=1, soft_max=64, max=4096,
        description="ReSTIR GI: frames in each pixel's running mean, carried through reprojection "
                    "(anti-aliasing and direct light settle over them; disocclusions and changed "
                    "lighting start over; 1 = off)",
    )
    use_denoising: BoolProperty(
        name="Denoise", default=defaults.DENOISE,
        description="ReSTIR GI: filter the indirect light of each frame with the engine's own "
                    "denoiser (edge-avoiding, guided by depth, normals, albedo and each pixel's "
                    "variance over its history); the image before it is kept in the Noisy Image pass",
    )
    use_preview_denoising: BoolProperty(
        name="Viewport Denoise", default=defaults.VIEWPORT_DENOISE,
        description="ReSTIR GI: filter the indirect light of the rendered viewport's frames with the "
                    "engine's own denoiser",
    )
    initial_sampling: EnumProperty(
        name="Initial Sampling", items=INITIAL_SAMPLING_ITEMS, default=R.initial_sampling,
        description="How each pixel draws the direction of its new sample (glossy surfaces use their BSDF)",
    )
    temporal_m_cap: IntProperty(
        name="Temporal M Cap", default=int(R.temporal_M_cap), min=1, max=10000,
        description="Cap on the number of past samples a temporal reservoir stands for",
    )
    spatial_m_cap: IntProperty(
        name="Spatial M Cap", default=int(R.spatial_M_cap), min=1, max=100000,
        description="Cap on the number of samples a spatial reservoir carries over frames",
    )
    max_age: IntProperty(
        name="Max Sample Age", default=R.max_age, min=1, max=10000,
        description="Frames after which a reused sample is dropped",
    )
    spatial_neighbors: IntProperty(
        name="Spatial Neighbors", default=R.spatial_neighbors, min=0, max=32,
        description="Neighbouring pixels whose reservoirs each pixel reuses per frame",
    )
    spatial_radius: FloatProperty(
        name="Spatial Radius", default=R.spatial_radius, min=1.0, soft_max=64.0, max=512.0, subtype="PIXEL",
        description="Radius in pixels within which spatial neighbours are chosen while the view "
                    "moves; half of it once nothing moves",
    )
    light_samples: IntProperty(
        name="Light Samples", default=R.light_samples, min=1, max=64,
        description="ReSTIR GI: shadow rays per frame for the direct light of pixels whose direct "
                    "light was noisy last frame (penumbrae, several lights); other pixels get one",
    )
    sky_samples: IntProperty(
        name="Sky Samples", default=R.sky_samples, min=0, max=64,
        description="ReSTIR GI: occlusion rays per pixel and frame toward the world for the light "
                    "it casts on diffuse surfaces, where the world lights the image (a share of "
                    "pixels cast one where it gives little); 0: the world's light goes through the "
                    "reservoirs",
    )
    boiling_filter: FloatProperty(
        name="Boiling Filter", default=R.boiling_filter, min=0.0, max=1.0, subtype="FACTOR",
        description="Empty reservoirs far brighter than their 16x16 pixel neighbourhood, so one rare "
                    "bright path does not spread into a blotch that lasts for frames (biased mode; 0: off)",
    )
    viewport_scale: EnumProperty(
        name="Viewport Resolution",
        items=(("AUTO", "Automatic", "Pick the resolution scale from the frame time budget"),
               ("FULL", "Full", "Render the viewport at full resolution"),
               ("HALF", "1/2", "Render the viewport at half resolution"),
               ("QUARTER", "1/4", "Render the viewport at quarter resolution")),
        default=defaults.VIEWPORT_SCALE, description="Resolution of the rendered viewport, for interactivity",
    )
    viewport_samples: IntProperty(
        name="Viewport Samples", default=defaults.VIEWPORT_SAMPLES, min=0, max=1 << 24,
        description="Frames (path tracing: samples) of a still rendered viewport before it stops "
                    "refining; it also stops once the image no longer changes (0 = no limit)",
    )
    preview_denoising_start_sample: IntProperty(
        name="Start Sample", default=defaults.VIEWPORT_DENOISE_START, min=1, max=1 << 24,
        description="ReSTIR GI: the first sample of a still rendered viewport shown denoised "
                    "(Viewport Denoise); the ones before are shown as rendered",
    )
    viewport_frame_budget: FloatProperty(
        name="Frame Budget", default=defaults.VIEWPORT_FRAME_BUDGET, min=0.01, max=10.0,
        subtype="TIME_ABSOLUTE", unit="TIME_ABSOLUTE",
        description="Time a viewport frame should take; the automatic resolution aims for it",
    )
    validation_interval: IntProperty(
        name="Validation Interval", default=R.validation_interval, min=0, max=1000,
        description="Every this many frames, stored samples are re-traced and dropped where their "
                    "light changed (0 = never)",
    )
    max_bounces: IntProperty(
        name="Max Bounces",
        description="Maximum number of bounces of a light path",
        default=defaults.MAX_BOUNCES, min=0, soft_max=16, max=128,
    )
    diffuse_bounces: IntProperty(
        name="Diffuse", default=defaults.DIFFUSE_BOUNCES, min=0, soft_max=16, max=1024,
        description="Maximum number of diffuse reflection bounces, bounded by the total maximum",
    )
    glossy_bounces: IntProperty(
        name="Glossy", default=defaults.GLOSSY_BOUNCES, min=0, soft_max=16, max=1024,
        description="Maximum number of glossy reflection bounces, bounded by the total maximum",
    )
    transmission_bounces: IntProperty(
        name="Transmission", default=defaults.TRANSMISSION_BOUNCES, min=0, soft_max=16, max=1024,
        description="Maximum number of transmission bounces, bounded by the total maximum",
    )
    seed: IntProperty(
        name="Seed",
        description="Seed of the random numbers; the same seed gives the same image",
        default=0, min=0,
    )

    @classmethod
    def register(cls):
        bpy.types.Scene.restir_gi = PointerProperty(
            name="ReSTIR GI Settings", description="ReSTIR GI render settings", type=cls)

    @classmethod
    def unregister(cls):
        del bpy.types.Scene.restir_gi


classes = (RestirGISceneSettings,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
