"""ReSTIR GI render engine for Blender (extension entry point).

The repository root is the extension root; the add-on itself lives in
``restir_addon`` and the renderer in ``core``.
"""


def register():
    from .restir_addon import register as _register  # noqa: PLC0415 (bpy: the package imports without it)
    _register()


def unregister():
    from .restir_addon import unregister as _unregister  # noqa: PLC0415
    _unregister()
