"""The RenderEngine: a switchboard whose callbacks hand over to final/viewport code."""

import bpy

from . import final
from .viewport import draw as viewport_draw
from .export import images
from .passes import register_passes


class RestirGIRenderEngine(bpy.types.RenderEngine):
    bl_idname = "RESTIR_GI"
    bl_label = "ReSTIR GI"
    bl_use_preview = True
    bl_use_postprocess = True

    def render(self, depsgraph):
        with images.rendering():        # no temporary image is removed meanwhile
            final.render(self, depsgraph)

    def update_render_passes(self, scene=None, renderlayer=None):
        register_passes(self, scene, renderlayer)

    def view_update(self, context, depsgraph):
        viewport_draw.view_update(self, context, depsgraph)

    def view_draw(self, context, depsgraph):
        viewport_draw.view_draw(self, context, depsgraph)

    def __del__(self):
        viewport_draw.free(self)


def register():
    bpy.utils.register_class(RestirGIRenderEngine)
    # Removes the temporary images kept while rendering (export/images.py),
    # from the main thread: a render thread must not register timers.
    if not bpy.app.timers.is_registered(images.sweep):
        bpy.app.timers.register(images.sweep, first_interval=images.SWEEP_INTERVAL, persistent=True)


def unregister():
    if bpy.app.timers.is_registered(images.sweep):
        bpy.app.timers.unregister(images.sweep)
    bpy.utils.unregister_class(RestirGIRenderEngine)
