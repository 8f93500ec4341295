"""Blender layer of the ReSTIR GI engine: everything that imports bpy lives here."""

if "bpy" in locals():  # add-on reload: re-import submodules in order
    import importlib
    for _name in ("properties", "state", "final", "viewport_sync", "viewport_arrays", "viewport",
                  "viewport_draw", "engine", "ui"):
        if _name in locals():
            importlib.reload(locals()[_name])

import bpy  # noqa: E402

from . import engine, properties, state, ui  # noqa: E402

_modules = (properties, state, engine, ui)


def register():
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
