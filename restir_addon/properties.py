"""Settings of the engine, attached to every scene as ``scene.restir_gi``."""

import bpy
from bpy.props import EnumProperty, IntProperty, PointerProperty

MODE_ITEMS = (
    ("PATH", "Path Tracing", "Plain path tracing: samples per pixel, no reuse between frames"),
)


class RestirGISceneSettings(bpy.types.PropertyGroup):
    mode: EnumProperty(
        name="Mode",
        description="Light transport algorithm",
        items=MODE_ITEMS,
        default="PATH",
    )
    samples: IntProperty(
        name="Samples",
        description="Samples per pixel per frame",
        default=16, min=1, soft_max=1024, max=65536,
    )
    max_bounces: IntProperty(
        name="Max Bounces",
        description="Maximum number of bounces of a light path",
        default=4, min=0, soft_max=16, max=128,
    )
    seed: IntProperty(
        name="Seed",
        description="Seed of the random numbers; the same seed gives the same image",
        default=0, min=0,
    )

    @classmethod
    def register(cls):
        bpy.types.Scene.restir_gi = PointerProperty(
            name="ReSTIR GI Settings", description="ReSTIR GI render settings", type=cls)

    @classmethod
    def unregister(cls):
        del bpy.types.Scene.restir_gi


classes = (RestirGISceneSettings,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
