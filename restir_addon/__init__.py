"""Blender layer of the ReSTIR GI engine: everything that imports bpy lives here."""

if "bpy" in locals():  # Reload Scripts: drop every module of the extension, imported afresh below
    import sys
    _root = __name__.rpartition(".")[0]
    for _name in [n for n in sys.modules if n.startswith(_root + ".core") or n.startswith(__name__ + ".")]:
        del sys.modules[_name]

import bpy  # noqa: F401 (the mark of a reload, above)

from . import engine, properties, state, ui

_modules = (properties, state, engine, ui)


def register():
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
