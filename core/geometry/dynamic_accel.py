"""Ray queries over a scene being edited: a static Embree scene for the objects
that stay put, and a small dynamic one for the objects that move or change.

embreex can neither refit nor instance, so any change to a triangle means a
new Embree scene. Rebuilding everything on every edit costs the whole scene's
build time per mouse move; here the first edit of an object takes it out of
the static scene (one build of the rest), and later edits of it rebuild only
the dynamic scene, which holds the edited objects alone. ``settle`` merges
them back once they stop moving, so queries go back to a single scene.

Queries take the nearer hit of the two scenes (the dynamic one is traced only
up to the static hit) and OR their occlusion; prims are numbered as in the
combined scene's triangle arrays, so ``DynamicAccel`` stands in for
``core.geometry.accel.Accel`` in a ``RenderContext``.
"""

import time

import numpy as np

from .accel import Accel, RayHits
from .boxes import crosses_box
from ..scene import column_bounds
from ..workers import forked
from ..workers.forked import LoopAbandoned


class TraceInterrupted(LoopAbandoned):
    """Raised by a query when the accel's ``interrupt`` callable returns True,
    so a frame in progress can be abandoned between two ray batches (a twin
    process running the frame's other half unwinds it too:
    core/workers/forked.py)."""


def _compact(vertices, triangles):
    """(vertices used by triangles, triangles re-indexed into them)."""
    if len(triangles) == 0:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32)
    if triangles.size * 8 < len(vertices):
        # A few objects of a large scene (the dynamic part): sort their
        # indices instead of marking and counting every vertex of the scene
        # (the same vertices in the same order; a 1M-triangle scene spent
        # 7.5 ms a frame here for one moving box).
        used, local = np.unique(triangles.ravel(), return_inverse=True)
        return (np.ascontiguousarray(np.take(vertices, used, axis=0), np.float32),
                local.reshape(-1, 3).astype(np.int32))
    used = np.zeros(len(vertices), bool)
    used[triangles.ravel()] = True
    remap = np.cumsum(used, dtype=np.int64) - 1
    return (np.ascontiguousarray(vertices[used], np.float32),
            np.ascontiguousarray(remap[triangles], np.int32))


class _Part:
    """One Embree scene over a subset of the combined scene's triangles."""

    def __init__(self, vertices, triangles, prims, threads):
        self.prims = prims.astype(np.int32)         # combined index of each local triangle
        if len(prims) * 2 > len(triangles):
            # Most of the scene (the static part): Embree takes every vertex,
            # unused ones included, rather than a compacted copy; the bounds
            # are those of all vertices (a superset: culling stays conservative).
            v, t = vertices, np.ascontiguousarray(triangles[prims], np.int32)
        else:
            v, t = _compact(vertices, triangles[prims])
        self.accel = Accel(v, t, threads)
        # Bounds, padded so float error in the slab test never culls a hit.
        lo, hi = column_bounds(v)
        pad = 1e-4 * max(float(np.abs(np.concatenate([lo, hi])).max()), float((hi - lo).max()), 1e-6)
        self.lo, self.hi = (lo - pad).astype(np.float32), (hi + pad).astype(np.float32)

    def crossing(self, o, d, limit):
        """Rows whose segment may reach this part's triangles."""
        return np.nonzero(crosses_box(o, d, limit, self.lo, self.hi))[0]

    def close(self):
        self.accel.close()


class DynamicAccel:
    """``Accel``'s queries over objects, some of which live in a small second scene.

    vertices (V, 3), triangles (T, 3) and object_ids (T,) are the combined
    scene's arrays; object_keys[i] is a key of object id i that stays the same
    from one ``update`` to the next (default: the ids themselves).
    """

    def __init__(self, vertices, triangles, object_ids, object_keys=None, threads=None, dynamic=()):
        """dynamic: keys of objects expected to move (animated): they start in
        the dynamic scene, so their first move rebuilds only that one."""
        self.threads = threads
        self.rays_traced = 0            # rays queried (each counted once, whatever the scenes)
        self.trace_seconds = 0.0
        self.static_builds = 0          # builds of the static scene
        self.dynamic_builds = 0         # builds of the dynamic scene
        self.build_seconds = 0.0
        self.interrupt = None           # callable: True aborts the next query (TraceInterrupted)
        self._static = None
        self._static_owners = None      # stable key number of each static triangle, in build order
        self._key_numbers = {}          # key -> a number that never changes
        self._dynamic = None
        self._dynamic_owners = np.zeros(0, np.int64)
        self._dynamic_prims = np.zeros(0, np.int64)
        self._dynamic_keys = set()
        self._object_ids_in = None      # the object_ids array of the last update, as passed
        # Edits so far and how to repeat the last one on a copy of this
        # structure in a twin process (core/scene_patch.py).
        self.updates = 0
        self.last_update = None
        self.update(vertices, triangles, object_ids, object_keys, changed=set(dynamic) or None)

    @staticmethod
    def from_scene(scene, threads=None):
        return DynamicAccel(scene.vertices, scene.triangles, scene.object_ids,
                            getattr(scene, "object_keys", None) or None, threads)

    # --- edits -----------------------------------------------------------------

    @property
    def triangle_count(self):
        return len(self._triangles)

    @property
    def dynamic_keys(self):
        return set(self._dynamic_keys)

    @property
    def dynamic_triangle_count(self):
        return 0 if self._dynamic is None else len(self._dynamic.prims)

    def update(self, vertices, triangles, object_ids, object_keys=None, changed=()):
        """Take the combined arrays after an edit.

        changed: keys of the objects whose triangles moved, changed or were
        added since the last call (None: build everything into the static
        scene). Objects that vanished are noticed here. Returns the tuple of
        scenes rebuilt ("static", "dynamic").
        """
        self.updates += 1
        self.last_update = ("update", None if changed is None else frozenset(changed),
                            object_ids is self._object_ids_in)
        same_layout = (changed and self._static is not None and object_ids is self._object_ids_in
                       and object_keys is not None and list(object_keys) == self._keys
                       and set(changed) <= self._dynamic_keys)
        self._object_ids_in = object_ids
        self._vertices = np.ascontiguousarray(vertices, np.float32).reshape(-1, 3)
        self._triangles = np.ascontiguousarray(triangles, np.int32).reshape(-1, 3)
        if same_layout:
            # Objects already in the dynamic scene moved again (an animation):
            # the same triangles belong to each scene, only the small one is rebuilt.
            self._build_dynamic(self._dynamic_prims, self._dynamic_owners)
            return ("dynamic",)
        self._object_ids = np.asarray(object_ids, np.int32).reshape(-1)
        n_obj = int(self._object_ids.max()) + 1 if len(self._object_ids) else 0
        keys = list(object_keys) if object_keys is not None else list(range(n_obj))
        self._keys = keys
        if changed is None:
            return self._settle()
        present = set(keys)
        dynamic = (self._dynamic_keys | set(changed)) & present
        is_dynamic = np.array([k in dynamic for k in keys] + [False], bool)[self._object_ids]
        static_prims = np.nonzero(~is_dynamic)[0]
        rebuilt = []
        owners = self._owners(static_prims)
        if self._static is None or not np.array_equal(owners, self._static_owners):
            # An object left the static scene (or vanished, or its triangles
            # were reordered): build the rest again.
            self._build_static(static_prims, owners)
            rebuilt.append("static")
        else:
            # Same objects with the same triangles: only their numbering may have moved.
            self._static.prims = static_prims.astype(np.int32)
        dynamic_prims = np.nonzero(is_dynamic)[0]
        self._dynamic_prims = dynamic_prims
        owners = self._owners(dynamic_prims)
        if set(changed) & present or not np.array_equal(owners, self._dynamic_owners):
            self._build_dynamic(dynamic_prims, owners)
            rebuilt.append("dynamic")
        elif self._dynamic is not None:
            self._dynamic.prims = dynamic_prims.astype(np.int32)
        self._dynamic_keys = dynamic
        return tuple(rebuilt)

    def replay(self, last_update, vertices, triangles, object_ids, object_keys):
        """Repeat another copy's ``last_update`` (``update`` or ``settle``)
        with the arrays it was given: object_ids as passed there, or the
        ones this copy was last given where that call passed its previous
        array again (the update then keeps its partition)."""
        if last_update[0] == "settle":
            return self.settle()
        _, changed, same_ids = last_update
        return self.update(vertices, triangles, self._object_ids_in if same_ids else object_ids,
                           object_keys, changed=None if changed is None else set(changed))

    def settle(self):
        """Merge every object into the static scene (one full build)."""
        self.updates += 1
        self.last_update = ("settle",)
        return self._settle()

    def _settle(self):
        prims = np.arange(len(self._triangles))
        self._build_static(prims, self._owners(prims))
        if self._dynamic is not None:
            self._dynamic.close()
        self._dynamic = None
        self._dynamic_owners = np.zeros(0, np.int64)
        self._dynamic_prims = np.zeros(0, np.int64)
        self._dynamic_keys = set()
        return ("static",)

    def _owners(self, prims):
        """Stable number of the object of each triangle in prims: the static
        scene stays valid while this sequence does (numbering may shift)."""
        for k in self._keys:
            self._key_numbers.setdefault(k, len(self._key_numbers))
        numbers = np.array([self._key_numbers[k] for k in self._keys] + [-1], np.int64)
        return numbers[self._object_ids[prims]]

    def _build_static(self, prims, owners):
        t0 = time.perf_counter()
        if self._static is not None:
            self._static.close()
        self._static = _Part(self._vertices, self._triangles, prims, self.threads)
        self._static_owners = owners
        self.static_builds += 1
        self.build_seconds += time.perf_counter() - t0

    def _build_dynamic(self, prims, owners):
        t0 = time.perf_counter()
        self._dynamic_owners = owners
        if self._dynamic is not None:
            self._dynamic.close()
        self._dynamic = _Part(self._vertices, self._triangles, prims, self.threads) if len(prims) else None
        if self._dynamic is not None:
            self.dynamic_builds += 1
        self.build_seconds += time.perf_counter() - t0

    def close(self):
        for part in (self._static, self._dynamic):
            if part is not None:
                part.close()
        self._static = self._dynamic = None

    # --- queries ---------------------------------------------------------------

    def poll(self):
        """Raise TraceInterrupted if ``interrupt`` says so: every query does,
        and long passes without queries call it between their steps."""
        if self.interrupt is None:
            return
        # In a twin process the callable is a copy of the leader's, which
        # nothing sets there: the leader's abandon comes through the twin.
        if forked.told_to_stop() if forked.in_twin() else self.interrupt():
            raise TraceInterrupted()

    def _query(self, origins, directions):
        """(start time, origins, directions) of a query, after the interrupt poll."""
        self.poll()
        return (time.perf_counter(), np.asarray(origins, np.float32).reshape(-1, 3),
                np.asarray(directions, np.float32).reshape(-1, 3))

    def intersect_closest(self, origins, directions, tmax=None, camera=False):
        t0, o, d = self._query(origins, directions)
        n = len(o)
        if self._static is None:
            return RayHits(np.full(n, np.inf, np.float32), np.full(n, -1, np.int32),
                           np.zeros(n, np.float32), np.zeros(n, np.float32))
        hits = self._static.accel.intersect_closest(o, d, tmax)
        prim = np.where(hits.prim >= 0, self._static.prims[np.maximum(hits.prim, 0)]
                        if len(self._static.prims) else -1, -1).astype(np.int32)
        t, u, v = hits.t, hits.u, hits.v
        if self._dynamic is not None and n:
            # Only rays that reach the moving objects' box before their static
            # hit are traced again, and only up to that hit.
            far = np.inf if tmax is None else np.broadcast_to(np.asarray(tmax, np.float32), (n,))
            limit = np.where(prim >= 0, t, far).astype(np.float32)
            rows = self._dynamic.crossing(o, d, limit)
            if len(rows):
                near = self._dynamic.accel.intersect_closest(o[rows], d[rows], limit[rows])
                take = near.prim >= 0
                rows = rows[take]
                prim[rows] = self._dynamic.prims[near.prim[take]]
                t, u, v = t.copy(), u.copy(), v.copy()
                t[rows], u[rows], v[rows] = near.t[take], near.u[take], near.v[take]
        self.rays_traced += n
        self.trace_seconds += time.perf_counter() - t0
        return RayHits(t, prim, u, v)

    def occluded(self, origins, directions, tmax):
        t0, o, d = self._query(origins, directions)
        n = len(o)
        if self._static is None:
            return np.zeros(n, bool)
        blocked = self._static.accel.occluded(o, d, tmax)
        if self._dynamic is not None and n:
            dist = np.broadcast_to(np.asarray(tmax, np.float32), (n,))
            rows = np.nonzero(~blocked)[0]
            if len(rows):
                rows = rows[self._dynamic.crossing(o[rows], d[rows], dist[rows])]
            if len(rows):
                blocked[rows] = self._dynamic.accel.occluded(o[rows], d[rows], dist[rows])
        self.rays_traced += n
        self.trace_seconds += time.perf_counter() - t0
        return blocked
