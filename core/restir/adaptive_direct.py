"""Adaptive shadow rays for the direct light of the visible points.

ReSTIR GI resamples the indirect light; the direct light of each visible point
is next-event estimation. One light sample is exact wherever a point sees all
or none of its lights, and noisy in penumbrae and where several lights
compete. So each pixel gets one shadow ray, and ``light_samples`` where last
frame's direct light was noisy: its 3x3 neighbourhood disagreed by more than
NOISE_RELATIVE. A flag is kept for HOLD_FRAMES frames, so a penumbra that
looked smooth with many rays does not fall back to one and flicker. Pixels
that lost their history (disocclusions) get ``light_samples``; the first frame
of a stream, with no history at all, gets one ray everywhere and its own noise
flags the penumbrae for the next frame (a first frame with 16 rays everywhere
took twice as long, and is a warm-up frame of a render or a viewport frame
that is averaged with the next ones).

The count of a pixel depends only on earlier frames, never on this frame's
samples, so each frame's direct light stays an unbiased estimate.
"""

import numpy as np

from ..util.vectors import luminance

NOISE_RELATIVE = 0.3    # neighbours differing by more than this (of the brightest) flag a pixel
HOLD_FRAMES = 8         # frames a flag lasts after its last trigger


def neighbourhood_range(values, valid, width, height, centre=True):
    """Max and min of ``values`` (P,) over each pixel's 3x3 neighbourhood
    (without the pixel itself if not ``centre``), counting valid pixels only
    (valid None: all; where none counts, max -inf and min +inf)."""
    img = values.reshape(height, width)
    if valid is None:
        hi = np.pad(img, 1, constant_values=-np.inf)
        lo = np.pad(img, 1, constant_values=np.inf)
    else:
        ok = valid.reshape(height, width)
        hi = np.pad(np.where(ok, img, -np.inf), 1, constant_values=-np.inf)
        lo = np.pad(np.where(ok, img, np.inf), 1, constant_values=np.inf)
    mx = np.full((height, width), -np.inf, img.dtype)
    mn = np.full((height, width), np.inf, img.dtype)
    for dy in range(3):
        for dx in range(3):
            if dy == 1 and dx == 1 and not centre:
                continue
            np.maximum(mx, hi[dy:dy + height, dx:dx + width], out=mx)
            np.minimum(mn, lo[dy:dy + height, dx:dx + width], out=mn)
    return mx.ravel(), mn.ravel()


def update_noise_hold(direct, valid, width, height, prev_hold, lum=None):
    """Frames each pixel (P,) stays flagged as noisy, from this frame's direct
    light (P, 3) or its luminance lum (P,) float32, and the reprojected hold
    of last frame (P,) int8 (or None)."""
    if lum is None:
        lum = luminance(direct).astype(np.float32)
    mx, mn = neighbourhood_range(lum, valid, width, height)
    floor = 1e-3 * float(lum[valid].mean()) if valid.any() else 0.0
    noisy = valid & (mx - mn > NOISE_RELATIVE * mx + floor)
    hold = np.zeros(len(valid), np.int8) if prev_hold is None else np.maximum(prev_hold - 1, 0).astype(np.int8)
    hold[noisy] = HOLD_FRAMES
    hold[~valid] = 0
    return hold


def light_sample_counts(index, prev_pix, hold, light_samples):
    """Shadow rays per visible point (gb.index order): ``light_samples`` where
    the reprojected hold (reprojected_hold) flags noise or history is missing
    (prev_pix < 0), else one; one everywhere on a first frame (hold None)."""
    light_samples = max(1, int(light_samples))
    if hold is None or light_samples == 1:
        return np.ones(len(index), np.int64)
    flagged = (prev_pix[index] < 0) | (hold[index] > 0)
    return np.where(flagged, light_samples, 1).astype(np.int64)


def reprojected_hold(prev_pix, prev_hold):
    """Last frame's hold carried to this frame's pixels (0 where no history)."""
    if prev_hold is None:
        return None
    return np.where(prev_pix >= 0, prev_hold[np.maximum(prev_pix, 0)], 0).astype(np.int8)
