"""Shared pytest configuration."""


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "slow: takes seconds or more; make test-fast leaves it out (-m 'not slow')")


def pytest_collection_modifyitems(config, items):
    """The Cycles comparisons (tests/oracle/) render both engines and the
    real-window tests (tests/e2e/) start Blender: all slow."""
    slow = [Path(__file__).parent / name for name in ("oracle", "e2e")]
    for item in items:
        if any(folder in Path(item.fspath).parents for folder in slow):
            item.add_marker("slow")


import importlib.util  # noqa: E402
import os  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def _load_package(name="restir_gi"):
    """The repository root as the package ``restir_gi``, the way Blender loads
    the extension: tests import the renderer as ``restir_gi.core``, the one
    path the add-on uses too (importing it needs no bpy)."""
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(
            name, ROOT / "__init__.py", submodule_search_locations=[str(ROOT)])
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


_load_package()


@pytest.fixture
def rng():
    """A fixed-seed generator: tests never touch numpy's global random state."""
    return np.random.default_rng(12345)


@pytest.fixture(scope="session")
def addon():
    """bpy with the add-on registered from this source tree, the way Blender loads
    an extension (the repository root as a package). Blender's user resources
    go to a temporary folder, never the user's home."""
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="restir-user-"))
    import bpy  # noqa: F401 (before the add-on registers)
    module = _load_package()
    if not getattr(module, "_registered_by_tests", False):
        module.register()
        module._registered_by_tests = True
    yield module


@pytest.fixture
def reports(addon, monkeypatch):
    """Every report the final render makes, as (type, message) in ``.log``
    (addon_util.capture_reports)."""
    from support.addon_util import capture_reports
    return capture_reports(addon, monkeypatch)


@pytest.fixture
def vp(addon):
    """The add-on's viewport session module (restir_addon/viewport/session.py)."""
    return addon.restir_addon.viewport.session


@pytest.fixture
def vp_draw(addon):
    """The add-on's viewport callbacks (restir_addon/viewport/draw.py)."""
    return addon.restir_addon.viewport.draw


@pytest.fixture
def recorder(addon):
    """A depsgraph_update_post handler that records ``depsgraph.updates``
    (blender_util.Recorder), removed afterwards."""
    import bpy
    from support.blender_util import Recorder
    rec = Recorder()
    yield rec
    if rec in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(rec)


@pytest.fixture
def ng(addon):
    """The add-on's node graph exporter (restir_addon/export/node_graph.py)."""
    from support.node_graph_util import modules
    return modules(addon)[0]


@pytest.fixture
def Link(addon):
    """core.materials.shader.graph.Link as the registered add-on has it."""
    from support.node_graph_util import modules
    return modules(addon)[2].Link
