"""The viewport session's render side: queued changes applied to the core
scene between two frames (viewport/session.py)."""

import numpy as np

from ...core.integrators import transparency
from ...core.geometry.dynamic_accel import DynamicAccel
from ...core.integrators.base import RAY_EPS_RELATIVE, RenderContext
from ...core.lights.light_set import LightSet
from ...core.workers.parallel import Workers
from ...core.scene import Scene


class SceneApplier:
    """Mixin of ViewportSession: _apply() and the core scene it builds."""

    def _apply(self, p):
        """Bring the core scene up to date with the pending changes."""
        if p.empty():
            return
        geometry = False
        lights_changed = p.materials is not None or p.lights is not None or p.world is not None
        if p.instances is not None:
            before = self._combined.arrays
            self._apply_objects(p)
            geometry = True
            # The lights hold the emitting triangles: a frame that only moved
            # or deformed other objects in place keeps them (LightSet.follow).
            lights_changed = lights_changed or p.full or p.layout or bool(p.reslotted) \
                or self._combined.arrays is not before or self._moved_emitters(p.moved | p.remeshed)
        if p.materials is not None:
            self._scene_materials, self._scene_shaders, self._scene_images = p.materials
        if p.lights is not None:
            self._scene_lights = p.lights
        if p.world is not None:
            self._environment, self._world_volume = p.world
        if p.volumes is not None:
            self._volume_grids = p.volumes
        if p.filter_width is not None:
            self._filter_width = p.filter_width
        if p.film_transparent is not None:
            self._film_transparent = p.film_transparent
        if p.camera is not None:
            self._camera = p.camera
        if p.size is not None:
            self._size = p.size
        if p.settings:
            self._settings_changed()
        # Change counters instead of hashing the whole scene every frame
        # (Scene.versions): geometry, and the lights, materials and world
        # (Scene.lighting_key combines the two, Scene.shading_key is the second).
        self._geometry_version += geometry
        self._lighting_version += any(x is not None for x in (p.materials, p.lights, p.world, p.volumes))
        self._applied_generation = p.generation
        self._build_context(lights_changed)
        self._scene_changed()

    def _moved_emitters(self, keys):
        """Whether any of these object keys has triangles the lights hold."""
        if self._ctx is None or not keys:
            return self._ctx is None
        ids = self._ctx.lights.emitting_objects
        if len(ids) == 0:
            return False
        index = {key: i for i, key in enumerate(self._combined.arrays["keys"])}
        return bool(np.isin([index.get(k, -1) for k in keys], ids).any())

    def _apply_objects(self, p):
        inst = p.instances
        changed = p.moved | p.remeshed
        a = self._combined.update(inst, changed, p.reslotted, p.layout)
        self.work.triangle_updates += 1
        if p.full and self._accel is not None:
            self._accel.close()
            self._accel = None
        if self._accel is None:
            self._accel = DynamicAccel(a["vertices"], a["triangles"], a["object_ids"], a["keys"],
                                       self.threads, dynamic=p.animated & inst.keys())
            self._count_builds(0, 0)
        else:
            counts = self._accel.static_builds, self._accel.dynamic_builds
            self._accel.update(a["vertices"], a["triangles"], a["object_ids"], a["keys"],
                               changed=changed & inst.keys())
            self._count_builds(*counts)
        self._accel.interrupt = self._should_abandon
        self._frames_since_edit = 0

    def _count_builds(self, static_before, dynamic_before):
        self.work.accel_static_builds += self._accel.static_builds - static_before
        self.work.accel_dynamic_builds += self._accel.dynamic_builds - dynamic_before

    def _build_context(self, lights_changed):
        a = self._combined.arrays
        if a is None or self._camera is None or self._size is None:
            self._ctx = None
            return
        w, h = self._render_resolution()
        mats = self._scene_materials
        mids = a["material_ids"]
        if len(mids) and mids.max() >= len(mats):
            mids = np.where(mids < len(mats), mids, 0).astype(np.int32)
        scene = Scene(vertices=a["vertices"], triangles=a["triangles"], normals=a["normals"],
                      uvs=a["uvs"], material_ids=mids, object_ids=a["object_ids"], materials=mats,
                      lights=self._scene_lights, camera=self._camera, environment=self._environment,
                      world_volume=self._world_volume, volume_grids=list(self._volume_grids),
                      shaders=self._scene_shaders, images=self._scene_images,
                      corner_data=a.get("corner_data") or {},
                      width=w, height=h, filter_width=self._filter_width,
                      object_keys=list(a["keys"]), object_matrices=a["matrices"].copy(),
                      face_normals=a["face_normals"],
                      versions=(self._geometry_version, self._lighting_version),
                      known_bounds=self._combined.bounds())
        scene.object_names = [key[0] for key in scene.object_keys]
        scene.object_info = {"Color": a["colors"][:, :3], "Alpha": a["colors"][:, 3],
                             "Random": a["random"], "Object Index": a["pass_index"], **a["attributes"]}
        if not a["visibility"].all():
            scene.ray_visibility = a["visibility"]
        if a["holdout"].any():
            scene.object_holdout = a["holdout"]
        scene.film_transparent = self._film_transparent
        previous = self._scene
        if previous is not None and previous.shaders is scene.shaders \
                and previous.materials is scene.materials and hasattr(previous, "_shading"):
            scene._shading = previous._shading      # compiled graphs depend on materials only
        if self._ctx is None or lights_changed:
            lights = LightSet(scene)
            eps = RAY_EPS_RELATIVE * scene.extent()
        else:
            lights = self._ctx.lights.follow(scene)
            eps = RAY_EPS_RELATIVE * scene.extent()
        self._scene = scene
        if self._workers is None:
            self._workers = Workers(self.threads, processes=self.twin_process, twin_wait=self.twin_wait,
                                    twin_max_pixels=self.twin_max_pixels)
        self._ctx = RenderContext(scene, transparency.wrap(self._accel, scene), lights, eps, self._workers)

