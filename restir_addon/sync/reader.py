"""The viewport session's Blender side: what changed in the depsgraph, read
into arrays and queued for the render side (viewport/session.py).

A transform-only change reads the new matrices (no mesh data), a geometry
change re-reads that object's mesh only, material, light and world edits
replace their table, graphs or environment and never touch triangles or the
Embree scenes.
"""

import bpy
import numpy as np

from ...core.util.errors import context
from ...core.scene import Lights
from ..export import film_transparent, instance_key, is_holdout, ray_visibility, visibility_warnings
from ..export.camera import export_camera, render_size
from ..export.lights import is_supported, light_row, row_signature
from ..export.materials import MaterialTable
from ..export.mesh import GEOMETRY_TYPES, unrendered
from ..export.volume_objects import GridFiles, volume_grids
from ..export.object_attributes import object_attributes, split_needs
from ..export.world import evaluated_world, export_world
from ..memory import check_geometry
from .state import as_update
from .objects import Instance, mesh_key, read_object_mesh, same_camera


class SceneReader:
    """Mixin of ViewportSession: sync() and the depsgraph walk (UI thread)."""

    def sync(self, depsgraph, updates=None):
        """Read the depsgraph: everything on the first call (or updates None),
        then only what ``updates`` (depsgraph.updates, or tuples
        (id, transform, geometry, shading)) says changed."""
        scene = depsgraph.scene
        if self._instances is None or updates is None:
            self._full_export(depsgraph)
            return
        self._materials.images.frame = scene.frame_current
        updates = [as_update(u) for u in updates]
        walk = False
        reread_objects, reread_data = set(), set()
        materials, world, scene_changed, camera_moved = [], False, False, False
        for u in updates:
            id_ = u.id
            if isinstance(id_, bpy.types.Object):
                if u.transform or u.geometry:
                    walk = True
                if u.geometry and id_.type != "LIGHT":
                    reread_objects.add(id_.name)
                if id_.type == "CAMERA":
                    camera_moved = True
            elif isinstance(id_, bpy.types.Material):
                materials.append(id_)
            elif isinstance(id_, bpy.types.World):
                world = True
            elif isinstance(id_, bpy.types.Scene):
                scene_changed = True
                walk = walk or u.transform or u.geometry
            elif isinstance(id_, bpy.types.Collection):
                walk = walk or u.transform or u.geometry
            elif isinstance(id_, (bpy.types.Mesh, bpy.types.Curve, bpy.types.Curves,
                                  bpy.types.MetaBall)) and u.geometry:
                walk = True
                reread_data.add(id_.as_pointer())
            elif isinstance(id_, bpy.types.Volume):
                walk = True
        # Volume objects' media are read on the walk (export/volume_objects.py),
        # from their materials too.
        walk = walk or bool(materials and getattr(self, "_grid_signature", None))
        if materials:
            changed = [m for m in materials if self._materials.refresh(m, depsgraph)]
            if changed:
                self.work.material_updates += len(changed)
                self._queue(materials=self._materials.snapshot())
        if walk:
            self._walk(depsgraph, reread_objects, reread_data)
        if world or scene_changed:
            env = self._read_world(depsgraph)
            if env is not None:
                self.work.world_updates += 1
                self._queue(world=env)
        if (camera_moved or scene_changed) and self._view_from_scene:
            camera = export_camera(depsgraph, self.warnings)
            if camera is not None and not same_camera(camera, self._view):
                self._view = camera
                self.work.camera_updates += 1
                self._queue(camera=camera)
        if scene_changed:
            self._read_film(scene)

    def _full_export(self, depsgraph):
        scene = depsgraph.scene
        self.work.full_exports += 1
        self._meshes = {}
        self._instances = {}
        self._materials = MaterialTable(self.warnings)
        self._materials.images.frame = scene.frame_current
        self._light_rows = None
        self._grid_signature = None
        self._walk(depsgraph, None, None, compare=self._stable_keys)
        world = self._read_world(depsgraph, force=True)
        self._filter_width_read = float(scene.render.filter_size)
        self._film_read = film_transparent(scene)
        changes = dict(materials=self._materials.snapshot(), world=world,
                       filter_width=self._filter_width_read, film_transparent=self._film_read,
                       full=True)
        if self._view is None:
            camera = export_camera(depsgraph, self.warnings)
            if camera is not None:
                self._view = camera
                self._view_from_scene = True
                changes["camera"] = camera
        if self._display is None:
            self._display = render_size(scene)
            changes["size"] = self._display
        self._queue(**changes)

    def _walk(self, depsgraph, reread_objects, reread_data, compare=False):
        """Pass over the depsgraph's instances: matrices, material slots, lights;
        meshes are read only when new or flagged (reread_* None: all).

        compare: the depsgraph has no update flags and new evaluated data
        (a final render without persistent data re-evaluates every frame):
        meshes are keyed by their object instead of their data, and one is
        read again only where its counts or vertex positions differ from what
        was read (one foreach_get and a comparison per mesh, no triangles)."""
        self.work.object_walks += 1
        instances, light_rows, fresh = {}, [], set()
        grids = []
        if getattr(self, "_grid_files", None) is None:
            self._grid_files = GridFiles()
        stable_owner = {}               # compare: stable mesh key -> evaluated data pointer
        animated = set()
        used_meshes = set()
        materials_before = len(self._materials.rows)
        for inst in depsgraph.object_instances:
            obj = inst.object
            if obj.type == "LIGHT":
                if is_supported(obj.data):
                    light_rows.append(light_row(obj, inst.matrix_world, self.warnings))
                else:
                    self.warnings(f"Light '{obj.name}' of type {obj.data.type} is not supported")
                continue
            if obj.type == "VOLUME":
                with context("object", f"'{obj.original.name}'"):
                    grids += volume_grids(obj, inst.matrix_world, self._grid_files, self.warnings)
                continue
            if obj.type not in GEOMETRY_TYPES:
                if unrendered(obj):
                    self.warnings(unrendered(obj))
                continue
            orig = obj.original
            if compare:
                mkey = _stable_mesh_key(obj, stable_owner)
                flagged = mkey not in fresh and self._mesh_differs(mkey, obj)
            else:
                mkey = mesh_key(obj)
                flagged = reread_objects is None or orig.name in reread_objects or (
                    orig.data is not None and orig.data.as_pointer() in (reread_data or ()))
            used_meshes.add(mkey)
            slot_ids = np.array([self._materials.id_of(s.material) for s in obj.material_slots] or [0],
                                np.int32)
            needs, attribute_needs = split_needs(self._materials.needs(slot_ids))
            cached = self._meshes.get(mkey)
            missing = cached is not None and not needs <= set(cached.corners)
            if mkey not in fresh and (flagged or mkey not in self._meshes or missing):
                with context("object", f"'{orig.name}'"):
                    self._meshes[mkey] = read_object_mesh(obj, needs, self.warnings)
                self._mesh_counts[mkey] = _counts(obj)
                self.work.mesh_exports += 1
                fresh.add(mkey)
            elif compare:
                fresh.add(mkey)         # compared once per walk
            mesh = self._meshes[mkey]
            if mesh is None or len(mesh.triangles) == 0:
                continue
            key = instance_key(inst, obj)
            while key in instances:     # the same key twice: keep both, numbered
                key = key + (len(instances),)
            instances[key] = Instance(mesh, np.array(inst.matrix_world, np.float64), slot_ids,
                                       tuple(obj.color), ray_visibility(obj, depsgraph.view_layer),
                                       int(obj.pass_index),
                                       object_attributes(inst, obj, attribute_needs),
                                       is_holdout(obj, depsgraph.view_layer))
            for text in visibility_warnings(obj, depsgraph.view_layer):
                self.warnings(text)
            if may_change(inst.parent if inst.is_instance else obj):
                animated.add(key)
        for mkey in set(self._meshes) - used_meshes:
            del self._meshes[mkey]
            self._mesh_counts.pop(mkey, None)
        check_geometry(sum(len(it.mesh.triangles) for it in instances.values()),
                       sum(len(it.mesh.positions) for it in instances.values()), len(instances),
                       self._available_memory)

        old = self._instances or {}
        common = instances.keys() & old.keys()
        remeshed = {k for k in common if instances[k].mesh is not old[k].mesh}
        remeshed |= instances.keys() - old.keys()
        moved = {k for k in common - remeshed if not np.array_equal(instances[k].matrix, old[k].matrix)}
        # Material slots, Object Info colour or index, or ray visibility changed.
        reslotted = {k for k in common - remeshed
                     if not np.array_equal(instances[k].slot_ids, old[k].slot_ids)
                     or instances[k].color != old[k].color
                     or instances[k].pass_index != old[k].pass_index
                     or instances[k].attributes != old[k].attributes
                     or instances[k].holdout != old[k].holdout
                     or instances[k].visibility != old[k].visibility}
        layout = set(instances) != set(old) or list(instances) != list(old)
        self._instances = instances
        changes = {}
        if moved or remeshed or reslotted or layout or not old:
            self.work.transform_updates += len(moved)
            changes.update(instances=instances, moved=moved, remeshed=remeshed,
                           reslotted=reslotted, layout=layout, animated=animated)
        if len(self._materials.rows) != materials_before:
            changes["materials"] = self._materials.snapshot()
        signature = [row_signature(r) for r in light_rows]
        if signature != self._light_rows:
            if self._light_rows is not None:
                self.work.light_updates += 1
            self._light_rows = signature
            changes["lights"] = Lights.from_list(light_rows)
        # Grids: the arrays are GridFiles' own while their files are unchanged.
        signature = [(id(g.density), g.to_index.tobytes(), g.scaled.tobytes(), g.constant.tobytes(),
                      repr(g.blackbody), None if g.color is None else (id(g.color[0]), repr(g.color[1:])))
                     for g in grids]
        if signature != getattr(self, "_grid_signature", None):
            self._grid_signature = signature
            changes["volumes"] = grids
        if changes:
            self._queue(**changes)

    def _mesh_differs(self, mkey, obj):
        """compare mode: whether an object's evaluated mesh differs from the
        one read under ``mkey`` (counts, then vertex positions)."""
        if mkey not in self._meshes or obj.type != "MESH":
            return True
        mesh = self._meshes[mkey]
        if self._mesh_counts.get(mkey) != _counts(obj):
            return True
        if mesh is None:
            return False
        me = obj.data
        attr = me.attributes.get("position")
        if attr is None:
            return True
        pos = np.empty(len(me.vertices) * 3, np.float32)
        attr.data.foreach_get("vector", pos)
        return not np.array_equal(pos.reshape(-1, 3), mesh.positions)

    def _read_film(self, scene):
        """Queue the pixel filter width and Film > Transparent if they changed."""
        fw = float(scene.render.filter_size)
        if fw != self._filter_width_read:
            self._filter_width_read = fw
            self._queue(filter_width=fw)
        film = film_transparent(scene)
        if film != self._film_read:
            self._film_read = film
            self._queue(film_transparent=film)

    def _read_world(self, depsgraph, force=False):
        """(environment, volume) of the world if its graph changed (or force), else None."""
        graph_sig, build = export_world(evaluated_world(depsgraph), self._materials.images, self.warnings)
        if force or graph_sig != self._world:
            self._world = graph_sig
            return build()
        return None


def _counts(obj):
    """Vertex, corner and loop-triangle counts of an evaluated mesh object."""
    me = obj.data if obj.type == "MESH" else None
    if me is None:
        return None
    return len(me.vertices), len(me.loops), len(me.loop_triangles)


def _stable_mesh_key(obj, owner):
    """A mesh key that survives re-evaluation: the original mesh for an
    object without modifiers or shape keys (its instances share it), else the
    object and its evaluated mesh's name. Two different evaluated meshes under
    one key (an instancer's generated geometry) fall back to data pointers."""
    orig = obj.original
    data = orig.data if orig is not None else None
    if obj.type == "MESH" and data is not None and len(orig.modifiers) == 0 \
            and getattr(data, "shape_keys", None) is None:
        key = ("data", data.as_pointer())
    else:
        key = ("object", orig.name if orig is not None else obj.name,
               obj.data.name if obj.data is not None else "")
    pointer = mesh_key(obj)
    if owner.setdefault(key, pointer) != pointer:
        return ("pointer", pointer)
    return key


def may_change(obj):
    """Whether an object may move or deform with the frame: animation or
    drivers on it, its shape keys or a parent, or constraints."""
    o = obj.original if obj is not None else None
    for _ in range(64):
        if o is None:
            return False
        ad = o.animation_data
        if ad is not None and (ad.action is not None or len(ad.drivers) or len(ad.nla_tracks)):
            return True
        if len(o.constraints):
            return True
        keys = getattr(o.data, "shape_keys", None)
        if keys is not None and keys.animation_data is not None:
            return True
        o = o.parent
    return False
