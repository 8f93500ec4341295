"""A Blender scene kept as a core scene from one render to the next.

``SceneSync`` reads the depsgraph once, then only what changed (SceneReader in
reader.py), queues it, and applies it between two frames to the
combined world-space arrays and the two-part Embree scene (SceneApplier in
applier.py): a moved object gets a new transform and goes to the small
dynamic Embree scene, a deformed mesh is read again alone, a material, light
or world edit never touches geometry.

The viewport session (viewport/session.py) and animation renders
(frame_scene.py) are both built on it. The queue is a hand-over between threads for the
viewport (sync on Blender's thread, apply on the render thread); a final
render reads and applies on one thread.
"""

import threading

from ...core.scene import Lights, Materials
from ..export import Warnings
from .arrays import CombinedArrays
from .reader import SceneReader
from .applier import SceneApplier
from .state import Work, Pending


class SceneSync(SceneReader, SceneApplier):
    """Blender-side reading state, the queue of changes, and the core scene
    (``scene``, ``accel``, ``context``) they were applied to."""

    # Render loops may fork a twin process for the second core (core/workers/forked.py);
    # twin_wait: (seconds, factor) the leader waits for its half of a pass
    # (None: forked's defaults); twin_max_pixels: larger images on threads.
    twin_process = True
    twin_wait = None
    twin_max_pixels = None

    def __init__(self, threads=None):
        self.work = Work()
        self.warnings = Warnings()
        self.threads = threads
        # --- Blender side (the thread calling sync) ---
        self._instances = None          # key -> Instance of the last sync
        self._meshes = {}               # mesh key -> MeshData
        self._mesh_counts = {}          # mesh key -> (vertices, loops, loop triangles) as read
        self._materials = None
        self._light_rows = None
        self._world = None
        self._filter_width_read = None
        self._film_read = None
        self._view = None
        self._view_from_scene = False   # no set_view yet: the view follows the scene camera
        self._display = None
        self._generation = 0
        self._available_memory = None   # bytes (None: read from the system when checked)
        self._stable_keys = False       # meshes keyed by object, compared by content (see _walk)
        # --- handed over under the lock ---
        self._cond = threading.Condition()
        self._pending = Pending()
        self._abandon = False           # the frame in progress is useless
        self._applying = False          # changes taken from the queue, not yet applied
        # --- render side ---
        self._scene = None
        self._accel = None
        self._workers = None            # threads for whole-image passes, made with the first context
        self._ctx = None
        self._combined = CombinedArrays()   # every object's triangles, in world space
        self._scene_materials = Materials.from_list([{}])
        self._scene_shaders, self._scene_images = [], {}
        self._scene_lights = Lights.empty()
        self._environment = None
        self._world_volume = None
        self._volume_grids = []
        self._camera = None
        self._filter_width = 1.5
        self._film_transparent = False
        self._size = None               # image size
        self._frames_since_edit = 0     # frames since objects last changed (for settling)
        self._applied_generation = 0
        self._geometry_version = self._lighting_version = 0

    # ------------------------------------------------------------------ hand-over

    def _edit_abandons(self):
        """Whether a queued edit makes the frame in progress useless (viewport)."""
        return False

    def _queue(self, abandon=False, **changes):
        """Merge changes into the pending set (and wake a render thread)."""
        abandon = abandon or self._edit_abandons()
        with self._cond:
            p = self._pending
            for name, value in changes.items():
                if name in ("moved", "remeshed", "reslotted", "animated"):
                    getattr(p, name).update(value)
                elif name in ("layout", "full"):
                    setattr(p, name, getattr(p, name) or value)
                else:
                    setattr(p, name, value)
            self._generation += 1
            p.generation = self._generation
            if abandon:
                self._abandon = True
            self._cond.notify_all()
        return self._generation

    @property
    def generation(self):
        """Number of changes queued so far (a frame includes them once its
        ``frame_generation`` reaches this)."""
        return self._generation

    def _take_pending(self):
        with self._cond:
            p, self._pending = self._pending, Pending()
            self._abandon = False
            self._applying = not p.empty()
        return p

    def apply_pending(self):
        """Apply what sync queued to the core scene (render side)."""
        try:
            self._apply(self._take_pending())
        finally:
            self._applying = False

    # ------------------------------------------------------------------ hooks

    def _render_resolution(self):
        return self._size

    def _should_abandon(self):
        return self._abandon

    def _settings_changed(self):
        """New render settings were queued (the viewport drops its history)."""

    def _scene_changed(self):
        """The core scene was rebuilt from applied changes."""

    # ------------------------------------------------------------------ results

    @property
    def scene(self):
        """The core.Scene of the latest applied changes (render side)."""
        return self._scene

    @property
    def context(self):
        """The RenderContext over ``scene`` (None without scene or camera)."""
        return self._ctx

    @property
    def accel(self):
        return self._accel

    def end_twin(self):
        """End the twin process the workers keep for the next frame."""
        if self._workers is not None:
            self._workers.end_twin()

    def _free_scene(self):
        if self._accel is not None:
            self._accel.close()
        if self._workers is not None:
            self._workers.close()
        self._accel = self._ctx = self._scene = self._workers = None
        self._combined.free()
