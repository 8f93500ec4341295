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


class MaterialTable:
    """Material rows keyed by the original material, row 0 the default."""

    def __init__(self, warn):
        self.rows = [material_row(None, warn)]
        self.index = {}
        self.warn = warn

    def id_of(self, mat):
        if mat is None:
            return 0
        key = mat.original.as_pointer()
        if key not in self.index:
            self.index[key] = len(self.rows)
            self.rows.append(material_row(mat, self.warn))
        return self.index[key]

    def refresh(self, mat_original, depsgraph):
        """Re-read one material; True if its row changed."""
        i = self.index.get(mat_original.as_pointer())
        if i is None:
            return False
        row = material_row(mat_original.evaluated_get(depsgraph), self.warn)
        if row_signature(row) == row_signature(self.rows[i]):
            return False
        self.rows[i] = row
        return True

    def table(self):
        return Materials.from_list(self.rows)


def row_signature(row):
    return tuple(sorted((k, tuple(np.ravel(v).tolist()) if not isinstance(v, str) else v)
                        for k, v in row.items()))


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


def instance_key(inst, obj):
    """Identity of a placed object that stays the same from frame to frame (for
    motion between frames): its name, plus the instancer's persistent id."""
    name = obj.original.name if obj.original is not None else obj.name
    if inst.is_instance:
        return (name, tuple(inst.persistent_id))
    return (name, ())


def export_scene(depsgraph, width=None, height=None):
    """core.Scene of the evaluated depsgraph; scene.warnings lists what was approximated.

    Returns (scene, camera_found).
    """
    warn = Warnings()
    bscene = depsgraph.scene
    if width is None:
        width, height = render_size(bscene)
    materials = MaterialTable(warn)
    cache = {}
    verts, tris, normals, uvs, mids, oids, light_rows = [], [], [], [], [], [], []
    offset = 0
    object_index = {}           # instance key -> object id
    object_matrices = []
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
        key = instance_key(inst, obj)
        if key not in object_index:
            object_index[key] = len(object_index)
            object_matrices.append(np.array(inst.matrix_world, np.float32))
        oids.append(np.full(len(mesh.triangles), object_index[key], np.int32))
        offset += len(pos)

    def cat(parts, shape, dtype):
        return np.concatenate(parts).astype(dtype) if parts else np.zeros(shape, dtype)

    camera = export_camera(depsgraph, warn)
    vertices, triangles = cat(verts, (0, 3), np.float32), cat(tris, (0, 3), np.int32)
    per_tri = [cat(mids, (0,), np.int32), cat(normals, (0, 3, 3), np.float32),
               cat(uvs, (0, 3, 2), np.float32), cat(oids, (0,), np.int32)]
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
    scene.object_keys = list(object_index)
    scene.object_names = [key[0] for key in object_index]
    scene.object_matrices = (np.stack(object_matrices) if object_matrices
                             else np.zeros((0, 4, 4), np.float32))
    return scene, camera is not None
