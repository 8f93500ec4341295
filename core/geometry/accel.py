"""Ray queries on whole batches through Embree (embreex).

``intersect_closest`` and ``occluded`` take (N, 3) origins and unit directions.
Embree's tnear is fixed at 0, so callers offset origins (see ``offset_origins``).
Large batches are split across threads: embreex releases the GIL inside
``run()``, so two halves on two cores run in parallel.
"""

import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..workers.parallel import in_worker
from ..util.rows import rows_finite, scale

_SPLIT_MIN = 16384          # below this a batch is traced on the calling thread
_FAR = np.float32(1e30)


@dataclass
class RayHits:
    """Closest hits of a batch; prim == -1 where the ray missed."""
    t: np.ndarray       # (N,) float32 distance along the unit direction
    prim: np.ndarray    # (N,) int32 triangle index
    u: np.ndarray       # (N,) float32 barycentric of vertex 1
    v: np.ndarray       # (N,) float32 barycentric of vertex 2

    @property
    def hit(self):
        return self.prim >= 0


def _prepare(origins, directions, tmax):
    o = np.ascontiguousarray(origins, dtype=np.float32).reshape(-1, 3)
    d = np.ascontiguousarray(directions, dtype=np.float32).reshape(-1, 3)
    if len(o) != len(d):  # embreex segfaults on mismatched lengths
        raise ValueError(f"{len(o)} origins but {len(d)} directions")
    if tmax is None:
        dist = np.full(len(o), _FAR, dtype=np.float32)
    else:
        dist = np.array(np.broadcast_to(np.asarray(tmax, np.float32), (len(o),)), dtype=np.float32)
        if len(dist) != len(o):
            raise ValueError("tmax must have one entry per ray")
    # Unbounded rays go as far as rays without tmax.
    dist = np.where(dist == np.inf, _FAR, dist).astype(np.float32)
    # Non-finite input must never reach Embree: such rays are traced as harmless
    # stand-ins (which can still touch geometry through the origin at t = 0) and
    # their results are discarded by the callers through ``bad``.
    bad = ~(rows_finite(o) & rows_finite(d) & (dist > 0))
    if bad.any():
        o = np.where(bad[:, None], 0.0, o).astype(np.float32)
        d = np.where(bad[:, None], np.float32([0, 0, 1]), d).astype(np.float32)
        dist = np.where(bad, np.float32(1e-30), dist).astype(np.float32)
    return o, d, dist, bad


class Accel:
    """An Embree scene over a Scene's triangles, with thread-split batch queries."""

    def __init__(self, vertices, triangles, threads=None):
        from embreex import rtcore_scene  # noqa: PLC0415 (Embree's library: loaded when a scene is built)
        from embreex.mesh_construction import TriangleMesh  # noqa: PLC0415

        self.triangle_count = len(triangles)
        self.rays_traced = 0          # counters for benchmarks: rays and seconds in Embree
        self.trace_seconds = 0.0
        self.threads = max(1, threads or min(os.cpu_count() or 1, 2))
        self._pool = ThreadPoolExecutor(self.threads) if self.threads > 1 else None
        self._scene = None
        if self.triangle_count == 0:
            return
        v = np.ascontiguousarray(vertices, dtype=np.float32)
        v = np.where(np.isfinite(v), v, 0.0).astype(np.float32)
        self._scene = rtcore_scene.EmbreeScene(robust=True)
        TriangleMesh(self._scene, v, np.ascontiguousarray(triangles, dtype=np.int32))
        # Embree commits lazily on the first query: do it here, before threads race.
        one = np.zeros((1, 3), np.float32)
        self._scene.run(one, np.float32([[0, 0, 1]]), np.float32([1e-30]))

    @staticmethod
    def from_scene(scene, threads=None):
        return Accel(scene.vertices, scene.triangles, threads)

    def close(self):
        if self._pool is not None:
            self._pool.shutdown(wait=False)
            self._pool = None
        self._scene = None

    def poll(self):
        """A point where long passes without ray queries may be interrupted
        (core/geometry/dynamic_accel.py); this structure is never interrupted."""

    def _map(self, fn, n):
        """Run fn(start, stop) over chunks of [0, n), in parallel when it pays."""
        if self._pool is None or n < _SPLIT_MIN or in_worker():
            return [fn(0, n)]
        bounds = np.linspace(0, n, self.threads + 1).astype(int)
        futures = [self._pool.submit(fn, a, b) for a, b in zip(bounds[:-1], bounds[1:])]
        return [f.result() for f in futures]

    def intersect_closest(self, origins, directions, tmax=None, camera=False):
        """Closest hits (RayHits). camera: the rays come from the camera (for
        wrappers that hide objects from camera rays; ignored here)."""
        o, d, dist, bad = _prepare(origins, directions, tmax)
        n = len(o)
        if self._scene is None or n == 0:
            return RayHits(np.full(n, np.inf, np.float32), np.full(n, -1, np.int32),
                           np.zeros(n, np.float32), np.zeros(n, np.float32))

        def run(a, b):
            return self._scene.run(o[a:b], d[a:b], dist[a:b], output=True)

        t0 = time.perf_counter()
        parts = self._map(run, n)
        self.trace_seconds += time.perf_counter() - t0
        self.rays_traced += n
        prim = np.concatenate([p["primID"] for p in parts]).astype(np.int32)
        prim[bad] = -1
        t = np.concatenate([p["tfar"] for p in parts]).astype(np.float32)
        t = np.where(prim >= 0, t, np.inf).astype(np.float32)
        u = np.concatenate([p["u"] for p in parts]).astype(np.float32)
        v = np.concatenate([p["v"] for p in parts]).astype(np.float32)
        return RayHits(t, prim, u, v)

    def occluded(self, origins, directions, tmax):
        """True where something lies between origin and origin + tmax * direction."""
        o, d, dist, bad = _prepare(origins, directions, tmax)
        n = len(o)
        if self._scene is None or n == 0:
            return np.zeros(n, bool)

        def run(a, b):
            return self._scene.run(o[a:b], d[a:b], dist[a:b], query="OCCLUDED")

        t0 = time.perf_counter()
        blocked = (np.concatenate(self._map(run, n)) >= 0) & ~bad
        self.trace_seconds += time.perf_counter() - t0
        self.rays_traced += n
        return blocked


def offset_origins(p, ng, direction, eps):
    """Move points off their surface along the geometric normal, to the side the
    ray leaves from (Embree's tnear is 0, so this avoids self-intersection)."""
    dn = ng[:, 0] * direction[:, 0] + ng[:, 1] * direction[:, 1] + ng[:, 2] * direction[:, 2]
    side = np.where(dn >= 0, eps, -eps).astype(np.float32)
    return (p + scale(ng, side)).astype(np.float32)
