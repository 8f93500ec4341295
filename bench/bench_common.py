"""Shared by the benchmarks: load the add-on from this tree and export a .blend."""

import importlib.util
import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "bench" / "out"


def load_addon():
    """bpy with the add-on registered from this source tree (as package restir_gi)."""
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="restir-bench-"))
    import bpy  # noqa: F401
    if "restir_gi" not in sys.modules:
        spec = importlib.util.spec_from_file_location("restir_gi", ROOT / "__init__.py",
                                                      submodule_search_locations=[str(ROOT)])
        module = importlib.util.module_from_spec(spec)
        sys.modules["restir_gi"] = module
        spec.loader.exec_module(module)
        module.register()
    return sys.modules["restir_gi"]


def export_blend(path, scale=1.0):
    """core.Scene of a .blend file's scene at its resolution times ``scale``."""
    load_addon()
    import bpy
    from restir_gi.restir_addon.export import export_scene
    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    r = scene.render
    w = max(1, int(r.resolution_x * r.resolution_percentage / 100 * scale))
    h = max(1, int(r.resolution_y * r.resolution_percentage / 100 * scale))
    core_scene, _ = export_scene(bpy.context.evaluated_depsgraph_get(), w, h)
    return core_scene
