"""Render Properties panels, and the built-in panels the engine adopts."""

import bpy

ENGINE = "RESTIR_GI"

# Built-in panels made for other engines that also apply to ours (material and
# world node inputs, light settings, the camera's depth of field), besides every
# panel open to BLENDER_RENDER.
EXTRA_PANELS = (
    "MATERIAL_PT_preview",
    "EEVEE_MATERIAL_PT_context_material",
    "EEVEE_MATERIAL_PT_surface",
    "EEVEE_WORLD_PT_surface",
    "DATA_PT_EEVEE_light",
    "DATA_PT_EEVEE_light_distance",
    "DATA_PT_camera_dof",
    "DATA_PT_camera_dof_aperture",
)


class RestirButtonsPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


class RESTIR_RENDER_PT_sampling(RestirButtonsPanel, bpy.types.Panel):
    bl_label = "Sampling"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.restir_gi
        layout.prop(settings, "mode")
        col = layout.column(align=True)
        col.prop(settings, "samples", text="Samples" if settings.mode == "PATH" else "Frames per Frame")
        if settings.mode != "PATH":
            col.prop(settings, "warmup_frames")
            col.prop(settings, "chunk_warmup_frames")
            col.prop(settings, "accumulate_frames")
        col.prop(settings, "seed")
        if settings.mode != "PATH":
            layout.prop(settings, "use_denoising")


class RESTIR_RENDER_PT_resampling(RestirButtonsPanel, bpy.types.Panel):
    bl_label = "Resampling"
    bl_parent_id = "RESTIR_RENDER_PT_sampling"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and context.scene.restir_gi.mode != "PATH"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        s = context.scene.restir_gi
        layout.prop(s, "initial_sampling")
        layout.prop(s, "light_samples")
        layout.prop(s, "sky_samples")
        col = layout.column(align=True)
        col.prop(s, "temporal_m_cap")
        col.prop(s, "max_age")
        col = layout.column(align=True)
        col.prop(s, "spatial_neighbors")
        col.prop(s, "spatial_radius")
        col.prop(s, "spatial_m_cap")
        layout.prop(s, "boiling_filter")
        layout.prop(s, "validation_interval")


class RESTIR_RENDER_PT_viewport(RestirButtonsPanel, bpy.types.Panel):
    bl_label = "Viewport"
    bl_parent_id = "RESTIR_RENDER_PT_sampling"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        s = context.scene.restir_gi
        layout.prop(s, "viewport_scale")
        layout.prop(s, "viewport_frame_budget")
        layout.prop(s, "viewport_samples")
        col = layout.column()
        col.active = s.mode != "PATH"
        col.prop(s, "use_preview_denoising")
        sub = col.column()
        sub.active = s.mode != "PATH" and s.use_preview_denoising
        sub.prop(s, "preview_denoising_start_sample")


class RESTIR_RENDER_PT_light_paths(RestirButtonsPanel, bpy.types.Panel):
    bl_label = "Light Paths"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        s = context.scene.restir_gi
        col = layout.column(align=True)
        col.prop(s, "max_bounces", text="Total")
        col = layout.column(align=True)
        col.prop(s, "diffuse_bounces")
        col.prop(s, "glossy_bounces")
        col.prop(s, "transmission_bounces")


class RESTIR_WORLD_PT_preview(bpy.types.Panel):
    """The world's preview (Blender has none of its own; Cycles adds one)."""
    bl_label = "Preview"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "world"
    bl_options = {"DEFAULT_CLOSED"}
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES and context.world is not None

    def draw(self, context):
        self.layout.template_preview(context.world)


classes = (RESTIR_RENDER_PT_sampling, RESTIR_RENDER_PT_resampling, RESTIR_RENDER_PT_viewport,
           RESTIR_RENDER_PT_light_paths, RESTIR_WORLD_PT_preview)


def _adopted_panels():
    for panel in bpy.types.Panel.__subclasses__():
        engines = getattr(panel, "COMPAT_ENGINES", None)
        if engines is None:
            continue
        if "BLENDER_RENDER" in engines or panel.__name__ in EXTRA_PANELS:
            yield panel


_adopted = []


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    for panel in _adopted_panels():
        if ENGINE not in panel.COMPAT_ENGINES:
            panel.COMPAT_ENGINES.add(ENGINE)
            _adopted.append(panel)


def unregister():
    for panel in _adopted:
        panel.COMPAT_ENGINES.discard(ENGINE)
    _adopted.clear()
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
