"""Where a final render's state lives between frames.

Blender makes a new RenderEngine for every animation frame unless persistent
data is on, so each (scene, view layer) stream lives here, outside the engine
(and each stereo view's, which shares its layer's exported scene):
ReSTIR GI's reservoirs and the exported scene with its Embree scenes
(frame_scene.py). Each stream remembers the last frame it rendered and its
camera, so a jump in time (not the next frame) or a camera cut starts over.
Each scene's frame_start as the file was loaded is kept too: the first frame
of its animation when the command line's -s moved frame_start
(``animation_start``).

The exported scene is freed when a render job ends (completed or cancelled)
unless Persistent Data is on, as Blender frees its own; everything is dropped
when a file is loaded or the add-on is unregistered.
"""

import bpy

from ..core.restir import ReSTIRGI
from .sync.frame_scene import FrameScene

_streams = {}
_loaded_starts = {}     # scene name -> frame_start as the file was loaded


def animation_start(scene):
    """The first frame of the scene's animation: its frame_start, or in a
    background render the frame_start it had when the file was loaded, if
    that is earlier. A farm that renders a chunk with ``blender -b
    file.blend -s A -e B -a`` makes A the scene's frame_start after the file
    is loaded; the chunk's warm-up (final._chunk_warmup) still reaches back
    before A, as it does for ``-f A..B``. (In Blender's window frame_start is
    what the user set.)"""
    loaded = _loaded_starts.get(scene.name_full) if bpy.app.background else None
    return scene.frame_start if loaded is None else min(scene.frame_start, loaded)


@bpy.app.handlers.persistent
def remember_frame_ranges(*_args):
    """(load_post) Each scene's frame_start as the file was loaded, before the
    command line's -s changes it."""
    _loaded_starts.clear()
    for scene in bpy.data.scenes:
        _loaded_starts[scene.name_full] = int(scene.frame_start)


class Stream:
    def __init__(self, frame_scene=None):
        self.restir = ReSTIRGI()
        self.last_frame = None
        self.last_camera = None     # name of the camera object of that frame
        self.last_view = None       # the core.Camera it was rendered with (final.jumped)
        self.reported_frame = None  # animation frame whose export warnings were reported last
        self.frame_scene = frame_scene if frame_scene is not None else FrameScene()
        self.timings = {}           # seconds in each stage of the latest frame (benchmarks, the log)

    def free(self):
        self.frame_scene.release()
        self.restir.reset()


def stream_for(scene_name, layer_name, view=None):
    """The stream of a view layer, or of one of its views (stereoscopy): a
    view has reservoirs of its own and shares the layer's exported scene."""
    key = (scene_name, layer_name) if view is None else (scene_name, layer_name, view)
    if key not in _streams:
        shared = None if view is None else stream_for(scene_name, layer_name).frame_scene
        _streams[key] = Stream(shared)
    return _streams[key]


@bpy.app.handlers.persistent
def clear(*_args):
    """Free every stream's buffers and forget the frame ranges loaded."""
    for stream in _streams.values():
        stream.free()
    _streams.clear()
    _loaded_starts.clear()


@bpy.app.handlers.persistent
def job_ended(scene, *_args):
    """A render job ended: free the exported scenes unless Persistent Data is
    on; with it, end the twin process kept for the next frame (core/workers/forked.py)."""
    for key, stream in _streams.items():
        target = bpy.data.scenes.get(key[0])
        if target is None or not target.render.use_persistent_data:
            stream.frame_scene.release()
        else:
            stream.frame_scene.end_twin()


def stream_count():
    return len(_streams)


_HANDLERS = (("load_pre", clear), ("load_post", remember_frame_ranges), ("render_complete", job_ended),
             ("render_cancel", job_ended))


def register():
    for name, fn in _HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        if fn not in handlers:
            handlers.append(fn)


def unregister():
    for name, fn in _HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        if fn in handlers:
            handlers.remove(fn)
    clear()
