"""More camera samples for the direct light at its edges where its history
is short.

A frame takes one camera sample per pixel. On a still view the running
means (accumulation.py) average a pixel's samples over its pixel filter, so
a sunlit silhouette or a shadow's edge is anti-aliased after a few frames.
Where objects moved, the direct light's history restarts around them (the
light probes see the light change: light_probes.py), and an edge pixel then
shows whichever side its one ray hit, by the full contrast. On
corpus_movers (still camera, frame 32) the pixels along the sliding box's
sunlit outline and its shadow's edge, half a percent of the image, held 89 %
of the squared error that the motion added to the finished frame.

So in a frame where objects moved, the pixels whose direct light has a
short history (at most SHORT_FRAMES frames, as last frame's running means
hold it) and whose 8 neighbours' direct light spans more than EDGE_SPAN of
their brightest take SAMPLES more camera rays, each with one next-event
sample (initial.nee_direct), and their direct light becomes

    D + mean_k E(x_k) - E(x_0)

D: the G-buffer sample's direct light (next-event estimation and the
emitters its sample ray found, MIS-weighted); E: its next-event part, at
the extra rays' visible points x_k and, with the very uniforms D used, at
its own x_0 (the G-buffer's ray traced again). Each x_k is distributed over
the pixel filter as x_0 is, so the difference has expectation zero: a
control variate that keeps the estimate unbiased and cancels what the
pixel's own ray contributes of the edge's contrast. A pixel whose ray
missed (the world) takes mean_k E(x_k): its D and E are zero.

The choice of pixels reads their neighbours and last frame only, never the
pixel's own sample.
"""

import numpy as np

from ..geometry.interaction import surface_hits
from ..integrators.base import ShadingFrame
from ..sampling import samplers
from ..util.rows import scatter
from ..util.vectors import luminance
from .accumulation import LIGHT_FRAMES
from .adaptive_direct import light_sample_counts, neighbourhood_range
from .gbuffer import pixel_rays, trace_rows
from .initial import first_uniforms, nee_direct

SHORT_FRAMES = 4.0      # the direct light's history holds at most this many frames
EDGE_SPAN = 0.15        # the 8 neighbours' direct light spans more than this share of their top
SAMPLES = 8             # extra camera rays per edge pixel
MAX_SHARE = 0.05        # at most this share of the image (the widest spans)
EDGE_SAMPLE = 0xD1EC7   # the sample number of the extra rays (path_seeds)


def edge_pixels(lum_direct, frames, width, height):
    """(E,) pixels to refine: direct light luminance lum_direct (P,), the
    frames (P,) its history holds (0: none)."""
    mx, mn = neighbourhood_range(np.asarray(lum_direct, np.float32), None, width, height, centre=False)
    floor = 1e-3 * float(np.mean(lum_direct)) if len(lum_direct) else 0.0
    span = mx - mn
    edges = np.flatnonzero((frames <= SHORT_FRAMES) & (span > EDGE_SPAN * mx + floor))
    cap = int(MAX_SHARE * len(lum_direct))
    if len(edges) > cap:
        edges = np.sort(edges[np.argsort(span[edges])[::-1][:cap]])
    return edges


def history_frames(prev_pix, data):
    """(P,) frames of direct light each pixel's history holds: the running
    means' light frames (``data`` (P', columns), last frame's, already capped
    where the light changed) at last frame's pixel prev_pix (P,), 0 without."""
    frames = np.zeros(len(prev_pix), np.float32)
    have = prev_pix >= 0
    frames[have] = data[prev_pix[have], LIGHT_FRAMES]
    return frames


def own_nee(ctx, seed, frame, pixel_filter, pixels, stream_index, sequences, counts_of, sampling):
    """(E, 3) E(x_0): the next-event part of the direct light of pixels
    (E,) at their G-buffer ray's visible point (stream_index: the frame's
    place in its stream), with the uniforms (each pixel's sequences if
    ``sequences``) and light sample counts (counts_of(rows)) the initial
    samples used."""
    gb = trace_rows(ctx, seed, frame, pixel_filter, True, 0, 0, stream_index, pixels=pixels)
    out = np.zeros((len(pixels), 3), np.float32)
    if len(gb.index):
        ids = gb.ids(gb.index)
        seeds = samplers.path_seeds(seed, frame, ids, 0)
        _, _, u_light = first_uniforms(seed, ids, seeds, stream_index if sequences else None)
        d, _ = nee_direct(ctx, gb.surf, gb.frame, seeds, u_light, sampling, counts_of(gb.index))
        scatter(out, gb.index, d)
    return out


def mean_nee(ctx, seed, frame, pixel_filter, pixels, stream_index, counts, sampling, samples):
    """(E, 3) mean of E(x_k) over ``samples`` camera rays in each of pixels
    (E,); counts (E,) their light sample counts (the MIS weights' n)."""
    seeds, o, d, tmax, hits = pixel_rays(ctx, seed, frame, pixel_filter, pixels, samples, EDGE_SAMPLE,
                                         stream_index)
    surf, idx = surface_hits(ctx.scene, o, d, hits)
    total = np.zeros((len(pixels), 3), np.float64)
    if len(idx):
        frame_sh = ShadingFrame.at(ctx.scene, surf, camera_ray=True)
        owner = idx // samples
        e, _ = nee_direct(ctx, surf, frame_sh, seeds[idx], None, sampling, np.asarray(counts)[owner])
        for c in range(3):
            total[:, c] = np.bincount(owner, weights=e[:, c], minlength=len(pixels))
    return (total / samples).astype(np.float32)


def refine_direct_edges(ctx, seed, frame, pixel_filter, first, prev_acc, stream_index, sequences, how):
    """The direct light of ``first`` (FirstPass: its direct and lum_direct,
    in place) at the edge pixels whose history is short (above); prev_acc:
    last frame's running means as this frame reads them (Accumulation).
    stream_index, sequences: as own_nee's. how: the InitialSampling of the
    frame's one initial sample. Returns the pixels refined."""
    scene = ctx.scene
    if pixel_filter.dist is None or prev_acc is None:
        return np.zeros(0, np.int64)
    frames = history_frames(first.prev_pix, prev_acc.data)
    edges = edge_pixels(first.lum_direct, frames, scene.width, scene.height)
    if len(edges) == 0:
        return edges
    prev, hold = first.prev_pix[edges], None if first.hold is None else first.hold[edges]

    def counts_of(rows):
        return light_sample_counts(rows, prev, hold, how.light_samples)

    counts = counts_of(np.arange(len(edges)))
    parts = ctx.workers.map(lambda a, b: (
        own_nee(ctx, seed, frame, pixel_filter, edges[a:b], stream_index, sequences,
                lambda rows: counts[a:b][rows], how.sampling),
        mean_nee(ctx, seed, frame, pixel_filter, edges[a:b], stream_index, counts[a:b], how.sampling,
                 SAMPLES)), len(edges))
    own = np.concatenate([p[0] for p in parts])
    mean = np.concatenate([p[1] for p in parts])
    refined = np.maximum(first.direct[edges] - own + mean, 0.0)
    first.direct[edges] = refined
    first.lum_direct[edges] = luminance(refined)
    return edges
