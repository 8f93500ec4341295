"""Where ReSTIR GI's temporal state lives between frames.

Blender makes a new RenderEngine for every animation frame unless persistent
data is on, so the reservoirs of each (scene, view layer) stream live here,
outside the engine, and are dropped when a file is loaded or the add-on is
unregistered. Each stream remembers the last frame it rendered and its camera,
so a jump in time (not the next frame) or a camera cut starts over.
"""

import bpy

from ..core.restir import ReSTIRGI

_streams = {}


class Stream:
    def __init__(self):
        self.restir = ReSTIRGI()
        self.last_frame = None
        self.last_camera = None     # name of the camera object of that frame


def stream_for(scene_name, layer_name):
    key = (scene_name, layer_name)
    if key not in _streams:
        _streams[key] = Stream()
    return _streams[key]


@bpy.app.handlers.persistent
def clear(*_args):
    """Free every stream's buffers."""
    _streams.clear()


def stream_count():
    return len(_streams)


def register():
    if clear not in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.append(clear)


def unregister():
    if clear in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(clear)
    clear()
