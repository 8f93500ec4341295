"""What a ReSTIR GI frame takes (ReSTIRSettings) and gives (FrameResult)."""

from dataclasses import dataclass

import numpy as np

from .initial import COSINE

BIASED = "RESTIR_BIASED"
UNBIASED = "RESTIR_UNBIASED"


@dataclass
class ReSTIRSettings:
    """How a ReSTIR GI frame resamples. These are the engine's defaults: the
    add-on's settings (restir_addon/defaults.py) read them. Why each value:
    docs/design.md, "Design choices"; the measurements behind them:
    docs/plan-archive.md."""
    mode: str = BIASED
    samples: int = 1                # initial samples per pixel per frame
    max_bounces: int = 4
    seed: int = 0
    initial_sampling: str = COSINE  # or "UNIFORM"
    temporal: bool = True
    spatial: bool = True
    temporal_M_cap: float = 8.0     # RTXDI's; higher caps hold each sample for more frames,
                                    # so the running means average fewer distinct ones
    spatial_M_cap: float = 100.0    # Falcor's; the same trade-off for carried spatial samples
    max_age: int = 30               # frames a reused sample lives
    spatial_neighbors: int = 4
    spatial_radius: float = 16.0    # pixels; smaller radii help stills but turn a moving
                                    # view's fine noise into crawling blotches
    still_radius_scale: float = 0.5     # the radius's share on a view that has not moved
                                        # since last frame (stills, a still viewport)
    validation_interval: int = 4    # frames; 0 turns validation off
    validate_on_change: bool = False    # validate in the very frame the lighting changed (final
                                        # renders: frames waiting for the interval stay dark)
    boiling_filter: float = 0.2     # strength (boiling.py), biased mode only; 0 turns it off
    light_samples: int = 4          # shadow rays for the direct light of visible points in
                                    # penumbrae (one elsewhere: adaptive_direct.py)
    still_temporal_M_cap: float = 4.0   # temporal cap of a still's frames after it settles
                                        # (core/render.py): less correlated frames, whose
                                        # mean converges faster
    edge_samples: int = 32          # camera rays for the radiance seen directly at bright
                                    # silhouettes (silhouettes.py; 1 turns it off)
    accumulate: int = 16            # frames in each pixel's running mean (accumulation.py);
                                    # 1 turns it off, accumulation.STILL averages every frame
    glossy_reuse: bool = True       # the glossy lobe's light from each pixel's and its
                                    # neighbours' samples (glossy_reuse.py)
    sequences: bool = True          # each pixel's first-bounce light samples and directions
                                    # follow its sequences over the frames of its stream
                                    # (samplers.first_bounce_uniforms; else hashed anew)
    sky_samples: int = 4            # occlusion rays toward the world per visible point and
                                    # frame for the diffuse lobe's sky light (sky.py); 0 leaves
                                    # it to the reservoirs' sky samples
    frame_weight: float = 1.0       # this frame's weight in the running means, in frames
                                    # (an unbiased still's first frames weigh less: core/render.py)
    denoise: bool = False           # filter the running means (denoise.py; FrameResult.color is
                                    # then the filtered image and .noisy the image before)


@dataclass
class FrameResult:
    """One frame, full-image rows (pixel index y * width + x)."""
    color: np.ndarray       # (P, 3) direct + indirect (denoised with ReSTIRSettings.denoise)
    direct: np.ndarray      # (P, 3) emission seen directly + direct light (accumulated)
    indirect: np.ndarray    # (P, 3) (accumulated)
    depth: np.ndarray       # (P,) this frame's
    normal: np.ndarray      # (P, 3) accumulated
    albedo: np.ndarray      # (P, 3) accumulated
    M: np.ndarray           # (P,) spatial reservoir M
    W: np.ndarray           # (P,) spatial reservoir W
    history_found: float    # fraction of visible pixels with accepted temporal history
    alpha: np.ndarray = None  # (P,) coverage by geometry (accumulated; Film > Transparent)
    noisy: np.ndarray = None  # (P, 3) color before the denoiser (None when it is off)
