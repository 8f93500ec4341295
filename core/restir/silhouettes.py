"""More camera samples for what the camera sees directly at bright silhouettes.

A frame takes one camera sample per pixel, so a pixel that an emitter, a
visible lamp or the sky covers in part sees either it or what lies beside it:
its colour flips between the two from frame to frame by the full contrast.
The running means (accumulation.py) average that out on a still view, but
a moving camera keeps a few frames of history there, and on the corpus's room
of small emitters the edges of the emitters (1 % of the pixels) held 93 % of
the squared error of a moving frame.

What the camera sees directly costs one ray and no shading, so the pixels
whose neighbours disagree about it get ``samples`` camera rays in all (the
G-buffer's own is the first; fewer where edges are many, so that they add
at most about one ray per pixel of the image), and their radiance seen
directly becomes the mean of them; the rest of their light is still the
G-buffer sample's. On a moving view the running means keep no history of it
at the brightest of them (OWN_CONTRAST; accumulation.py). Milder edges are
refined too: the sky's over the corpus's courtyard, refined, cost about
10 ms of a 140 ms frame and took 12 % off the MSE of a moving view (0.00065 ->
0.00057); with no history there as well, the MSE rose to 0.00076.

The choice of pixels looks at the 8 neighbours and the other pixels' mean
only, never at the pixel's own sample, so each pixel's estimate stays
unbiased: its extra rays are taken or not whatever its own ray saw (but see
edge_pixels for where a cap binds).
"""

from dataclasses import dataclass

import numpy as np

from ..materials import shading as materials
from ..geometry.interaction import HitSides, surface_hits
from ..workers.parallel import concat_rows
from ..util.rows import gather
from ..util.vectors import dot, luminance
from .adaptive_direct import neighbourhood_range
from .gbuffer import CAMERA_SAMPLE, pixel_rays, seen_directly

EDGE_CONTRAST = 1.0     # neighbours differing by more than this x the image's mean luminance
OWN_CONTRAST = 4.0      # ... and by more than this: no history of it on a moving view
MAX_EDGE_SHARE = 0.25   # at most this share of the image gets extra rays (the brightest edges)


def edge_pixels(lum_seen, lum_other, width, height):
    """Edge pixels: those whose 8 neighbours' luminance seen directly
    (lum_seen (P,)) spans more than EDGE_CONTRAST x the image's mean
    luminance (seen plus lum_other (P,), the direct light) over the other
    pixels, at most MAX_EDGE_SHARE of the image (the widest spans).
    Returns (edges (E,), bright (E,) bool: spans over OWN_CONTRAST x that
    mean).

    A pixel's own values enter neither its span nor its threshold. They do
    enter its neighbours' spans, so where the cap (or the rays per edge of
    refine_edges, which follow the number of edges) binds, a pixel's own
    ray can move the count of edges by at most the 8 around it."""
    lum_seen = np.asarray(lum_seen, np.float32)
    mx, mn = neighbourhood_range(lum_seen, None, width, height, centre=False)
    span = mx - mn
    own = lum_seen + np.asarray(lum_other, np.float32)
    n = len(own)
    scale = (float(own.sum(dtype=np.float64)) - own) / max(n - 1, 1)
    np.maximum(scale, 1e-6, out=scale)
    edges = np.flatnonzero(span > EDGE_CONTRAST * scale)
    cap = int(MAX_EDGE_SHARE * n)
    if len(edges) > cap:
        edges = edges[np.argsort(span[edges])[::-1][:cap]]
        edges.sort()
    return edges, span[edges] > OWN_CONTRAST * scale[edges]


def mean_seen_directly(ctx, seed, frame, pixel_filter, pixels, samples, stream_index=None):
    """(E, 3) mean radiance seen directly through ``samples`` jittered camera
    rays in each of ``pixels`` (E,). Without a stream_index the first of
    them is the G-buffer's own; with one (the frame's place in its stream,
    gbuffer.stream_jitter), a pixel's rays are the points stream_index *
    samples + k of its pixel filter sequence: spread evenly over the pixel,
    and over the frames of a still."""
    samples = max(1, int(samples))
    _, o, d, tmax, hits = pixel_rays(ctx, seed, frame, pixel_filter, pixels, samples, CAMERA_SAMPLE, stream_index)
    le = seen_directly(ctx, o, d, tmax, hits, *_sides(ctx.scene, d, hits))
    return le.reshape(len(pixels), samples, 3).mean(axis=1, dtype=np.float64).astype(np.float32)


def _mean_seen_on_workers(ctx, seed, frame, pixel_filter, pixels, samples, stream_index):
    """mean_seen_directly with the rays split over the context's workers
    (the edge pixels of a sunlit courtyard or a room of small lamps take up
    to one ray per image pixel): each range of rays takes the pixels whose
    first ray falls in it."""
    samples = max(1, int(samples))

    def part(a, b):
        lo, hi = -(-a // samples), -(-b // samples)
        return mean_seen_directly(ctx, seed, frame, pixel_filter, pixels[lo:hi], samples, stream_index)

    return concat_rows(ctx.workers.map(part, len(pixels) * samples))


def _sides(scene, d, hits):
    """What seen_directly reads of the surfaces hit, and the rows that hit:
    HitSides (triangle, front side) where every material's emission is
    uniform over its surface; where some graph's emission is evaluated at
    each hit (it varies over the surface or reads Light Path:
    materials.emission_per_hit), the whole SurfaceHits."""
    if scene.face_normals is None or materials.emission_per_hit(scene, camera=True):
        return surface_hits(scene, None, d, hits)
    idx = np.flatnonzero(hits.hit)
    prim = hits.prim[idx]
    front = dot(gather(scene.face_normals, prim), gather(d, idx)) <= 0
    return HitSides(prim, front), idx


@dataclass
class RefinedSeen:
    """What the running means need to know of a frame's refined edges
    (accumulation.accumulate), for the pixels of the whole image."""
    own: np.ndarray         # (P,) bool: no history of the radiance seen directly on a moving view
    ceiling: np.ndarray     # (P,) float32: most luminance seen directly in the pixel's 3x3

    def rows(self, a, b):
        return RefinedSeen(self.own[a:b], self.ceiling[a:b])


def refine_edges(ctx, seed, frame, pixel_filter, seen, lum_direct, samples, stream_index=None):
    """The radiance seen directly, ``seen`` (P, 3, the G-buffer rays'; in
    place), of the edge pixels replaced by the mean over ``samples`` camera
    rays (mean_seen_directly; stream_index: the frame's place in its
    stream). lum_direct (P,): luminance of the direct light. Returns a
    RefinedSeen, or None where there is nothing to refine (``samples`` 1 or
    no pixel filter: then every ray of a pixel is the same)."""
    scene = ctx.scene
    if samples <= 1 or len(seen) == 0 or pixel_filter.dist is None:
        return None
    lum = luminance(seen)
    edges, bright = edge_pixels(lum, lum_direct, scene.width, scene.height)
    own = np.zeros(len(seen), bool)
    if len(edges):
        # At most about one extra ray per pixel of the image in all.
        samples = min(samples, max(2, len(seen) // len(edges)))
        seen[edges] = _mean_seen_on_workers(ctx, seed, frame, pixel_filter, edges, samples, stream_index)
        own[edges[bright]] = True
        lum[edges] = luminance(seen[edges])
    # A pixel whose ray missed a moving emitter can still hold part of it
    # once refined, under its own object id (or none): the running means'
    # trail test (reprojection.previous_pixels) goes by object ids, so the
    # history of the radiance seen directly is held under the brightest of
    # this frame's pixels around it instead.
    ceiling = neighbourhood_range(lum, None, scene.width, scene.height)[0]
    return RefinedSeen(own, ceiling)
