"""The viewport session's Blender side: what changed in the depsgraph, read
into arrays and queued for the render side (ViewportSession in viewport.py).

A transform-only change reads the new matrices (no mesh data), a geometry
change re-reads that object's mesh only, material, light and world edits
replace their table, graphs or environment and never touch triangles or the
Embree scenes.
"""

import bpy
import numpy as np

from ..core.scene import Lights
from .export import instance_key
from .export.camera import export_camera, render_size
from .export.lights import is_supported, light_row, row_signature
from .export.materials import MaterialTable
from .export.mesh import GEOMETRY_TYPES
from .export.world import export_world
from .viewport_state import as_update
from .viewport_sync import _Instance, _mesh_key, _read_object_mesh, _same_camera


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
        if materials:
            changed = [m for m in materials if self._materials.refresh(m, depsgraph)]
            if changed:
                self.work.material_updates += len(changed)
                self._queue(materials=self._materials.snapshot())
        if walk:
            self._walk(depsgraph, reread_objects, reread_data)
        if world or scene_changed:
            env = self._read_world(scene)
            if env is not None:
                self.work.world_updates += 1
                self._queue(world=env)
        if (camera_moved or scene_changed) and self._view_from_scene:
            camera = export_camera(depsgraph, self.warnings)
            if camera is not None and not _same_camera(camera, self._view):
                self._view = camera
                self.work.camera_updates += 1
                self._queue(camera=camera)
        if scene_changed:
            fw = float(scene.render.filter_size)
            if fw != self._filter_width_read:
                self._filter_width_read = fw
                self._queue(filter_width=fw)

    def _full_export(self, depsgraph):
        scene = depsgraph.scene
        self.work.full_exports += 1
        self._meshes = {}
        self._instances = {}
        self._materials = MaterialTable(self.warnings)
        self._light_rows = None
        self._walk(depsgraph, None, None)
        world = self._read_world(scene, force=True)
        self._filter_width_read = float(scene.render.filter_size)
        changes = dict(materials=self._materials.snapshot(), world=world,
                       filter_width=self._filter_width_read, full=True)
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

    def _walk(self, depsgraph, reread_objects, reread_data):
        """Pass over the depsgraph's instances: matrices, material slots, lights;
        meshes are read only when new or flagged (reread_* None: all)."""
        self.work.object_walks += 1
        instances, light_rows, fresh = {}, [], set()
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
            if obj.type not in GEOMETRY_TYPES:
                continue
            mkey = _mesh_key(obj)
            used_meshes.add(mkey)
            orig = obj.original
            flagged = reread_objects is None or orig.name in reread_objects or (
                orig.data is not None and orig.data.as_pointer() in (reread_data or ()))
            slot_ids = np.array([self._materials.id_of(s.material) for s in obj.material_slots] or [0],
                                np.int32)
            needs = self._materials.needs(slot_ids)
            cached = self._meshes.get(mkey)
            missing = cached is not None and not needs <= set(cached.corners)
            if mkey not in fresh and (flagged or mkey not in self._meshes or missing):
                self._meshes[mkey] = _read_object_mesh(obj, needs, self.warnings)
                self.work.mesh_exports += 1
                fresh.add(mkey)
            mesh = self._meshes[mkey]
            if mesh is None or len(mesh.triangles) == 0:
                continue
            key = instance_key(inst, obj)
            while key in instances:     # the same key twice: keep both, numbered
                key = key + (len(instances),)
            instances[key] = _Instance(mesh, np.array(inst.matrix_world, np.float64), slot_ids)
        for mkey in set(self._meshes) - used_meshes:
            del self._meshes[mkey]

        old = self._instances or {}
        common = instances.keys() & old.keys()
        remeshed = {k for k in common if instances[k].mesh is not old[k].mesh}
        remeshed |= instances.keys() - old.keys()
        moved = {k for k in common - remeshed if not np.array_equal(instances[k].matrix, old[k].matrix)}
        reslotted = {k for k in common - remeshed
                     if not np.array_equal(instances[k].slot_ids, old[k].slot_ids)}
        layout = set(instances) != set(old) or list(instances) != list(old)
        self._instances = instances
        changes = {}
        if moved or remeshed or reslotted or layout or not old:
            self.work.transform_updates += len(moved)
            changes.update(instances=instances, moved=moved, remeshed=remeshed,
                           reslotted=reslotted, layout=layout)
        if len(self._materials.rows) != materials_before:
            changes["materials"] = self._materials.snapshot()
        signature = [row_signature(r) for r in light_rows]
        if signature != self._light_rows:
            if self._light_rows is not None:
                self.work.light_updates += 1
            self._light_rows = signature
            changes["lights"] = Lights.from_list(light_rows)
        if changes:
            self._queue(**changes)

    def _read_world(self, scene, force=False):
        """Queue the world's environment if its graph changed (or force)."""
        graph_sig, build = export_world(scene.world, self._materials.images, self.warnings)
        if force or graph_sig != self._world:
            self._world = graph_sig
            return (build(),)
        return None
