"""The viewport's combined scene: every instance's triangles in world space,
concatenated into the arrays a core Scene is made of, and updated in place
when an edit keeps each changed object's vertex and triangle counts (a move,
a material slot change, a mesh edit of the same size)."""

import numpy as np

from ...core.scene import column_bounds
from ..export import corner_data, object_random, placed_corners
from ..export.object_attributes import attribute_tables
from .objects import placed_instance

NAMES = ("vertices", "triangles", "normals", "uvs", "material_ids", "object_ids", "face_normals")
_EMPTY_SHAPES = {"vertices": (0, 3), "triangles": (0, 3), "normals": (0, 3, 3), "uvs": (0, 3, 2),
                 "material_ids": (0,), "object_ids": (0,), "face_normals": (0, 3)}
_INT = {"triangles", "material_ids", "object_ids"}


def _material_ids(inst):
    return inst.slot_ids[np.clip(inst.mesh.slots, 0, len(inst.slot_ids) - 1)]


class CombinedArrays:
    """``arrays``: name -> array for the names in NAMES, plus ``keys`` (the
    instance key of each object id), ``matrices`` (their world matrices),
    ``colors`` (O, 4), ``random`` (O,) and ``visibility`` (O, 5) per object."""

    def __init__(self):
        self.arrays = None
        self._layout = {}       # key -> (v0, v1, t0, t1) rows in the combined arrays
        self.placed_instance = {}       # key -> viewport_sync.placed_instance: (positions, normals, face normals,
                                # triangles, uvs) in world space
        self._bounds = np.zeros((0, 2, 3), np.float32)  # per object id: (lo, hi) of its vertices
        self._has_vertices = np.zeros(0, bool)

    def update(self, instances, changed, reslotted, relayout):
        """Bring the arrays up to date with ``instances`` (key -> instance):
        ``changed`` keys moved or were re-meshed, ``reslotted`` changed
        material slots; ``relayout`` (objects added or removed) rebuilds."""
        for key in changed | (self.placed_instance.keys() - instances.keys()):
            self.placed_instance.pop(key, None)
        in_place = self.arrays is not None and not relayout and all(
            key in self._layout and self._fits(key, instances[key]) for key in changed | reslotted)
        # Corner data (textured materials) is rebuilt whole on a change.
        in_place = in_place and not (changed and any(it.mesh.corners for it in instances.values()))
        if not in_place:
            self._assemble(instances)
            self._per_object(instances)
            return self.arrays
        a = self.arrays
        for key in changed | reslotted:
            v0, v1, t0, t1 = self._layout[key]
            it = instances[key]
            if key in changed:
                pos, nrm, fn, tris, uvs = self._place(key, it)
                a["vertices"][v0:v1], a["normals"][t0:t1], a["face_normals"][t0:t1] = pos, nrm, fn
                a["triangles"][t0:t1] = tris + v0
                a["uvs"][t0:t1] = uvs
                oid = a["keys"].index(key)
                a["matrices"][oid] = it.matrix
                if len(pos):
                    self._bounds[oid] = column_bounds(pos)
            a["material_ids"][t0:t1] = _material_ids(it)
        if reslotted:
            self._per_object(instances)
        return a

    def bounds(self):
        """(lo, hi) of every vertex, from the objects' own (Scene.known_bounds):
        a frame that moves one object does not pass over the others."""
        b = self._bounds[self._has_vertices]
        if len(b) == 0:
            return np.zeros(3, np.float32), np.zeros(3, np.float32)
        return b[:, 0].min(axis=0), b[:, 1].max(axis=0)

    def _per_object(self, instances):
        """Object Info colour, random number and index, ray visibility, by object id."""
        a = self.arrays
        its = list(instances.values())
        a["colors"] = np.array([it.color for it in its], np.float32).reshape(-1, 4)
        a["visibility"] = np.array([it.visibility for it in its], bool).reshape(-1, 5)
        a["random"] = np.array([object_random(k[:2]) for k in instances], np.float32)
        a["pass_index"] = np.array([it.pass_index for it in its], np.float32)
        a["attributes"] = attribute_tables([it.attributes for it in its])
        a["holdout"] = np.array([it.holdout for it in its], bool)

    def free(self):
        self.arrays = None
        self._layout = {}
        self.placed_instance = {}
        self._bounds, self._has_vertices = np.zeros((0, 2, 3), np.float32), np.zeros(0, bool)

    def _fits(self, key, inst):
        v0, v1, t0, t1 = self._layout[key]
        return v1 - v0 == len(inst.mesh.positions) and t1 - t0 == len(inst.mesh.triangles)

    def _place(self, key, inst):
        if key not in self.placed_instance:
            self.placed_instance[key] = placed_instance(inst)
        return self.placed_instance[key]

    def _assemble(self, instances):
        """Combined arrays of every instance (placed ones reused from the cache)."""
        parts = {name: [] for name in NAMES}
        layout, keys, matrices = {}, [], []
        v_off = t_off = 0
        for oid, (key, it) in enumerate(instances.items()):
            pos, nrm, fn, tris, uvs = self._place(key, it)
            nv, nt = len(pos), len(tris)
            for name, value in (("vertices", pos), ("triangles", tris + v_off),
                                ("normals", nrm), ("uvs", uvs), ("material_ids", _material_ids(it)),
                                ("object_ids", np.full(nt, oid, np.int32)), ("face_normals", fn)):
                parts[name].append(value)
            layout[key] = (v_off, v_off + nv, t_off, t_off + nt)
            keys.append(key)
            matrices.append(it.matrix)
            v_off += nv
            t_off += nt
        a = {}
        for name, items in parts.items():
            dtype = np.int32 if name in _INT else np.float32
            a[name] = np.concatenate(items, dtype=dtype) if items else np.zeros(_EMPTY_SHAPES[name], dtype)
        a["keys"] = keys
        a["matrices"] = (np.stack(matrices).astype(np.float32) if matrices
                         else np.zeros((0, 4, 4), np.float32))
        a["corner_data"] = corner_data(
            [placed_corners(it.mesh.corners, it.matrix) for it in instances.values()],
            [it.mesh.triangles for it in instances.values()])
        self.arrays = a
        self._layout = layout
        self._object_bounds(a["vertices"], [layout[k][:2] for k in keys])

    def _object_bounds(self, vertices, spans):
        """Per object id, the bounds of its rows of ``vertices`` (one
        reduceat per column over the whole array)."""
        spans = np.array(spans, np.int64).reshape(-1, 2)
        self._has_vertices = spans[:, 1] > spans[:, 0]
        self._bounds = np.zeros((len(spans), 2, 3), np.float32)
        starts = spans[self._has_vertices, 0]
        if len(starts):
            for k in range(3):
                column = np.ascontiguousarray(vertices[:, k])
                self._bounds[self._has_vertices, 0, k] = np.minimum.reduceat(column, starts)
                self._bounds[self._has_vertices, 1, k] = np.maximum.reduceat(column, starts)
