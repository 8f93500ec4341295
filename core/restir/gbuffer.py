"""Primary visibility: the visible point of every pixel (the G-buffer)."""

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .. import samplers
from ..camera import generate_rays, view_depth
from ..integrators.base import ShadingFrame
from ..interaction import SurfaceHits, surface_hits
from ..rows import scatter


@dataclass
class GBuffer:
    """One visible point per pixel; rows of misses hold zeros and valid False."""
    valid: np.ndarray       # (P,) bool
    surf: SurfaceHits       # the valid rows only, in pixel order
    frame: ShadingFrame     # BSDF parameters and shading frames of those rows
    index: np.ndarray       # (V,) pixel index of each valid row
    depth: np.ndarray       # (P,) view depth, 1e10 on misses
    object_id: np.ndarray   # (P,) int32, -1 on misses
    emission: np.ndarray    # (P, 3) radiance seen directly: emitters, camera-visible lights, world
    albedo: np.ndarray      # (P, 3)
    width: int
    height: int

    def _image(self, rows):
        return scatter(np.zeros((len(self.valid), 3), np.float32), self.index, rows)

    @cached_property
    def p(self):
        """(P, 3) positions (zeros on misses)."""
        return self._image(self.surf.p)

    @cached_property
    def ng(self):
        return self._image(self.surf.ng)

    @cached_property
    def n(self):
        return self._image(self.surf.ns)


def trace_gbuffer(ctx, seed, frame, pixel_filter, jitter=True):
    """Trace one primary ray per pixel (jittered by the pixel filter)."""
    scene = ctx.scene
    w, h = scene.width, scene.height
    n = w * h
    pix = np.arange(n, dtype=np.int64)
    xy = np.stack([pix % w, pix // w], axis=1).astype(np.float32) + 0.5
    if jitter:
        seeds = samplers.path_seeds(seed, frame, pix, 0xC0FFEE)
        xy += pixel_filter.offsets(samplers.uniform2(seeds, samplers.DIM_CAMERA))
    o, d, tmax = generate_rays(scene.camera, w, h, xy)
    hits = ctx.accel.intersect_closest(o, d, tmax)
    emission = ctx.lights.emitted_along(o, d, np.minimum(hits.t, tmax))
    emission[~hits.hit] += scene.world_color
    surf, idx = surface_hits(scene, o, d, hits)
    valid = np.zeros(n, bool)
    valid[idx] = True
    depth = np.full(n, 1e10, np.float32)
    object_id = np.full(n, -1, np.int32)
    albedo = np.zeros((n, 3), np.float32)
    frame = ShadingFrame.at(scene, surf)
    if len(idx):
        if len(ctx.lights.tri_index):
            emission[idx] += ctx.lights.triangle_emission(surf.prim, surf.front)
        depth[idx] = view_depth(scene.camera, surf.p)
        object_id[idx] = np.take(scene.object_ids, surf.prim)
        scatter(albedo, idx, np.clip(frame.params.diffuse + frame.params.f0, 0.0, 1.0))
    return GBuffer(valid, surf, frame, idx, depth, object_id, emission, albedo, w, h)
