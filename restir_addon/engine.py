"""The RenderEngine: a switchboard whose callbacks hand over to final/viewport code."""

import bpy


class RestirGIRenderEngine(bpy.types.RenderEngine):
    bl_idname = "RESTIR_GI"
    bl_label = "ReSTIR GI"
    bl_use_preview = False
    bl_use_shading_nodes_custom = False

    def render(self, depsgraph):
        scale = depsgraph.scene.render.resolution_percentage / 100.0
        width = int(depsgraph.scene.render.resolution_x * scale)
        height = int(depsgraph.scene.render.resolution_y * scale)
        result = self.begin_result(0, 0, width, height)
        self.end_result(result)


def register():
    bpy.utils.register_class(RestirGIRenderEngine)


def unregister():
    bpy.utils.unregister_class(RestirGIRenderEngine)
