"""The direct light of pixels whose running mean has just restarted, at
sharp edges of light: filtered over the pixel's 3x3 neighbourhood in the
denoised image.

A frame takes one camera sample per pixel. A pixel's running mean averages
its samples over the pixel filter, so on a still view a shadow's edge or a
sunlit silhouette is anti-aliased after a few frames. Where the direct
light's history restarts (the light probes saw a moving shadow or an object
entering the light, light_probes.py; disocclusions), an edge pixel shows
whichever side its one ray hit, by the full contrast: on corpus_movers,
those pixels along the sliding box's sunlit edges and its shadow's edge held
half of the moving frame's squared error.

The denoiser (denoise.py) leaves the direct light alone (filtering it
blurred sunlit patches into the floor around them). Here only pixels whose
direct light holds at most FRESH_FRAMES frames and whose 3x3 neighbourhood's
direct light spans more than EDGE_SPAN of its top are filtered, with a 3x3
tent over the pixels that see a surface: about the footprint of the pixel
filter that the one sample could not cover. The running means keep their
own values; only the finished image shows the filtered light.
"""

import numpy as np

from ..util.vectors import luminance
from .accumulation import LIGHT_FRAMES
from .adaptive_direct import neighbourhood_range

FRESH_FRAMES = 2.0      # the direct light's mean holds at most this many frames
EDGE_SPAN = 0.3         # the 3x3 neighbourhood's direct light spans more than this share of its top
# corpus_movers, still camera, biased + denoiser, frame 32 MSE against Cycles
# at 1024 spp: 0.0719 without, 0.0514 with (FRESH_FRAMES 2 or 4 alike).


def fresh_edge_direct(data, valid, width, height, r0, r1):
    """(rows r0..r1 of the image x width, 3) float32: the direct light
    (running means' columns 0:3 of ``data``, (P, columns)) of those rows,
    tent-filtered where the pixel is a fresh edge (above). valid (P,) bool:
    pixels that see a surface (the only ones filtered and read)."""
    a0, a1 = max(r0 - 1, 0), min(r1 + 1, height)     # one row of halo each side
    rows = data[a0 * width:a1 * width]
    h = a1 - a0
    direct = np.nan_to_num(rows[:, 0:3].astype(np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    direct = direct.reshape(h, width, 3)
    ok = valid[a0 * width:a1 * width].reshape(h, width)
    v = ok.astype(np.float64)
    pd = np.pad(direct * v[..., None], ((1, 1), (1, 1), (0, 0)))
    pv = np.pad(v, 1)
    total = np.zeros_like(direct)
    weight = np.zeros_like(v)
    for dy in range(3):
        for dx in range(3):
            tent = (2 - abs(dy - 1)) * (2 - abs(dx - 1))
            total += tent * pd[dy:dy + h, dx:dx + width]
            weight += tent * pv[dy:dy + h, dx:dx + width]
    hi, lo = (x.reshape(h, width) for x in neighbourhood_range(luminance(direct.reshape(-1, 3)), ok.ravel(),
                                                               width, h))
    frames = rows[:, LIGHT_FRAMES].reshape(h, width)
    fresh = ok & (frames <= FRESH_FRAMES) & (hi - lo > EDGE_SPAN * np.maximum(hi, 1e-30))
    out = np.where(fresh[..., None], total / np.maximum(weight, 1e-30)[..., None], direct)
    return out[r0 - a0:r1 - a0].reshape(-1, 3).astype(np.float32)
