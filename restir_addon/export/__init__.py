"""Exporter: an evaluated depsgraph to a core.Scene, with the warnings it raised."""

import hashlib

import numpy as np

from ...core import Lights, make_scene
from ...core.materials.shading import shading
from .camera import export_camera, render_size
from .lights import is_supported, light_row
from .materials import MaterialTable
from .mesh import (GEOMETRY_TYPES, SWAP, base_mesh, hair_warning, in_edit_mode, mirrors, place, placed_triangles,
                   read_corner_data, read_mesh, unrendered)
from .strands import STRAND_TYPES, has_particle_hair, pad_corners, read_strands, with_particle_hair
from .object_attributes import attribute_tables, object_attributes, split_needs
from .volume_objects import GridFiles, volume_grids
from .world import evaluated_world, export_world


class Warnings:
    """Collects each distinct warning once, in order."""

    def __init__(self):
        self.items = []

    def __call__(self, text):
        if text not in self.items:
            self.items.append(text)


def _object_mesh(obj, cache, keys, warn):
    """(MeshData, corner data) of an evaluated object, cached by data block
    (corner data read for ``keys``, more read when a later user needs more);
    None where the object has no usable geometry (with a warning)."""
    if obj.type in STRAND_TYPES:
        key = obj.data.as_pointer()
        if key not in cache:
            mesh = read_strands(obj, warn)
            cache[key] = None if mesh is None else (mesh, {})
        return cache[key]
    if obj.type == "MESH" and not in_edit_mode(obj.data):
        hair = has_particle_hair(obj)       # the object's own strands: not shared with the mesh's other users
        key = ("hair", obj.name) if hair else obj.data.as_pointer()
        if key not in cache:
            entry = _read(obj.data, obj.name, warn)
            if hair:
                mesh = with_particle_hair(obj, None if entry is None else entry[0], warn)
                shown = entry is not None and getattr(obj, "show_instancer_for_render", True)
                # The mesh's corner data goes with it only while the emitter is rendered.
                entry = None if mesh is None else (mesh, entry[1] if shown else {})
            cache[key] = entry
            text = hair_warning(obj, None)
            if text:
                warn(text)
        entry = cache[key]
        emitter = not hair or getattr(obj, "show_instancer_for_render", True)
        if entry is not None and emitter and not keys <= set(entry[1]):
            entry[1].update(read_corner_data(obj.data, keys - set(entry[1]), warn, obj.name, base_mesh(obj)))
        if hair and entry is not None:
            return entry[0], pad_corners(entry[1], entry[0])
        return entry
    key = ("converted", obj.name)
    if key not in cache:
        try:
            me = obj.to_mesh()
        except RuntimeError:
            me = None
        cache[key] = None
        if me is not None:
            entry = _read(me, obj.name, warn)
            if entry is not None:
                entry[1].update(read_corner_data(me, keys, warn, obj.name, base_mesh(obj)))
            cache[key] = entry
            obj.to_mesh_clear()
        text = hair_warning(obj, None if cache[key] is None else cache[key][0])
        if text:
            warn(text)
    return cache[key]


def _read(me, name, warn):
    try:
        return read_mesh(me), {}
    except KeyError as exc:      # e.g. loose geometry without a "position" attribute
        warn(f"Object '{name}' has no readable geometry ({exc}); it is skipped")
        return None


def object_random(key):
    """Object Info's Random: a stable number in [0, 1) per placed object."""
    digest = hashlib.blake2b(repr(key).encode(), digest_size=4).digest()
    return int.from_bytes(digest, "little") / 2.0 ** 32


def ray_visibility(obj, view_layer=None):
    """Object > Visibility > Ray Visibility: (camera, shadow, diffuse, glossy,
    transmission). An object of an Indirect Only collection in the view layer
    is hidden from camera rays: it shows through shadows and light only, as
    Cycles renders it (a holdout takes precedence)."""
    out = [bool(getattr(obj, "visible_" + kind, True))
           for kind in ("camera", "shadow", "diffuse", "glossy", "transmission")]
    if out[0] and view_layer is not None and not is_holdout(obj, view_layer):
        original = obj.original if obj.original is not None else obj
        try:
            out[0] = not original.indirect_only_get(view_layer=view_layer)
        except (AttributeError, TypeError, RuntimeError):
            pass
    return tuple(out)


def is_holdout(obj, view_layer=None):
    """Object > Visibility > Holdout, or its collection's Holdout in the view
    layer: the camera sees a hole where it is (core/materials.camera_alpha);
    other rays see the object as it is, as in Cycles."""
    if getattr(obj, "is_holdout", False):
        return True
    original = obj.original if obj.original is not None else obj
    try:
        return bool(original.holdout_get(view_layer=view_layer)) if view_layer is not None else False
    except (AttributeError, TypeError, RuntimeError):
        return False


def visibility_warnings(obj, view_layer=None):
    """Warnings for what Object > Visibility asks of an object that is not
    rendered here (it renders as an ordinary object): shadow catcher."""
    out = []
    if getattr(obj, "is_shadow_catcher", False):
        out.append(f"Object '{obj.name}': shadow catcher is not supported; it renders as an ordinary object")
    return out


def film_transparent(scene):
    """Render Properties > Film > Transparent."""
    return bool(getattr(scene.render, "film_transparent", False))


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
    materials.images.frame = bscene.frame_current
    cache = {}
    verts, tris, normals, uvs, mids, oids, light_rows, corners = [], [], [], [], [], [], [], []
    offset = 0
    object_index = {}           # instance key -> object id
    grids, grid_files = [], GridFiles()
    object_matrices, object_colors, visibility, pass_index, attributes, holdouts = [], [], [], [], [], []
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type == "LIGHT":
            if is_supported(obj.data):
                light_rows.append(light_row(obj, inst.matrix_world, warn))
            else:
                warn(f"Light '{obj.name}' of type {obj.data.type} is not supported")
            continue
        if obj.type == "VOLUME":
            grids += volume_grids(obj, inst.matrix_world, grid_files, warn)
            continue
        if obj.type not in GEOMETRY_TYPES:
            if unrendered(obj):
                warn(unrendered(obj))
            continue
        slot_ids = np.array([materials.id_of(s.material) for s in obj.material_slots] or [0], np.int32)
        needs, attribute_needs = split_needs(materials.needs(slot_ids))
        entry = _object_mesh(obj, cache, needs, warn)
        if entry is None or len(entry[0].triangles) == 0:
            continue
        mesh, corner = entry
        flip = mirrors(inst.matrix_world)
        pos, nrm = place(mesh, inst.matrix_world, flip)
        placed_tris, placed_uvs = placed_triangles(mesh, inst.matrix_world, flip)
        slots = np.clip(mesh.slots, 0, len(slot_ids) - 1)
        verts.append(pos)
        tris.append(placed_tris + offset)
        normals.append(nrm)
        uvs.append(placed_uvs)
        corners.append(placed_corners(corner, inst.matrix_world, flip))
        mids.append(slot_ids[slots])
        key = instance_key(inst, obj)
        if key not in object_index:
            object_index[key] = len(object_index)
            object_matrices.append(np.array(inst.matrix_world, np.float32))
            object_colors.append(tuple(obj.color))
            visibility.append(ray_visibility(obj, depsgraph.view_layer))
            pass_index.append(obj.pass_index)
            attributes.append(object_attributes(inst, obj, attribute_needs))
            holdouts.append(is_holdout(obj, depsgraph.view_layer))
            for text in visibility_warnings(obj, depsgraph.view_layer):
                warn(text)
        oids.append(np.full(len(mesh.triangles), object_index[key], np.int32))
        offset += len(pos)

    def cat(parts, shape, dtype):
        return np.concatenate(parts).astype(dtype) if parts else np.zeros(shape, dtype)

    camera = export_camera(depsgraph, warn)
    vertices, triangles = cat(verts, (0, 3), np.float32), cat(tris, (0, 3), np.int32)
    per_tri = [cat(mids, (0,), np.int32), cat(normals, (0, 3, 3), np.float32),
               cat(uvs, (0, 3, 2), np.float32), cat(oids, (0,), np.int32)]
    world, world_volume = export_world(evaluated_world(depsgraph), materials.images, warn)[1]()
    scene = make_scene(
        vertices, triangles,
        material_ids=per_tri[0],
        materials=materials.table(),
        lights=Lights.from_list(light_rows),
        camera=camera,
        normals=per_tri[1],
        uvs=per_tri[2],
        object_ids=per_tri[3],
        width=width, height=height,
        filter_width=float(bscene.render.filter_size),
        corner_data=corner_data(corners, tris),
    )
    scene.environment = world
    scene.world_volume = world_volume
    scene.volume_grids = grids
    scene.film_transparent = film_transparent(bscene)
    scene.shaders = materials.graphs
    scene.images = materials.images.images
    scene.object_info = {"Color": np.asarray([c[:3] for c in object_colors] or np.zeros((0, 3)), np.float32),
                         "Alpha": np.asarray([c[3] for c in object_colors], np.float32),
                         "Random": np.asarray([object_random(k) for k in object_index], np.float32),
                         "Object Index": np.asarray(pass_index, np.float32), **attribute_tables(attributes)}
    shading(scene)      # compiles the graphs now: their warnings join the export's
    if visibility and not all(all(v) for v in visibility):
        scene.ray_visibility = np.asarray(visibility, bool)
    if any(holdouts):
        scene.object_holdout = np.asarray(holdouts, bool)
    scene.warnings = warn.items + scene.warnings
    scene.object_keys = list(object_index)
    scene.object_names = [key[0] for key in object_index]
    scene.object_matrices = (np.stack(object_matrices) if object_matrices
                             else np.zeros((0, 4, 4), np.float32))
    return scene, camera is not None


def placed_corners(corner, matrix, flip=None):
    """Corner data of one placed instance, corners in placed_triangles'
    order: tangents (read in object space) turned into world space by the
    instance's matrix, their bitangent sign flipped where it mirrors (the
    bitangent is the sign times cross(normal, tangent), and a mirror turns
    that cross product around); the rest unchanged. flip: mirrors(matrix),
    if the caller has it."""
    flip = mirrors(matrix) if flip is None else flip
    keys = [k for k in corner if k.startswith("tangent:")]
    if not keys and not flip:
        return corner
    m = np.asarray(matrix, np.float32)[:3, :3]
    out = {k: (v[:, SWAP] if flip else v) for k, v in corner.items()}
    for k in keys:
        t = out[k].copy()
        v = t[..., :3] @ m.T
        length = np.linalg.norm(v, axis=-1, keepdims=True)
        t[..., :3] = v / np.where(length > 0, length, 1)
        if flip:
            t[..., 3] = -t[..., 3]
        out[k] = t
    return out


def corner_data(parts, tris):
    """Per-triangle corner data of all objects by key, zeros where an object
    had none (make_scene drops it with the triangles it drops)."""
    keys = set().union(*parts) if parts else set()
    out = {}
    for key in sorted(keys):
        width = {"uv": 2, "color": 4, "tangent": 4}.get(key.partition(":")[0], 3)
        arrays = [p.get(key) if p.get(key) is not None else np.zeros((len(t), 3, width), np.float32)
                  for p, t in zip(parts, tris)]
        out[key] = np.ascontiguousarray(np.concatenate(arrays), np.float32)
    return out
