"""Where a final render's state lives between frames.

Blender makes a new RenderEngine for every animation frame unless persistent
data is on, so each (scene, view layer) stream lives here, outside the engine:
ReSTIR GI's reservoirs and the exported scene with its Embree scenes
(frame_scene.py). Each stream remembers the last frame it rendered and its
camera, so a jump in time (not the next frame) or a camera cut starts over.

The exported scene is freed when a render job ends (completed or cancelled)
unless Persistent Data is on, as Blender frees its own; everything is dropped
when a file is loaded or the add-on is unregistered.
"""

import bpy

from ..core.restir import ReSTIRGI
from .frame_scene import FrameScene

_streams = {}


class Stream:
    def __init__(self):
        self.restir = ReSTIRGI()
        self.last_frame = None
        self.last_camera = None     # name of the camera object of that frame
        self.frame_scene = FrameScene()

    def free(self):
        self.frame_scene.release()
        self.restir.reset()


def stream_for(scene_name, layer_name):
    key = (scene_name, layer_name)
    if key not in _streams:
        _streams[key] = Stream()
    return _streams[key]


@bpy.app.handlers.persistent
def clear(*_args):
    """Free every stream's buffers."""
    for stream in _streams.values():
        stream.free()
    _streams.clear()


@bpy.app.handlers.persistent
def job_ended(scene, *_args):
    """A render job ended: free the exported scenes unless Persistent Data is on."""
    for (scene_name, _layer), stream in _streams.items():
        target = bpy.data.scenes.get(scene_name)
        if target is None or not target.render.use_persistent_data:
            stream.frame_scene.release()


def stream_count():
    return len(_streams)


_HANDLERS = (("load_pre", clear), ("render_complete", job_ended), ("render_cancel", job_ended))


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
