"""Primary visibility: the visible point of every pixel (the G-buffer)."""

import dataclasses
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..materials import shading as materials
from ..sampling import samplers
from ..camera.projection import generate_rays, view_depth
from ..integrators.base import ShadingFrame
from ..geometry.interaction import SurfaceHits, surface_hits
from ..workers.parallel import concat_rows
from .reservoirs import Reservoirs
from ..util.rows import gather, scatter, scatter_add


@dataclass
class GBuffer:
    """One visible point per pixel; rows of misses hold zeros and valid False."""
    valid: np.ndarray       # (P,) bool
    surf: SurfaceHits       # the valid rows only, in pixel order (None when split in parts)
    frame: ShadingFrame     # BSDF parameters and shading frames of those rows (idem)
    index: np.ndarray       # (V,) pixel index of each valid row
    depth: np.ndarray       # (P,) view depth, 1e10 on misses
    object_id: np.ndarray   # (P,) int32, -1 on misses
    emission: np.ndarray    # (P, 3) radiance seen directly: emitters, camera-visible lights, world
    albedo: np.ndarray      # (P, 3)
    width: int
    height: int
    offset: int = 0         # pixel index of row 0 (a part of the image: see part())
    parts: dict = dataclasses.field(default=None, repr=False)   # (start, stop) -> GBuffer
    pixels: np.ndarray = None   # (P,) image-wide pixel index of each row, where the rows are
                                # scattered pixels (trace_rows' ``pixels``); else offset + row

    def ids(self, rows):
        """Image-wide pixel indices of rows (the seeds of their random numbers)."""
        return rows + self.offset if self.pixels is None else self.pixels[rows]

    def part(self, start, stop):
        """The pixels [start, stop) as a GBuffer of their own (rows of a pass
        that workers split; offset keeps their image-wide pixel index)."""
        if self.parts is not None and (start, stop) in self.parts:
            return self.parts[(start, stop)]
        if start == 0 and stop == len(self.valid):
            return self
        lo, hi = np.searchsorted(self.index, [start, stop])
        rows = np.arange(lo, hi)
        return GBuffer(self.valid[start:stop], self.surf.subset(rows), self.frame.subset(rows),
                       self.index[lo:hi] - start, self.depth[start:stop], self.object_id[start:stop],
                       self.emission[start:stop], self.albedo[start:stop], self.width, self.height,
                       self.offset + start)

    def _image(self, name):
        if self.parts is not None and len(self.parts) > 1:     # the parts have theirs
            return np.concatenate([getattr(part, name) for part in self.parts.values()])
        rows = getattr(self.surf, "ns" if name == "n" else name)
        return scatter(np.zeros((len(self.valid), 3), np.float32), self.index, rows)

    @cached_property
    def p(self):
        """(P, 3) positions (zeros on misses)."""
        return self._image("p")

    @cached_property
    def ng(self):
        return self._image("ng")

    @cached_property
    def n(self):
        return self._image("n")

    def images(self):
        """(p, n, ng) of the whole image, computed now (cached_property is not
        safe to fill from several threads at once)."""
        return self.p, self.n, self.ng


@dataclass
class FirstPass:
    """Whole-image outputs of a frame's first pass (G-buffer, initial samples,
    temporal resampling) that the rest of the frame reads."""
    valid: np.ndarray       # (P,) bool
    depth: np.ndarray       # (P,)
    object_id: np.ndarray   # (P,) int32
    p: np.ndarray           # (P, 3) visible points (zeros on misses)
    n: np.ndarray           # (P, 3) shading normals
    ng: np.ndarray          # (P, 3) geometric normals
    albedo: np.ndarray      # (P, 3)
    direct: np.ndarray      # (P, 3) direct light of the visible points
    lum_direct: np.ndarray  # (P,) its luminance (adaptive_direct.py)
    seen: np.ndarray        # (P, 3) radiance seen directly: emitters, visible lamps, world
    glossy: np.ndarray      # (P, 3) the glossy lobe's indirect light
    diffuse: np.ndarray     # (P, 3) diffuse reflectance of the visible points
    alpha: np.ndarray       # (P,) this frame's coverage (materials.camera_alpha)
    keep: np.ndarray        # (P,) share of the pixel a holdout leaves
    prev_pix: np.ndarray    # (P,) int32 last frame's pixel (-1: no history)
    hold: np.ndarray        # (P,) int8 reprojected noise hold, or None
    temporal: object        # Reservoirs
    glossy_samples: object = None   # GlossySamples (glossy_reuse.py), or None without path reuse
    sky: np.ndarray = None  # (P,) luminance of the sky rays' light (part of direct)
    sample_value: np.ndarray = None     # (P,) the first initial sample's weight (gradients.py)

    @staticmethod
    def allocate(n, shaded, with_hold, glossy_samples=None):
        """Whole-image arrays for n pixels, the colours and factors in the
        columns of ``shaded`` (P, COLUMNS): direct 0:3, glossy 3:6, albedo
        6:9 and seen 14:17 where the running means (accumulation.py) will
        have them, diffuse 9:12, keep 12 and alpha 13."""
        vec = lambda: np.empty((n, 3), np.float32)  # noqa: E731
        return FirstPass(np.empty(n, bool), np.empty(n, np.float32), np.empty(n, np.int32), vec(), vec(),
                         vec(), shaded[:, 6:9], shaded[:, 0:3], np.empty(n, np.float32),
                         shaded[:, 14:17], shaded[:, 3:6],
                         shaded[:, 9:12], shaded[:, 13], shaded[:, 12], np.empty(n, np.int32),
                         np.empty(n, np.int8) if with_hold else None, Reservoirs.empty(0).whole_image(n),
                         glossy_samples, np.empty(n, np.float32), np.empty(n, np.float32))


@dataclass
class FrameImage:
    """The whole-image G-buffer arrays of a frame (what spatial reuse reads of
    neighbours, and the history kept for the next frame)."""
    valid: np.ndarray
    depth: np.ndarray
    object_id: np.ndarray
    p: np.ndarray
    n: np.ndarray
    ng: np.ndarray
    width: int
    height: int

    def part(self, start, stop, diffuse):
        """A GBuffer of pixels [start, stop) with what the passes after the
        first read of its visible points: position, normals and (diffuse)
        the diffuse reflectance, gathered from whole-image arrays."""
        valid = self.valid[start:stop]
        index = np.flatnonzero(valid)
        surf = VisiblePoints(gather(self.p[start:stop], index), gather(self.ng[start:stop], index),
                             gather(self.n[start:stop], index))
        frame = DiffuseOnly(gather(diffuse[start:stop], index))
        return GBuffer(valid, surf, frame, index, self.depth[start:stop], self.object_id[start:stop],
                       None, None, self.width, self.height, start)


@dataclass
class DiffuseOnly:
    """What the passes after the first read of a ShadingFrame: its BSDF
    parameters' diffuse reflectance (shading.shade_indirect), as
    ``frame.params.diffuse``."""
    diffuse: np.ndarray     # (V, 3)

    @property
    def params(self):
        return self


@dataclass
class VisiblePoints:
    """The fields of SurfaceHits that shading and reprojection read."""
    p: np.ndarray
    ng: np.ndarray
    ns: np.ndarray


def trace_gbuffer(ctx, seed, frame, pixel_filter, jitter=True, stream_index=None):
    """Trace one primary ray per pixel (jittered by the pixel filter), the
    pixel ranges on the context's workers."""
    scene = ctx.scene
    n = scene.width * scene.height
    parts = ctx.workers.map(lambda a, b: trace_rows(ctx, seed, frame, pixel_filter, jitter, a, b, stream_index), n)
    ranges = [(g.offset, g.offset + len(g.valid)) for g in parts]      # (a twin may split elsewhere)
    if len(parts) == 1:
        return parts[0]
    # The whole image's per-pixel arrays; its hits and shading frames stay
    # in the parts (passes read them per range), not copied a second time.
    per_pixel = ("valid", "depth", "object_id", "emission", "albedo")
    joined = GBuffer(**{f: concat_rows([getattr(g, f) for g in parts]) for f in per_pixel},
                     surf=None, frame=None, index=np.concatenate([g.index + g.offset for g in parts]),
                     width=parts[0].width, height=parts[0].height, offset=0,
                     parts=dict(zip(ranges, parts)))
    return joined


CAMERA_SAMPLE = 0xC0FFEE      # the sample number of the G-buffer's camera rays (path_seeds)


def camera_rays(scene, pixel_filter, pix, seeds, jitter=None):
    """Camera rays (o, d, tmax) through pixels pix (N,), jittered by the
    pixel filter and over the lens (depth of field) with each seed's camera
    dimensions (centres through the lens centre if seeds is None). jitter:
    (N, 2) uniforms for the pixel filter instead of the seeds' own."""
    w, h = scene.width, scene.height
    xy = np.stack([pix % w, pix // w], axis=1).astype(np.float32) + 0.5
    lens = time = None
    if seeds is not None:
        xy += pixel_filter.offsets(samplers.uniform2(seeds, samplers.DIM_CAMERA) if jitter is None else jitter)
        lens = samplers.lens_uniforms(scene.camera, seeds)
        time = samplers.time_uniforms(scene.camera, seeds)      # a camera moving over the shutter
    return generate_rays(scene.camera, w, h, xy, lens, time)


def stream_jitter(seed, pix, index):
    """(N, 2) pixel filter uniforms of pixels pix (N,) for point ``index``
    (an integer, or (N,) integers) of their image stream's sequence: the
    camera's dimensions of each pixel's Sobol points (samplers.sobol_jitter),
    whose first bounce's dimensions the initial samples follow. Each point
    is uniform, as a hashed one, but a pixel's points over consecutive
    indices (its frames) cover its filter evenly, so the running means and a
    still's mean of frames converge faster at edges, as Cycles' pattern does
    over its samples. A straight edge's covered share from a still's 16
    points (tests/core/sampling/test_samplers.py): squared error 0.0020, against 0.0040
    for the R2 sequence rotated per pixel used before and 0.013 for
    independent points."""
    return samplers.sobol_jitter(samplers.hash_keys(seed, pix, CAMERA_SAMPLE), index)


def pixel_rays(ctx, seed, frame, pixel_filter, pixels, samples, sample, stream_index=None):
    """``samples`` camera rays through each of ``pixels`` (E,), traced:
    (seeds (E * samples,), o, d, tmax, hits), pixel by pixel in a row. Ray k
    of a pixel has the path seed of sample number ``sample`` + k and, with
    a stream_index (the frame's place in its stream), the point
    stream_index * samples + k of the pixel's filter sequence (stream_jitter):
    spread evenly over the pixel, and over the frames of a still."""
    rep = np.repeat(np.asarray(pixels, np.int64), samples)
    k = np.tile(np.arange(samples, dtype=np.int64), len(pixels))
    seeds = samplers.path_seeds(seed, frame, rep, sample + k)
    along = None if stream_index is None else stream_jitter(seed, rep, stream_index * samples + k)
    o, d, tmax = camera_rays(ctx.scene, pixel_filter, rep, seeds, along)
    return seeds, o, d, tmax, ctx.accel.intersect_closest(o, d, tmax, camera=True)


def seen_directly(ctx, o, d, tmax, hits, surf, idx):
    """(N, 3) radiance camera rays see directly: camera-visible lights, the
    world where they miss (unless the film is transparent) and the emission
    of the surfaces hit (surf: surface_hits of the rows idx)."""
    emission = ctx.lights.emitted_along(o, d, np.minimum(hits.t, tmax))
    miss = np.nonzero(~hits.hit & (np.asarray(tmax) > 0))[0]     # tmax 0: outside a fisheye's lens
    if len(miss) and ctx.lights.environment is not None and not ctx.scene.film_transparent:
        scatter_add(emission, miss, ctx.lights.world_radiance(gather(d, miss), camera=True))
    if len(idx):
        scatter_add(emission, idx, materials.camera_emission(ctx.scene, surf, ctx.lights))
    return emission


def trace_rows(ctx, seed, frame, pixel_filter, jitter, start, stop, stream_index=None, pixels=None, aim=None):
    """The GBuffer of pixels [start, stop) (offset start), or with ``pixels``
    of those image-wide pixel indices (start and stop unused). stream_index:
    the frame's place in its image stream, whose pixel filter positions then
    follow stream_jitter (else each frame's are hashed anew). aim: (rows
    (K,), points (K, 3)): those rows' rays re-aimed from their origins at
    the points, or None."""
    scene = ctx.scene
    w, h = scene.width, scene.height
    pix = np.arange(start, stop, dtype=np.int64) if pixels is None else np.asarray(pixels, np.int64)
    n = len(pix)
    seeds = samplers.path_seeds(seed, frame, pix, CAMERA_SAMPLE) if jitter else None
    along = stream_jitter(seed, pix, stream_index) if jitter and stream_index is not None else None
    o, d, tmax = camera_rays(scene, pixel_filter, pix, seeds, along)
    if aim is not None and len(aim[0]):
        rows, points = aim
        to = np.asarray(points, np.float64) - o[rows]
        length = np.linalg.norm(to, axis=1, keepdims=True)
        d[rows] = (to / np.maximum(length, 1e-30)).astype(d.dtype)
        tmax[rows] = 2.0 * length[:, 0] + 1e-6      # past the point (a camera ray's clip range may end before it)
    hits = ctx.accel.intersect_closest(o, d, tmax, camera=True)
    surf, idx = surface_hits(scene, o, d, hits)
    emission = seen_directly(ctx, o, d, tmax, hits, surf, idx)
    valid = np.zeros(n, bool)
    valid[idx] = True
    depth = np.full(n, 1e10, np.float32)
    object_id = np.full(n, -1, np.int32)
    albedo = np.zeros((n, 3), np.float32)
    frame_sh = ShadingFrame.at(scene, surf, camera_ray=True)
    if len(idx):
        depth[idx] = view_depth(scene.camera, surf.p)
        object_id[idx] = np.take(scene.object_ids, surf.prim)
        scatter(albedo, idx, np.clip(frame_sh.params.diffuse + frame_sh.params.f0, 0.0, 1.0))
    if pixels is not None:
        return GBuffer(valid, surf, frame_sh, idx, depth, object_id, emission, albedo, w, h, 0, pixels=pix)
    return GBuffer(valid, surf, frame_sh, idx, depth, object_id, emission, albedo, w, h, start)
