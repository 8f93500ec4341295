"""The scene of final renders, kept from one frame of an animation to the next.

An animation render used to export the whole evaluated scene and build a new
Embree scene for every frame, even when only the camera moved. ``FrameScene``
(a SceneSync, as the viewport's session) keeps the exported arrays and the
two-part Embree scene between frames and applies only what changed:

- With Persistent Data on, Blender keeps its depsgraph between frames and
  flags what each frame changed (``depsgraph.updates``), as Cycles reads it.
- Without it, Blender evaluates every frame afresh and flags everything, so
  changes are found by comparison: matrices, material slots, light rows, the
  camera and the world graph as read, and for each mesh its counts and vertex
  positions (one foreach_get per mesh; triangles, normals and UVs are read
  again only for a mesh whose positions or counts changed). Materials with
  animation data are read again every frame. The kept scene is freed when
  the render job ends (``release``), as Blender frees its own.

A moved object keeps its triangles and goes to the small dynamic Embree scene
(core/geometry/dynamic_accel.py); a deformed mesh is read again alone; a material,
light or world change never touches geometry.

Threads: Render > Performance > Threads (``blender -t N``) when set to Fixed,
otherwise both cores (core/workers/parallel.py); a change re-exports the scene.
"""

import time

import bpy

from ...core.materials.shading import shading
from ..export import Warnings
from ..export.camera import export_camera
from .scene_sync import SceneSync
from .objects import same_camera


class FrameScene(SceneSync):
    """SceneSync for final renders: ``update(depsgraph, width, height)`` once
    per frame, then ``context`` and ``scene`` are that frame's."""

    def __init__(self, threads=None):
        super().__init__(threads)
        self._view_from_scene = True
        self._depsgraph = None          # pointer of the depsgraph of the last update
        self._persistent = None
        self._reported = 0              # warnings already handed out by new_warnings
        self.timings = (0.0, 0.0)       # seconds of the last update: reading, applying

    def update(self, depsgraph, width, height, camera=None, camera_only=False):
        """Bring the core scene to this frame's depsgraph. Returns True if the
        scene has a camera. camera: the core.Camera to render with (one view
        of a stereo pair) instead of the scene camera's; camera_only: the
        depsgraph is the one of the last update (another view of the same
        frame), so only the camera changes."""
        t0 = time.perf_counter()
        scene = depsgraph.scene
        persistent = bool(scene.render.use_persistent_data)
        threads = scene.render.threads if scene.render.threads_mode == "FIXED" else None
        if threads != self.threads:
            self.release()
            self.threads = threads
        pointer = depsgraph.as_pointer()
        fresh_depsgraph = persistent and pointer != self._depsgraph
        if camera_only and self._instances is not None and pointer == self._depsgraph:
            pass        # the geometry, materials and lights stay as the last update left them
        elif self._instances is None or persistent != self._persistent or fresh_depsgraph:
            # Everything (a new depsgraph with Persistent Data has new data
            # throughout, and its meshes are keyed by data). Warnings start
            # over too: what a previous render warned about may be fixed.
            self._stable_keys = not persistent
            self.warnings, self._reported = Warnings(), 0
            self.sync(depsgraph)
        elif persistent:
            self.sync(depsgraph, depsgraph.updates)     # what Blender flagged
            self._refresh_materials(depsgraph, self._animated_materials(sequences_only=True))
        else:
            self._sync_compare(depsgraph)
        self._persistent, self._depsgraph = persistent, pointer
        if (width, height) != self._display:
            self._display = (width, height)
            self._queue(size=self._display)
        if camera is None:
            camera = export_camera(depsgraph, self.warnings, region=True)
        if camera is not None and not same_camera(camera, self._view):
            self._view = camera
            self.work.camera_updates += 1
            self._queue(camera=camera)
        t1 = time.perf_counter()
        self.apply_pending()
        if self._scene is not None:
            shading(self._scene)        # compiles the graphs now: their warnings join the export's
            for text in self._scene.warnings:
                self.warnings(text)
        self.timings = (t1 - t0, time.perf_counter() - t1)
        return camera is not None

    def _sync_compare(self, depsgraph):
        scene = depsgraph.scene
        self._materials.images.frame = scene.frame_current
        self._refresh_materials(depsgraph, self._animated_materials())
        self._walk(depsgraph, None, None, compare=True)
        env = self._read_world(depsgraph)
        if env is not None:
            self.work.world_updates += 1
            self._queue(world=env)
        self._read_film(scene)

    def _refresh_materials(self, depsgraph, materials):
        changed = [m for m in materials if self._materials.refresh(m, depsgraph)]
        if changed:
            self.work.material_updates += len(changed)
            self._queue(materials=self._materials.snapshot())

    def _animated_materials(self, sequences_only=False):
        """Original materials in use whose values may change with the frame:
        with animation data (keyframes, drivers) or an Image Texture on an
        image sequence, whose file follows the frame (only those with
        sequences_only: Persistent Data's updates flag the others)."""
        used = self._materials.index
        out = []
        for mat in bpy.data.materials:
            tree = mat.node_tree
            if mat.as_pointer() not in used or tree is None:
                continue
            animated = mat.animation_data is not None or tree.animation_data is not None
            if (animated and not sequences_only) or (not animated and any(
                    getattr(getattr(n, "image", None), "source", "") == "SEQUENCE" for n in tree.nodes)):
                out.append(mat)
        return out

    def new_warnings(self, repeat=False):
        """Warnings raised since the last call; with repeat, all of them (a
        new render reports again what the previous one did)."""
        items = self.warnings.items[0 if repeat else self._reported:]
        self._reported = len(self.warnings.items)
        return items

    def release(self):
        """Free the arrays and Embree scenes."""
        self._free_scene()
        self._instances = None
        self._meshes, self._mesh_counts = {}, {}
