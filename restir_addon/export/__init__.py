"""Exporter: an evaluated depsgraph to a core.Scene, with the warnings it raised."""

import numpy as np

from ...core import Lights, Materials, make_scene
from .camera import export_camera, render_size
from .lights import is_supported, light_row
from .materials import material_row
from .mesh import GEOMETRY_TYPES, place, read_mesh
from .world import export_world


class Warnings:
    """Collects each distinct warning once, in order."""

    def __init__(self):
        self.items = []

    def __call__(self, text):
        if text not in self.items:
            self.items.append(text)


class _MaterialTable:
    def __init__(self, warn):
        self.rows = [material_row(None, warn)]
        self.index = {}
        self.warn = warn

    def id_of(self, mat):
        if mat is None:
            return 0
        key = mat.as_pointer()
        if key not in self.index:
            self.index[key] = len(self.rows)
            self.rows.append(material_row(mat, self.warn))
        return self.index[key]


def _object_mesh(obj, cache):
    """MeshData of an evaluated object (cached by data block), or None."""
    if obj.type == "MESH":
        key = obj.data.as_pointer()
        if key not in cache:
            cache[key] = read_mesh(obj.data)
        return cache[key]
    key = ("converted", obj.name)
    if key not in cache:
        try:
            me = obj.to_mesh()
        except RuntimeError:
            me = None
        cache[key] = read_mesh(me) if me is not None else None
        if me is not None:
            obj.to_mesh_clear()
    return cache[key]


def export_scene(depsgraph, width=None, height=None):
    """core.Scene of the evaluated depsgraph; scene.warnings lists what was approximated.

    Returns (scene, camera_found).
    """
    warn = Warnings()
    bscene = depsgraph.scene
    if width is None:
        width, height = render_size(bscene)
    materials = _MaterialTable(warn)
    cache = {}
    verts, tris, normals, uvs, mids, oids, light_rows = [], [], [], [], [], [], []
    offset = 0
    object_index = {}
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type == "LIGHT":
            if is_supported(obj.data):
                light_rows.append(light_row(obj, inst.matrix_world, warn))
            else:
                warn(f"Light '{obj.name}' of type {obj.data.type} is not supported")
            continue
        if obj.type not in GEOMETRY_TYPES:
            continue
        mesh = _object_mesh(obj, cache)
        if mesh is None or len(mesh.triangles) == 0:
            continue
        pos, nrm = place(mesh, inst.matrix_world)
        slot_ids = np.array([materials.id_of(s.material) for s in obj.material_slots] or [0], np.int32)
        slots = np.clip(mesh.slots, 0, len(slot_ids) - 1)
        verts.append(pos)
        tris.append(mesh.triangles + offset)
        normals.append(nrm)
        uvs.append(mesh.uvs)
        mids.append(slot_ids[slots])
        name = obj.original.name if obj.original is not None else obj.name
        oids.append(np.full(len(mesh.triangles), object_index.setdefault(name, len(object_index)), np.int32))
        offset += len(pos)

    def cat(parts, shape, dtype):
        return np.concatenate(parts).astype(dtype) if parts else np.zeros(shape, dtype)

    camera = export_camera(depsgraph, warn)
    vertices, triangles = cat(verts, (0, 3), np.float32), cat(tris, (0, 3), np.int32)
    per_tri = [cat(mids, (0,), np.int32), cat(normals, (0, 3, 3), np.float32),
               cat(uvs, (0, 3, 2), np.float32), cat(oids, (0,), np.int32)]
    bad_vertex = ~np.isfinite(vertices).all(axis=1)
    if bad_vertex.any():
        # Non-finite vertices would poison the scene bounds (and every ray offset
        # derived from them) even when no kept triangle uses them: drop the
        # triangles that use them and neutralise the vertices.
        keep = ~bad_vertex[triangles].any(axis=1)
        warn(f"Skipped {int((~keep).sum())} triangle(s) with non-finite vertex coordinates")
        triangles, per_tri = triangles[keep], [a[keep] for a in per_tri]
        vertices[bad_vertex] = 0.0
    scene = make_scene(
        vertices, triangles,
        material_ids=per_tri[0],
        materials=Materials.from_list(materials.rows),
        lights=Lights.from_list(light_rows),
        camera=camera,
        world_color=export_world(bscene.world, warn),
        normals=per_tri[1],
        uvs=per_tri[2],
        object_ids=per_tri[3],
        width=width, height=height,
        filter_width=float(bscene.render.filter_size),
    )
    scene.warnings = warn.items + scene.warnings
    scene.object_names = list(object_index)
    return scene, camera is not None
