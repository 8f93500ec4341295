"""Light probes: where the direct light changed since last frame, for the
running means of the direct light where objects move (A-SVGF's temporal
gradient, for the light the visible points receive).

gradients.py re-draws indirect samples and leaves the direct light to the
running means' gate (accumulation.light_range), which compares a pixel's
history with the light of its 3x3 neighbourhood. Where a moving object's
shadow edge crosses a pixel, or a moving object enters the light, that
neighbourhood spans both sides and the gate cannot tell: the pixels kept
four of five frames of their old light, a sliding box's sunlit edges and
the edge of its shadow trailing a pixel behind (corpus_movers, frame 32: 3 %
of the pixels held 70 % of the squared error against Cycles).

A probe is one light sample per visible point, with random numbers fixed per
pixel: its unshadowed value (luminance of the light's radiance times the
cosine over the pdf) times its visibility. Each frame in which objects move
stores its pixels' probes; the next frame evaluates the same pixels' probes
again in the new scene, at last frame's points carried with their objects'
motion. Where nothing changed the value is the same to the bit; where a
shadow arrived or left, it differs by the light gained or lost. As in
gradients.py, the relative change is summed over a small window,

    lambda = GAIN sum |new - old| / sum max(new, old),

and the direct light's running mean keeps history_frames(lambda) frames.
"""

import numpy as np

from ..integrators.base import shadow_rays
from ..sampling import samplers
from ..util.vectors import dot, luminance
from .gradients import temporal_gradient

PROBE_PIXELS = 0x51C7   # random-number domain of the probes (fixed per pixel, every frame)
RADIUS = 1              # window half-size of the sums: a pixel and its eight neighbours
# A probe is exact, so any change is real light: a hundredth of the light
# lost or gained over the window in a frame restarts the running mean.
# corpus_movers (still camera, frame 32, biased + denoiser): MSE 0.02114 at
# 10, 0.02073 at 30, 0.02025 at 100, 0.02018 at 1000.
GAIN = 100.0


def probe_values(ctx, p, n, ng, pixels, seed):
    """(N,) float32: each point's probe (one light sample, visibility
    included) at points p with shading normals n and geometric normals ng
    (N, 3), with the random numbers of its image pixel ``pixels`` (N,)."""
    count = len(p)
    out = np.zeros(count, np.float32)
    lights = ctx.lights
    if count == 0 or lights.count == 0:
        return out
    keys = samplers.hash_keys(seed, PROBE_PIXELS, pixels)
    ls = lights.sample(p, samplers.uniform(keys, 0), samplers.uniform2(keys, 1), n)
    cos = dot(ls.wi, n)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        value = luminance(ls.radiance) * cos / np.where(ls.pdf > 0, ls.pdf, 1.0)
    live = np.nonzero((cos > 0) & (dot(ls.wi, ng) > 0) & (ls.pdf > 0) & np.isfinite(value) & (value > 0))[0]
    if len(live) == 0:
        return out
    blocked = ctx.accel.occluded(*shadow_rays(ctx, p[live], ng[live], ls.wi[live], ls.dist[live]))
    lit = live[~blocked]
    out[lit] = value[lit]
    return out


def image_probes(ctx, p, n, ng, valid, seed):
    """(P,) float32 probes of an image's visible points (0 where nothing is
    seen); p, n, ng (P, 3) full-image rows, valid (P,). Over pixel ranges on
    the context's workers."""
    def part(a, b):
        out = np.zeros(b - a, np.float32)
        at = np.flatnonzero(valid[a:b]) + a
        if len(at):
            out[at - a] = probe_values(ctx, p[at], n[at], ng[at], at, seed)
        return out

    return ctx.workers.map_into(part, len(valid))


def probes_moved(ctx, history, motion, seed):
    """(P,) float32: last frame's pixels' probes evaluated in the current
    scene, at last frame's visible points carried with their objects' motion
    (temporal.ObjectMotion, or None)."""
    p, n, ng = history.p, history.n, history.ng
    if motion is not None and motion.to_current is not None:
        p, n, ng = p.copy(), n.copy(), ng.copy()
        motion.carry_forward(history.object_id, history.valid, points=(p,), normals=(n, ng))
    return image_probes(ctx, p, n, ng, history.valid, seed)


def light_change(old, new, width, height):
    """lambda (P,) float32 in [0, 1]: the relative change of the probes
    around each pixel of a width x height image (old, new (P,); values that
    are not finite count for nothing), as gradients.temporal_gradient
    finds it for the re-drawn samples."""
    n = width * height
    return temporal_gradient(np.arange(n, dtype=np.int64), old, new, np.ones(n, bool), width, height,
                             radius=RADIUS, gain=GAIN)
