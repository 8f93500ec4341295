"""The RenderEngine: a switchboard whose callbacks hand over to final/viewport code."""

import bpy

from . import final, state, viewport
from .passes import register_passes


class RestirGIRenderEngine(bpy.types.RenderEngine):
    bl_idname = "RESTIR_GI"
    bl_label = "ReSTIR GI"
    bl_use_preview = False
    bl_use_postprocess = True

    def render(self, depsgraph):
        # A still is never continued (a render continues only an animation's
        # previous frame): its ReSTIR state is let go after its last frame,
        # before the images are copied to Blender, where a still peaks.
        stream = state.stream_for(depsgraph.scene.name, depsgraph.view_layer.name)
        stream.restir.keep_history = bool(self.is_animation)
        final.render(self, depsgraph)

    def update_render_passes(self, scene=None, renderlayer=None):
        register_passes(self, scene, renderlayer)

    def view_update(self, context, depsgraph):
        viewport.view_update(self, context, depsgraph)

    def view_draw(self, context, depsgraph):
        viewport.view_draw(self, context, depsgraph)

    def __del__(self):
        viewport.free(self)


def register():
    bpy.utils.register_class(RestirGIRenderEngine)


def unregister():
    bpy.utils.unregister_class(RestirGIRenderEngine)
